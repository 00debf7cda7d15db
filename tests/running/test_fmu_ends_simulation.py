"""An FMU that ends the simulation itself (fmi2Terminated, fmi3DoStep's
terminateSimulation, an event update's terminateSimulation) ends the run normally, at
the last communication point every component reached: in every coupling, while Newton
iterates, on the isolated and Ray backends, and in every FMI version and interface.
The FMUs are C (tests/support/ender.py, tests/support/third_party/kinds), compiled here."""
from __future__ import annotations

import json
import shutil
import uuid
import zipfile
from pathlib import Path

import numpy as np
import pytest

import dsim
from dsim.master.tools.cli import main
from tests.support.scene_files import component, scene_folder, ssd
from tests.support.scenes import EMPTY_SSD

# --- an FMU of our own that ends the simulation itself (tests/support/ender.py) -------

def _ender_scene(folder: Path, fmu: Path, t_end: float, glued: bool, coupling: str,
                 stop: float = 1.0, step: float = 0.1, joint: str = "") -> Path:
    """One ender pushed by F = 2 N (x = t^2), or (glued) two of 1 kg and 3 kg joined at
    P by a fixed joint, the first pushed by F = 8 N (x = t^2 for both); the first ends
    the simulation at ``t_end``."""
    parts = [component("a", "resources/ender.fmu",
                       {"m": 1.0, "F": 8.0 if glued else 2.0, "T_end": t_end},
                       outputs=("P.u_x",))]
    gluing = ""
    if glued:
        parts.append(component("b", "resources/ender.fmu", {"m": 3.0}))
        gluing = joint or '<glue:Joint name="j" a="a.P" b="b.P" dofs="x" kind="fixed"/>'
    text = ssd("ender", parts, gluing=gluing, stop=stop,
               master=f'step="{step!r}" coupling="{coupling}"')
    return scene_folder(folder, text, {"ender.fmu": fmu})


@pytest.mark.parametrize("t_end, last", [(0.35, 0.3), (0.4, 0.4)])
@pytest.mark.parametrize("glued, coupling", [(False, "causal"), (True, "explicit"),
                                             (True, "iterative"), (True, "strong")])
def test_an_fmu_that_ends_the_simulation_ends_the_run_normally(ender, tmp_path, t_end, last,
                                                               glued, coupling):
    """The run ends at the last communication point every component reached (the step's
    start when the FMU ended inside a step, its end when it ended there), exit 0, every
    row on x = t^2, the statistics naming the component and the time it reached."""
    folder = _ender_scene(tmp_path / "scene", ender, t_end, glued, coupling)
    out = tmp_path / "out.csv"
    assert main(["run", str(folder), "--out", str(out), "--quiet"]) == 0
    result = dsim.simulate(folder)
    assert result.ok and result.status == "completed"
    time = result["time"]
    assert time[-1] == pytest.approx(last, abs=1e-12)
    assert len(time) == round(last / 0.1) + 1
    # the rows are the run's without the end, up to where it ended
    whole = dsim.simulate(_ender_scene(tmp_path / "whole", ender, 1e300, glued, coupling))
    assert whole.ok and whole.statistics["ended_by"] is None and len(whole["time"]) == 11
    np.testing.assert_array_equal(result["a.P.u_x"], whole["a.P.u_x"][:len(time)])
    if coupling != "explicit":  # (one explicit trial per step is not exact at 0.1 s)
        assert np.max(np.abs(result["a.P.u_x"] - time ** 2)) < 1e-9
    ended = result.statistics["ended_by"]
    assert ended["component"] == "a" and ended["time"] == pytest.approx(t_end, abs=1e-12)
    assert result.statistics["time_reached"] == pytest.approx(last, abs=1e-12)
    assert any("component 'a' ended the simulation" in w for w in result.warnings)
    rows = out.read_text().strip().splitlines()
    assert len(rows) == len(time) + 1  # the header and every row


SPRING = ('<glue:Joint name="j" a="a.P" b="b.P" dofs="x" kind="flexible" '
          'measure="displacement"><glue:Spring k0="400" k1="0"/></glue:Joint>')


@pytest.mark.parametrize("t_end, last", [(0.35, 0.3), (0.4, 0.4)])
@pytest.mark.parametrize("coupling", ["iterative", "strong"])
def test_a_glued_fmu_that_ends_while_newton_iterates_ends_at_a_converged_step(
        ender, tmp_path, t_end, last, coupling):
    """Two enders on a spring: every step takes Newton iterations (restores), and the one
    that ends is stepped again after its end; the rows are those of the run without the
    end, to the last converged communication point."""
    ended = dsim.simulate(_ender_scene(tmp_path / "ended", ender, t_end, True, coupling,
                                       joint=SPRING))
    whole = dsim.simulate(_ender_scene(tmp_path / "whole", ender, 1e300, True, coupling,
                                       joint=SPRING))
    assert ended.ok and whole.ok
    assert whole.statistics["iterations"]["max_per_step"] > 1
    assert ended["time"][-1] == pytest.approx(last, abs=1e-12)
    n = len(ended["time"])
    assert n == round(last / 0.1) + 1
    np.testing.assert_array_equal(ended["a.P.u_x"], whole["a.P.u_x"][:n])
    assert ended.statistics["ended_by"]["time"] == pytest.approx(t_end, abs=1e-12)


def test_an_fmu_that_ends_the_simulation_in_a_worker_ends_the_run_the_same(
        ender, tmp_path, ray_local):
    """The isolated and Ray backends end the run where the in-process one does (the
    step's start, and the step's end after a complete step), and run a scene without
    components to its time column."""
    empty = tmp_path / "setup"
    empty.mkdir()
    (empty / "SystemStructure.ssd").write_text(EMPTY_SSD)
    for t_end in (0.35, 0.4):
        folder = _ender_scene(tmp_path / f"scene{t_end}", ender, t_end, True, "iterative")
        here = dsim.simulate(folder)
        for backend in ("isolated", "ray"):
            there = dsim.simulate(folder, backend=backend)
            assert there.ok and there.statistics["ended_by"] == here.statistics["ended_by"]
            np.testing.assert_array_equal(there["a.P.u_x"], here["a.P.u_x"])
            nothing = dsim.simulate(empty, backend=backend, step=0.1)
            assert nothing.ok and len(nothing["time"]) == 6


# --- the same end in every FMI version and interface ---------------------------------
# The kinds skeletons (tests/support/third_party/kinds) know no end of the simulation: a copy of
# them, changed here, ends it when the model sets its discrete flag to 99 (at a time
# event), as each version says: FMI 1.0 and 2.0 co-simulation discard the step and
# answer fmi(2)GetBooleanStatus(fmi(2)Terminated = 3) true; FMI 3.0 co-simulation sets
# fmi3DoStep's terminateSimulation; Model Exchange sets terminateSimulation in the event
# update.

ENDS_MODEL_C = r"""
#include "model.h"
enum { A, T_END, X, V, DER_V, N_VARS };
const int model_n_vars = N_VARS, model_n_states = 2, model_n_indicators = 0;
const char model_kinds[] = "ppccc";
const unsigned model_state_vr[] = {X, V}, model_derivative_vr[] = {V, DER_V};
void model_start(ModelData *m) { m->r[A] = 2.0; m->r[T_END] = 1e300; }
void model_initialize(ModelData *m) { m->r[X] = 0.0; m->r[V] = 0.0; m->flags = 0; }
void model_compute(ModelData *m) { m->r[DER_V] = m->r[A]; }
void model_indicators(const ModelData *m, double z[]) { (void)m; (void)z; }
int model_event(ModelData *m, double *next_time) {
    if (time_reached(m->time, m->r[T_END])) m->flags = 99;
    else *next_time = m->r[T_END];
    return 0;
}
"""

#: (file, text as the skeleton has it, what the copy has instead)
ENDS_PATCHES = (
    ("core.c", "        if (c->d.time >= t_end) break;",
     "        if (c->d.flags == 99 || c->d.time >= t_end) break;"),
    ("core.c", "    c->d.time = t_end;\n    core_set_states(c, x);",
     "    if (c->d.flags != 99) c->d.time = t_end;  /* ended: where it is */\n"
     "    core_set_states(c, x);"),
    ("fmi3.c", "    if (terminate) *terminate = fmi3False;",
     "    if (terminate) *terminate = m->core.d.flags == 99;"),
    ("fmi3.c", "    if (earlyReturn) *earlyReturn = fmi3False;",
     "    if (earlyReturn) *earlyReturn = m->core.d.flags == 99 && m->core.d.time < t + h;"),
    ("fmi2.c", '    CHECK("fmi2DoStep", core_do_step(&m->core, t, h));\n    return fmi2OK;',
     '    CHECK("fmi2DoStep", core_do_step(&m->core, t, h));\n'
     "    return m->core.d.flags == 99 ? fmi2Discard : fmi2OK;"),
    ("fmi2.c", "    *value = fmi2False;", "    *value = m->core.d.flags == 99;"),
    ("fmi2.c", "    info->terminateSimulation = fmi2False;",
     "    info->terminateSimulation = m->core.d.flags == 99;"),
    ("fmi1cs.c", '    CHECK("fmiDoStep", core_do_step(&m->core, t, h));\n    return fmi1OK;',
     '    CHECK("fmiDoStep", core_do_step(&m->core, t, h));\n'
     "    return m->core.d.flags == 99 ? fmi1Discard : fmi1OK;"),
    ("fmi1cs.c", "    (void)s; (void)value;\n    return fmi1Discard;\n}\n\n"
     "fmi1Status FMI1_FUNCTION(fmiGetStringStatus)",
     "    if (s != 3 || !value) return fmi1Discard;\n    *value = m->core.d.flags == 99;\n"
     "    return fmi1OK;\n}\n\nfmi1Status FMI1_FUNCTION(fmiGetStringStatus)"),
)


@pytest.fixture(scope="module")
def ends(tmp_path_factory):
    """fmu(version, interfaces) -> the model x'' = a (a = 2: x = t^2) that ends the
    simulation at T_end, built from the changed copy of the kinds skeletons."""
    import subprocess

    import fmpy

    from tests.support.third_party.kinds import build as kinds

    folder = tmp_path_factory.mktemp("ends")
    for name in ("core.c", "core.h", "model.h", "fmi1cs.c", "fmi2.c", "fmi3.c"):
        shutil.copy(kinds.HERE / name, folder / name)
    for name, before, after in ENDS_PATCHES:
        text = (folder / name).read_text()
        assert before in text, (name, before)
        (folder / name).write_text(text.replace(before, after))
    (folder / "ends.c").write_text(ENDS_MODEL_C)
    model = kinds.Model("ends", "x'' = a until T_end", (
        kinds.Var("a", 0, "parameter", start=2.0),
        kinds.Var("T_end", 1, "parameter", start=1e300),
        kinds.Var("x", 2, "output", depends=("x",)),
        kinds.Var("v", 3, "output", derivative="x", depends=("v",)),
        kinds.Var("der(v)", 4, derivative="v", depends=())), states=("x", "v"))

    def fmu(version: str, interfaces) -> Path:
        guid = f"{{{uuid.uuid4()}}}"
        name = f"ends{version[0]}"
        library = folder / f"{name}.so"
        subprocess.run(["gcc", "-shared", "-fPIC", "-O2", "-std=c99", "-fvisibility=hidden",
                        f"-DMODEL_IDENTIFIER={name}", f'-DMODEL_GUID="{guid}"',
                        f"-DTIME_VR={kinds.TIME_VR}",
                        f"-I{Path(fmpy.__file__).parent / 'c-code'}", f"-I{folder}",
                        str(folder / kinds.SKELETONS[version]), str(folder / "core.c"),
                        str(folder / "ends.c"), "-o", str(library), "-lm"], check=True)
        path = folder / f"{name}_{'_'.join(interfaces)}.fmu"
        with zipfile.ZipFile(path, "w") as archive:
            archive.writestr("modelDescription.xml", kinds.model_description(
                model, version, interfaces, True, name, guid))
            archive.write(library, f"binaries/{kinds._platform(version)}/{name}.so")
        return path

    return fmu


@pytest.mark.parametrize("version, interface", [("1.0", "CoSimulation"),
                                                ("2.0", "CoSimulation"),
                                                ("3.0", "CoSimulation"),
                                                ("2.0", "ModelExchange"),
                                                ("3.0", "ModelExchange")])
@pytest.mark.parametrize("t_end, last", [(0.35, 0.3), (0.4, 0.4)])
def test_every_fmi_version_and_interface_ends_the_run_the_same(ends, tmp_path, version,
                                                               interface, t_end, last):
    fmu = ends(version, (interface,))
    part = component("e", "resources/ends.fmu", {"T_end": t_end}, outputs=("x",)).replace(
        'source="resources/ends.fmu"', f'source="resources/ends.fmu" '
        f'implementation="{interface}"')
    folder = scene_folder(tmp_path / "scene", ssd("ends", [part], stop=1.0,
                                                  master='step="0.1"'), {"ends.fmu": fmu})
    result = dsim.simulate(folder)
    assert result.ok, result.statistics["message"]
    time = result["time"]
    assert time[-1] == pytest.approx(last, abs=1e-12) and len(time) == round(last / 0.1) + 1
    np.testing.assert_allclose(result["e.x"], time ** 2, atol=1e-12)
    ended = result.statistics["ended_by"]
    assert ended["component"] == "e" and ended["time"] == pytest.approx(t_end, abs=1e-9)


@pytest.mark.parametrize("version, interface", [("2.0", "ModelExchange"),
                                                ("3.0", "ModelExchange"),
                                                ("2.0", "CoSimulation")])
def test_an_fmu_that_ends_the_simulation_in_initialization_ends_at_the_start(
        ends, ender, tmp_path, capsys, version, interface):
    """Model Exchange: terminateSimulation from the event iteration that leaving
    initialization mode starts (T_end = 0, the start time); FMI 2.0 co-simulation:
    fmi2ExitInitializationMode returns fmi2Discard and its status says terminated.
    Either ends the run normally at the start time: exit 0, one row, the statistics and
    a warning saying which component ended it (it was exit 2, "the FMU asked to end the
    simulation" or "cannot be initialised")."""
    if interface == "ModelExchange":
        part = component("e", "resources/ends.fmu", {"T_end": 0.0}, outputs=("x",))
        part = part.replace('source="resources/ends.fmu"', 'source="resources/ends.fmu" '
                            f'implementation="{interface}"')
        fmus = {"ends.fmu": ends(version, (interface,))}
    else:
        part = component("e", "resources/ender.fmu", {"F": 2.0, "T_end": 0.0},
                         outputs=("P.u_x",))
        fmus = {"ender.fmu": ender}
    folder = scene_folder(tmp_path / "scene", ssd("ends", [part], stop=1.0,
                                                  master='step="0.1"'), fmus)
    out = tmp_path / "out.csv"
    assert main(["run", str(folder), "--out", str(out), "--quiet"]) == 0
    err = capsys.readouterr().err
    assert "component 'e' ended the simulation at t = 0 s: the run ends at t = 0 s" in err
    assert len(out.read_text().strip().splitlines()) == 2  # the header and one row
    statistics = json.loads(out.with_suffix(".stats.json").read_text())
    assert statistics["status"] == "completed" and statistics["steps"] == 0
    assert statistics["ended_by"] == {"component": "e", "time": 0.0}
