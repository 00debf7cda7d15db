"""SSP files as more tools write them (issue 29): a scene without FMU components, an
FMU that ends the simulation itself, .ssv enumeration values given as item names,
startElement="" inside a nested system, Dymola-style connectors that name nothing,
Integer/Real mismatches, an element order that changes nothing, FMUs outside the
scene (--allow-outside) and one error per cause.  Every archive is built here."""
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
from tests.scene_files import component, scene_folder, ssd
from tests.third_party.build import Variable, compile_library, model_description

# --- an FMU of our own that ends the simulation itself -------------------------------

#: FMI 2.0 co-simulation, a mass under a constant force F plus the port force P.f_x,
#: integrated exactly over each step (the force held): x = x0 + v t + F t^2 / (2 m).  At
#: t = T_end it ends the simulation as the standard says: the step that reaches T_end
#: advances to T_end only, returns fmi2Discard, and fmi2GetBooleanStatus(fmi2Terminated)
#: is true, fmi2GetRealStatus(fmi2LastSuccessfulTime) T_end.  T_end at the start time
#: ends it as it leaves initialization (fmi2ExitInitializationMode returns fmi2Discard,
#: its status terminated).
ENDER_C = r"""
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include "fmi2Functions.h"

enum { M, F, T_END, FX, UX, VX, AX, N };
typedef struct { double r[N]; int direction; double time; int terminated; } Model;

/* direction (an Enumeration): 1 Push (F pushes), 2 Pull (F pulls) */
static void accelerate(Model *m) {
    m->r[AX] = ((m->direction == 2 ? -1.0 : 1.0) * m->r[F] + m->r[FX]) / m->r[M];
}

const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }
const char *fmi2GetVersion(void) { return fmi2Version; }
fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean on, size_t n,
                               const fmi2String k[]) { return fmi2OK; }
fmi2Component fmi2Instantiate(fmi2String name, fmi2Type type, fmi2String guid,
                              fmi2String res, const fmi2CallbackFunctions *f,
                              fmi2Boolean visible, fmi2Boolean logging) {
    Model *m = calloc(1, sizeof(Model));
    m->r[M] = 1.0; m->r[F] = 0.0; m->r[T_END] = 1e300; m->direction = 1;
    return m;
}
void fmi2FreeInstance(fmi2Component c) { free(c); }
fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean td, fmi2Real tol, fmi2Real t0,
                               fmi2Boolean sd, fmi2Real stop) {
    ((Model *)c)->time = t0; return fmi2OK;
}
fmi2Status fmi2EnterInitializationMode(fmi2Component c) { return fmi2OK; }
fmi2Status fmi2ExitInitializationMode(fmi2Component c) {
    Model *m = c;
    accelerate(m);
    /* T_end at the start: ended as it leaves initialization (status fmi2Terminated) */
    if (m->r[T_END] <= m->time) { m->terminated = 1; return fmi2Discard; }
    return fmi2OK;
}
fmi2Status fmi2Terminate(fmi2Component c) { return fmi2OK; }
fmi2Status fmi2Reset(fmi2Component c) { return fmi2OK; }
fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                       fmi2Real v[]) {
    Model *m = c;
    for (size_t k = 0; k < n; k++) { if (vr[k] >= N) return fmi2Error; v[k] = m->r[vr[k]]; }
    return fmi2OK;
}
fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                       const fmi2Real v[]) {
    Model *m = c;
    for (size_t k = 0; k < n; k++) { if (vr[k] >= N) return fmi2Error; m->r[vr[k]] = v[k]; }
    accelerate(m);
    return fmi2OK;
}
fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                          fmi2Integer v[]) {
    for (size_t k = 0; k < n; k++) { if (vr[k]) return fmi2Error; v[k] = ((Model *)c)->direction; }
    return fmi2OK;
}
fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                          const fmi2Integer v[]) {
    for (size_t k = 0; k < n; k++) {
        if (vr[k] || v[k] < 1 || v[k] > 2) return fmi2Error;
        ((Model *)c)->direction = v[k];
    }
    accelerate(c);
    return fmi2OK;
}
fmi2Status fmi2GetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                          fmi2Boolean v[]) { return n ? fmi2Error : fmi2OK; }
fmi2Status fmi2SetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                          const fmi2Boolean v[]) { return n ? fmi2Error : fmi2OK; }
fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                         fmi2String v[]) { return n ? fmi2Error : fmi2OK; }
fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                         const fmi2String v[]) { return n ? fmi2Error : fmi2OK; }
fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *s) {
    if (!*s) *s = malloc(sizeof(Model));
    memcpy(*s, c, sizeof(Model)); return fmi2OK;
}
fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate s) {
    memcpy(c, s, sizeof(Model)); return fmi2OK;
}
fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *s) {
    free(*s); *s = NULL; return fmi2OK;
}
fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate s, size_t *n) {
    return fmi2Error;
}
fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate s, fmi2Byte b[], size_t n) {
    return fmi2Error;
}
fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte b[], size_t n,
                                   fmi2FMUstate *s) { return fmi2Error; }
fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference u[],
        size_t nu, const fmi2ValueReference z[], size_t nz, const fmi2Real du[],
        fmi2Real dz[]) { return fmi2Error; }
fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[],
        size_t n, const fmi2Integer o[], const fmi2Real v[]) { return fmi2Error; }
fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[],
        size_t n, const fmi2Integer o[], fmi2Real v[]) { return fmi2Error; }
fmi2Status fmi2DoStep(fmi2Component c, fmi2Real t, fmi2Real h, fmi2Boolean prior) {
    Model *m = c;
    if (m->terminated) return fmi2Error;  /* no step after the end */
    double end = t + h, d;
    int ends = end >= m->r[T_END] - 1e-12;
    d = (ends ? m->r[T_END] : end) - t;
    accelerate(m);
    m->r[UX] += m->r[VX] * d + 0.5 * m->r[AX] * d * d;
    m->r[VX] += m->r[AX] * d;
    m->time = t + d;
    if (ends) { m->terminated = 1; return fmi2Discard; }
    return fmi2OK;
}
fmi2Status fmi2CancelStep(fmi2Component c) { return fmi2Error; }
fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind s, fmi2Status *v) {
    return fmi2Discard;
}
fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind s, fmi2Real *v) {
    if (s != fmi2LastSuccessfulTime) return fmi2Discard;
    *v = ((Model *)c)->time; return fmi2OK;
}
fmi2Status fmi2GetIntegerStatus(fmi2Component c, const fmi2StatusKind s, fmi2Integer *v) {
    return fmi2Discard;
}
fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind s, fmi2Boolean *v) {
    if (s != fmi2Terminated) return fmi2Discard;
    *v = ((Model *)c)->terminated; return fmi2OK;
}
fmi2Status fmi2GetStringStatus(fmi2Component c, const fmi2StatusKind s, fmi2String *v) {
    return fmi2Discard;
}
"""

ENDER_VARIABLES = (
    Variable("m", 0, causality="parameter", start=1.0),
    Variable("F", 1, causality="parameter", start=0.0),
    Variable("T_end", 2, causality="parameter", start=1e300),
    Variable("P.f_x", 3, causality="input", start=0.0),
    Variable("P.u_x", 4, causality="output", initial="exact", start=0.0),
    Variable("P.v_x", 5, causality="output", initial="exact", start=0.0),
    Variable("P.a_x", 6, causality="output", initial="calculated"),
    Variable("direction", 0, "Enumeration", "parameter", start=1),
)
#: the enumeration type of ``direction`` (FMI 2.0 needs one declared)
DIRECTION = ('<TypeDefinitions><SimpleType name="Direction"><Enumeration>'
             '<Item name="Push" value="1"/><Item name="Pull" value="2"/>'
             "</Enumeration></SimpleType></TypeDefinitions>")


@pytest.fixture(scope="module")
def ender(tmp_path_factory) -> Path:
    """The FMU of ENDER_C, compiled with gcc against fmpy's FMI 2.0 headers."""
    folder = tmp_path_factory.mktemp("ender")
    source = folder / "ender.c"
    source.write_text(ENDER_C)
    library = compile_library(source, folder / "ender.so")
    fmu = folder / "ender.fmu"
    with zipfile.ZipFile(fmu, "w") as archive:
        description = model_description("ender", ENDER_VARIABLES).replace(
            "<ModelVariables>", DIRECTION + "<ModelVariables>").replace(
            '<Enumeration start="1"/>', '<Enumeration declaredType="Direction" start="1"/>')
        archive.writestr("modelDescription.xml", description)
        archive.write(library, "binaries/linux64/ender.so")
    return fmu


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
# The kinds skeletons (tests/third_party/kinds) know no end of the simulation: a copy of
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

    from tests.third_party.kinds import build as kinds

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


# --- a scene without FMU components --------------------------------------------------

EMPTY_SSD = """<?xml version="1.0" encoding="UTF-8"?>
<ssd:SystemStructureDescription version="1.0" name="setup"
    xmlns:ssd="http://ssp-standard.org/SSP1/SystemStructureDescription"
    xmlns:ssc="http://ssp-standard.org/SSP1/SystemStructureCommon"
    xmlns:ssv="http://ssp-standard.org/SSP1/SystemStructureParameterValues">
  <ssd:System name="root">
    <ssd:Connectors>
      <ssd:Connector name="k" kind="parameter"><ssc:Real/></ssd:Connector>
    </ssd:Connectors>
    <ssd:ParameterBindings><ssd:ParameterBinding><ssd:ParameterValues>
      <ssv:ParameterSet version="1.0" name="p"><ssv:Parameters>
        <ssv:Parameter name="k"><ssv:Real value="2.5"/></ssv:Parameter>
      </ssv:Parameters></ssv:ParameterSet>
    </ssd:ParameterValues></ssd:ParameterBinding></ssd:ParameterBindings>
  </ssd:System>
  <ssd:DefaultExperiment startTime="0" stopTime="0.5"/>
</ssd:SystemStructureDescription>
"""


@pytest.mark.parametrize("coupling", ["causal", "explicit", "iterative", "strong"])
def test_a_scene_without_components_runs_to_its_time_column(tmp_path, capsys, coupling):
    """Only system connectors and a parameter set (a parameter setup exported alone):
    validate says why in a warning, a run writes the time column and exits 0, --strict
    refuses it in one line."""
    folder = tmp_path / "setup"
    folder.mkdir()
    (folder / "SystemStructure.ssd").write_text(EMPTY_SSD)
    assert main(["validate", str(folder)]) == 0
    assert "has no FMU component" in capsys.readouterr().err
    out = tmp_path / "out.csv"
    assert main(["run", str(folder), "--out", str(out), "--coupling", coupling,
                 "--step", "0.1", "--quiet"]) == 0
    lines = out.read_text().split()
    assert lines[0] == "time"
    np.testing.assert_allclose([float(x) for x in lines[1:]], 0.1 * np.arange(6), atol=1e-15)
    result = dsim.simulate(folder, coupling=coupling, step=0.1)
    assert result.ok and len(result["time"]) == 6
    assert any("has no FMU component" in w for w in result.statistics["warnings"])
    capsys.readouterr()
    for command in (["validate"], ["run", "--out", str(tmp_path / "strict.csv")]):
        assert main([command[0], str(folder), "--strict", *command[1:]]) == 2
        errors = capsys.readouterr().err.strip().splitlines()
        assert len(errors) == 1 and "has no FMU component" in errors[0]


# --- .ssv enumeration values given as item names (SSP 1.0) ---------------------------

def _ssv(values: dict) -> str:
    """An .ssv of Enumeration parameters (``name: value text``)."""
    parameters = "".join(f'<ssv:Parameter name="{k}"><ssv:Enumeration value="{v}"/>'
                         "</ssv:Parameter>" for k, v in values.items())
    return ('<?xml version="1.0" encoding="UTF-8"?><ssv:ParameterSet version="1.0" '
            'name="set" xmlns:ssv="http://ssp-standard.org/SSP1/SystemStructureParameterValues">'
            f"<ssv:Parameters>{parameters}</ssv:Parameters></ssv:ParameterSet>")


def _enumeration_scene(folder: Path, fmu: Path, value: str) -> Path:
    text = ssd("enum", [component("a", "resources/ender.fmu", {"F": 2.0},
                                  outputs=("P.u_x",))], stop=0.5, master='step="0.1"')
    text = text.replace("<ssd:ParameterBinding>", '<ssd:ParameterBinding source='
                        '"resources/set.ssv"/><ssd:ParameterBinding>')
    folder = scene_folder(folder, text, {"ender.fmu": fmu})
    (folder / "resources" / "set.ssv").write_text(_ssv({"direction": value}))
    return folder


@pytest.mark.parametrize("value, sign", [("Pull", -1.0), ("Push", 1.0), ("2", -1.0)])
def test_an_enumeration_value_named_by_its_item_is_that_items_value(ender, tmp_path, value,
                                                                   sign):
    """<ssv:Enumeration value="Pull"/> sets the item Pull (2) of the FMU's type: the mass
    is pulled, x = -t^2; an integer is still read as the item's value."""
    result = dsim.simulate(_enumeration_scene(tmp_path / "scene", ender, value))
    assert result.ok
    np.testing.assert_allclose(result["a.P.u_x"], sign * result["time"] ** 2, atol=1e-12)


def test_an_enumeration_name_that_is_no_item_is_refused_in_one_line(ender, tmp_path, capsys):
    folder = _enumeration_scene(tmp_path / "scene", ender, "Sideways")
    assert main(["validate", str(folder)]) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1
    assert "parameter 'direction' = 'Sideways' is no item of 'a.direction' (its items: " \
        "Push, Pull)" in lines[0]


# --- startElement="" inside a nested system ------------------------------------------

def test_an_empty_start_element_in_a_nested_system_is_that_system(ender, tmp_path):
    """b (pushed by 2 N: its acceleration is 2 m/s^2) feeds the nested system's input
    connector sub.u; inside sub, startElement="" (as OMSimulator writes) is sub itself,
    carried on to a's port force: a, unpushed otherwise, moves as x = t^2."""
    b = component("b", "resources/ender.fmu", {"F": 2.0}, outputs=("P.a_x",))
    a = component("a", "resources/ender.fmu", outputs=("P.u_x",), inputs=("P.f_x",))
    sub = ('<ssd:System name="sub"><ssd:Connectors><ssd:Connector name="u" kind="input">'
           f"<ssc:Real/></ssd:Connector></ssd:Connectors><ssd:Elements>{a}</ssd:Elements>"
           '<ssd:Connections><ssd:Connection startElement="" startConnector="u" '
           'endElement="a" endConnector="P.f_x"/></ssd:Connections></ssd:System>')
    text = ssd("nested", [b, sub], [("b", "P.a_x", "sub", "u")], stop=0.5,
               master='step="0.1"')
    result = dsim.simulate(scene_folder(tmp_path / "scene", text, {"ender.fmu": ender}))
    assert result.ok
    np.testing.assert_allclose(result["sub.a.P.u_x"], result["time"] ** 2, atol=1e-12)


# --- Dymola-style connectors that name nothing ---------------------------------------

DYMOLA_CONNECTORS = ('<ssd:Connector name="_x_start" kind="parameter"><ssc:Real/>'
                     '</ssd:Connector><ssd:Connector name="fmi_StartTime" kind="parameter">'
                     '<ssc:Real/></ssd:Connector><ssd:Connector name="_v_start" '
                     'kind="parameter"><ssc:Real/></ssd:Connector><ssd:Connector '
                     'name="fmi_StopTime" kind="parameter"><ssc:Real/></ssd:Connector>')


def _dymola_scene(folder: Path, fmu: Path, connect_missing: bool = False) -> Path:
    """Two enders, each declaring four connectors its FMU does not have (as Dymola
    writes); b's port force fed by a's acceleration (and, ``connect_missing``, a's
    _x_start fed into b's _v_start, a connection through connectors that name nothing)."""
    parts = [component("a", "resources/ender.fmu", {"F": 2.0}, outputs=("P.a_x",)),
             component("b", "resources/ender.fmu", outputs=("P.u_x",), inputs=("P.f_x",))]
    parts = [p.replace("<ssd:Connectors>", "<ssd:Connectors>" + DYMOLA_CONNECTORS)
             for p in parts]
    links = [("a", "P.a_x", "b", "P.f_x")]
    if connect_missing:
        links.append(("a", "_x_start", "b", "_v_start"))
    text = ssd("dymola", parts, links, stop=0.5, master='step="0.1"')
    return scene_folder(folder, text, {"ender.fmu": fmu})


def test_unconnected_connectors_that_name_nothing_are_dropped_with_a_warning(
        ender, tmp_path, capsys):
    folder = _dymola_scene(tmp_path / "scene", ender)
    assert main(["validate", str(folder)]) == 0
    warned = [line for line in capsys.readouterr().err.splitlines() if "dropped" in line]
    assert len(warned) == 2  # one per component
    assert "4 connector(s) name no variable of ender.fmu and are connected to nothing: " \
        "dropped (_x_start, fmi_StartTime, _v_start, ...)" in warned[0]
    result = dsim.simulate(folder)
    assert result.ok  # b pushed by a's 2 m/s^2 from the start: x = t^2
    np.testing.assert_allclose(result["b.P.u_x"], result["time"] ** 2, atol=1e-12)
    assert main(["validate", "--strict", str(folder)]) == 2
    errors = capsys.readouterr().err.strip().splitlines()
    assert len(errors) == 2 and all("refused with --strict" in e for e in errors)


def test_a_connection_through_a_connector_that_names_nothing_is_one_error(ender, tmp_path,
                                                                          capsys):
    folder = _dymola_scene(tmp_path / "scene", ender, connect_missing=True)
    assert main(["validate", str(folder)]) == 2
    errors = [line for line in capsys.readouterr().err.splitlines()
              if line.startswith("dsim: error")]
    assert len(errors) == 1 and "'a' has no variable '_x_start'" in errors[0]


# --- Integer and Real ----------------------------------------------------------------

def _counting_scene(folder: Path, fmu: Path, declared: str = "Real",
                    backwards: bool = False) -> Path:
    """Block b1's Integer output count (the steps it took) declared ``declared`` and fed
    into block b2's Real input u (``backwards``: b2's Real y into b1's Integer extra)."""
    b1 = component("b1", "resources/block.fmu").replace(
        'source="resources/block.fmu">', 'source="resources/block.fmu"><ssd:Connectors>'
        f'<ssd:Connector name="count" kind="output"><ssc:{declared}/></ssd:Connector>'
        "</ssd:Connectors>")
    b2 = component("b2", "resources/block.fmu", {"y0": 0.0}, outputs=("y",))
    links = [("b2", "y", "b1", "extra")] if backwards else [("b1", "count", "b2", "u")]
    text = ssd("counting", [b1, b2], links, stop=0.5, master='step="0.1"')
    return scene_folder(folder, text, {"block.fmu": fmu})


def test_an_integer_output_feeds_a_real_input_exactly_with_warnings(block_fmus, tmp_path,
                                                                    capsys):
    """count declared ssc:Real (it is an Integer) feeds b2.u: both are warnings, the value
    is carried exactly: b2 lags behind the count it sees at each step's start,
    y(n+1) = 0.9 n + (y(n) - 0.9 n) exp(-h / 0.1).  A Real into an Integer stays refused."""
    folder = _counting_scene(tmp_path / "scene", block_fmus["state"])
    assert main(["validate", str(folder)]) == 0
    err = capsys.readouterr().err
    assert "connector 'count' is declared Real, but the FMU's variable is Integer: read as " \
        "Integer" in err
    assert "connects an Integer 'b1.count' to a Real 'b2.u': carried as a Real (exact)" in err
    result = dsim.simulate(folder)
    assert result.ok
    expected = [0.0]
    for n in range(5):
        expected.append(0.9 * n + (expected[-1] - 0.9 * n) * np.exp(-0.1 / 0.1))
    np.testing.assert_allclose(result["b2.y"], expected, rtol=1e-14, atol=1e-15)
    np.testing.assert_array_equal(result["b1.count"], np.arange(6))
    assert main(["validate", "--strict", str(folder)]) == 2
    assert len(capsys.readouterr().err.strip().splitlines()) == 2
    # a Real into an Integer would be rounded: still refused, one line
    folder = _counting_scene(tmp_path / "backwards", block_fmus["state"], "Integer", True)
    assert main(["validate", str(folder)]) == 2
    errors = capsys.readouterr().err.strip().splitlines()
    assert len(errors) == 1 and "connects a Real 'b2.y' to a Integer 'b1.extra'" in errors[0]


# --- an element order that changes nothing -------------------------------------------

def test_annotations_before_connectors_are_a_warning(ender, tmp_path, capsys):
    """<ssd:Annotations> before <ssd:Connectors> in a component (OMSimulator accepts it):
    read as if in order, with a warning; --strict refuses it."""
    part = component("a", "resources/ender.fmu", {"F": 2.0}, outputs=("P.u_x",)).replace(
        'source="resources/ender.fmu">', 'source="resources/ender.fmu"><ssd:Annotations>'
        '<ssc:Annotation type="com.example.tool"><note/></ssc:Annotation></ssd:Annotations>')
    text = ssd("order", [part], stop=0.3, master='step="0.1"')
    folder = scene_folder(tmp_path / "scene", text, {"ender.fmu": ender})
    assert main(["validate", str(folder)]) == 0
    assert "elements out of the order SSP 1.0 gives" in capsys.readouterr().err
    result = dsim.simulate(folder)
    np.testing.assert_allclose(result["a.P.u_x"], result["time"] ** 2, atol=1e-12)
    assert main(["validate", "--strict", str(folder)]) == 2


def _binding(values: dict) -> str:
    """One ssd:ParameterBindings of an inline parameter set of Real ``values``."""
    parameters = "".join(f'<ssv:Parameter name="{name}"><ssv:Real value="{value!r}"/>'
                         "</ssv:Parameter>" for name, value in values.items())
    return ("<ssd:ParameterBindings><ssd:ParameterBinding><ssd:ParameterValues>"
            f'<ssv:ParameterSet version="1.0" name="set"><ssv:Parameters>{parameters}'
            "</ssv:Parameters></ssv:ParameterSet></ssd:ParameterValues>"
            "</ssd:ParameterBinding></ssd:ParameterBindings>")


def test_an_element_repeated_where_ssp_allows_one_is_merged_in_order(ender, tmp_path,
                                                                      capsys):
    """As OMSimulator's importStartValues1 writes a system: its Annotations before its
    Connectors, and two ssd:ParameterBindings (SSP 1.0 allows one): read with one
    warning, the bindings merged in document order (the second's F = 2 N over the
    first's 8 N: x = t^2 on 1 kg; the first's m = 1 kg kept); --strict refuses it.  It
    was refused as not valid SSP 1.0."""
    from tests.scene_files import pack

    part = component("a", "resources/ender.fmu", outputs=("P.u_x",))
    text = ssd("repeated", [part], stop=0.3, master='step="0.1"').replace(
        '<ssd:System name="root">',
        '<ssd:System name="root"><ssd:Annotations><ssc:Annotation type="org.openmodelica">'
        "<note/></ssc:Annotation></ssd:Annotations><ssd:Connectors><ssd:Connector "
        'name="C1" kind="input"><ssc:Real/></ssd:Connector></ssd:Connectors>'
        + _binding({"a.m": 1.0, "a.F": 8.0}) + _binding({"a.F": 2.0}))
    archive = pack(scene_folder(tmp_path / "scene", text, {"ender.fmu": ender}),
                   tmp_path / "repeated.ssp")
    assert main(["validate", str(archive)]) == 0
    warnings = capsys.readouterr().err.strip().splitlines()
    assert len(warnings) == 1, warnings
    assert "ssd:ParameterBindings 2 times in system 'root'" in warnings[0]
    assert "merged in order" in warnings[0]
    result = dsim.simulate(archive)
    assert result.ok, result.statistics["message"]
    np.testing.assert_allclose(result["a.P.u_x"], result["time"] ** 2, atol=1e-12)
    assert main(["validate", "--strict", str(archive)]) == 2


# --- FMUs outside the scene: refused in one line, or trusted with --allow-outside -----

def _outside_scene(root: Path, fmu: Path, source: str = "../../fmi2/ender.fmu",
                   glued: bool = False) -> Path:
    """root/fmi2/ender.fmu beside root/scenes/loader/ (a platform's loader test): a
    (source ``source``) pushed by 2 N feeds b (inside the scene) through a connection;
    ``glued``: a and b in a fixed joint as well."""
    (root / "fmi2").mkdir(parents=True, exist_ok=True)
    shutil.copy(fmu, root / "fmi2" / "ender.fmu")
    a = component("a", source, {"F": 2.0}, outputs=("P.u_x", "P.a_x"))
    b = component("b", "resources/ender.fmu", outputs=("P.u_x",), inputs=("P.f_x",))
    gluing = '<glue:Joint name="j" a="a.P" b="c.P" dofs="x" kind="fixed"/>' if glued else ""
    parts = [a, b] + ([component("c", "resources/ender.fmu")] if glued else [])
    text = ssd("loader", parts, [("a", "P.a_x", "b", "P.f_x")], gluing=gluing, stop=0.3,
               master='step="0.1"')
    # a value for a, bound at the root system: nothing more to say once a is refused
    text = text.replace('<ssd:System name="root">', '<ssd:System name="root">'
                        "<ssd:ParameterBindings><ssd:ParameterBinding><ssd:ParameterValues>"
                        '<ssv:ParameterSet version="1.0" name="root"><ssv:Parameters>'
                        '<ssv:Parameter name="a.m"><ssv:Real value="1"/></ssv:Parameter>'
                        "</ssv:Parameters></ssv:ParameterSet></ssd:ParameterValues>"
                        "</ssd:ParameterBinding></ssd:ParameterBindings>")
    return scene_folder(root / "scenes" / "loader", text, {"ender.fmu": fmu})


@pytest.mark.parametrize("glued", [False, True])
def test_an_fmu_outside_the_scene_is_one_line_without_follow_on_errors(ender, tmp_path,
                                                                       capsys, glued):
    folder = _outside_scene(tmp_path, ender, glued=glued)
    for command in (["validate"], ["run", "--out", str(tmp_path / "out.csv")]):
        assert main([command[0], str(folder), *command[1:]]) == 2
        lines = capsys.readouterr().err.strip().splitlines()
        assert len(lines) == 1, lines
        assert "FMU source '../../fmi2/ender.fmu' is outside the scene (--allow-outside " \
            "DIR trusts a folder: docs/security.md)" in lines[0]
    assert not (tmp_path / "out.csv").exists()


def test_allow_outside_trusts_one_folder(ender, tmp_path, capsys):
    folder = _outside_scene(tmp_path, ender)
    trusted = str(tmp_path / "fmi2")
    assert main(["validate", str(folder), "--allow-outside", trusted]) == 0
    out = tmp_path / "out.csv"
    assert main(["run", str(folder), "--allow-outside", trusted, "--out", str(out),
                 "--quiet"]) == 0
    assert main(["info", str(folder), "--allow-outside", trusted]) == 0
    result = dsim.simulate(folder, allow_outside=trusted)
    np.testing.assert_allclose(result["a.P.u_x"], result["time"] ** 2, atol=1e-12)
    np.testing.assert_allclose(result["b.P.u_x"], result["time"] ** 2, atol=1e-12)
    # a folder that does not exist is one line
    capsys.readouterr()
    assert main(["validate", str(folder), "--allow-outside", str(tmp_path / "nowhere")]) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1 and "no such folder" in lines[0]


def test_sweep_and_regress_take_allow_outside_as_run_does(ender, tmp_path, capsys):
    """dsim sweep and dsim regress refused --allow-outside (a usage error); now every
    point and every case trusts the folder as dsim run does (without it, the scene is
    refused in one line, exit 2, as by dsim run)."""
    folder = _outside_scene(tmp_path, ender)
    trusted = str(tmp_path / "fmi2")
    out = tmp_path / "sweep"
    assert main(["sweep", str(folder), "--step", "0.1,0.05", "--out", str(out)]) == 2
    assert "is outside the scene" in capsys.readouterr().err
    assert main(["sweep", str(folder), "--step", "0.1,0.05", "--out", str(out),
                 "--allow-outside", trusted, "--target-error", "1"]) == 0
    said = capsys.readouterr().out
    assert "2 points (2 completed)" in said and f"--allow-outside {trusted}" in said
    for point in ("point_001", "point_002"):
        time, x = np.loadtxt(out / f"{point}.csv", delimiter=",", skiprows=1,
                             usecols=(0, 1), unpack=True)
        np.testing.assert_allclose(x, time ** 2, atol=1e-12)
    scenes = folder.parent  # root/scenes: the loader scene, its baseline stored beside
    assert main(["regress", str(scenes), "--update", "--no-kernel-study",
                 "--allow-outside", trusted]) == 0
    assert main(["regress", str(scenes)]) == 1  # refused without the trust: an error
    assert "is outside the scene" in capsys.readouterr().err
    assert main(["regress", str(scenes), "--allow-outside", trusted]) == 0
    assert "loader: passed" in capsys.readouterr().err


@pytest.mark.parametrize("attack", ["dotdot", "symlink", "link_in_trusted", "absolute"])
def test_allow_outside_trusts_nothing_beyond_its_folder(ender, tmp_path, capsys, attack):
    """With --allow-outside fmi2: a ../ escape to another folder, a link in the scene to
    a file outside both, a link inside the trusted folder that leads out of it, and an
    absolute path are all refused (links resolved before the check); without the
    option, a link to the trusted folder's FMU is refused too."""
    other = tmp_path / "other"
    other.mkdir()
    shutil.copy(ender, other / "ender.fmu")
    source = {"dotdot": "../../other/ender.fmu", "symlink": "resources/link.fmu",
              "link_in_trusted": "../../fmi2/link.fmu",
              "absolute": str(other / "ender.fmu")}[attack]
    folder = _outside_scene(tmp_path, ender, source)
    (folder / "resources" / "link.fmu").symlink_to(other / "ender.fmu")
    (tmp_path / "fmi2" / "link.fmu").symlink_to(other / "ender.fmu")
    assert main(["validate", str(folder), "--allow-outside", str(tmp_path / "fmi2")]) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1, lines
    assert ("is an absolute path" if attack == "absolute" else "is outside the scene and "
            "the folders --allow-outside trusts") in lines[0]
    # a link in the scene to the trusted folder's FMU: refused unless that folder is trusted
    (folder / "resources" / "trusted.fmu").symlink_to(tmp_path / "fmi2" / "ender.fmu")
    text = (folder / "SystemStructure.ssd").read_text().replace(source, "resources/trusted.fmu")
    (folder / "SystemStructure.ssd").write_text(text)
    assert main(["validate", str(folder)]) == 2
    capsys.readouterr()
    assert main(["validate", str(folder), "--allow-outside", str(tmp_path / "fmi2")]) == 0


# --- one error per cause, the most fundamental first ---------------------------------

def test_no_binary_for_this_platform_is_said_before_a_description_complaint(
        ender, tmp_path, capsys):
    """An FMU whose description names a unit it does not define (fmpy's check refuses
    it) and that has a library only for Windows: the one line says what no fix of the
    description would cure, no binary for this platform; its connection adds nothing."""
    broken = tmp_path / "windows.fmu"
    with zipfile.ZipFile(ender) as source, zipfile.ZipFile(broken, "w") as target:
        text = source.read("modelDescription.xml").decode().replace(
            'name="m" valueReference="0" causality="parameter" variability="fixed"><Real',
            'name="m" valueReference="0" causality="parameter" variability="fixed"><Real '
            'unit="kg"')
        assert 'unit="kg"' in text
        target.writestr("modelDescription.xml", text)
        target.writestr("binaries/win64/ender.dll", source.read("binaries/linux64/ender.so"))
    a = component("a", "resources/windows.fmu", outputs=("P.a_x",))
    b = component("b", "resources/ender.fmu", inputs=("P.f_x",))
    text = ssd("blocked", [a, b], [("a", "P.a_x", "b", "P.f_x")], stop=0.3)
    folder = scene_folder(tmp_path / "scene", text, {"ender.fmu": ender,
                                                      "windows.fmu": broken})
    assert main(["validate", str(folder)]) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1, lines
    assert "FMU windows.fmu: no binary for this platform (binaries/linux64/ender.so " \
        "missing; the FMU has win64)" in lines[0]
