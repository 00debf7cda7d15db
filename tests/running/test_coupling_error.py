"""No run quietly inaccurate: a fixed-step run estimates its connections' coupling error
as it runs (master/running/coupling_error.py), the statistics and the summary give it,
and where it passes 0.1 % of a connected value's range per step the run warns once,
naming the connections and the remedies.  The two-mass oscillator split in two C FMUs
against its closed form: the causal exchange at 1 ms ends half its amplitude off after
10 s; the strong coupling at 1 ms 5e-4 of it."""
from __future__ import annotations

import json
import shutil

import numpy as np
import pytest

import dsim
from dsim.master.running.coupling_error import CouplingErrorWatch
from dsim.master.tools.cli import main
from tests.support.closed_forms import LINKS, exact_x1
from tests.support.scenes import archive_scene

pytestmark = pytest.mark.skipif(shutil.which("gcc") is None, reason="no C compiler")


@pytest.fixture(scope="module")
def oscillator(tmp_path_factory):
    """The two-mass oscillator's archive for a coupling: (path, coupling) -> .ssp."""
    from tests.support.third_party.kinds.build import mass_fmus

    folder = tmp_path_factory.mktemp("held")
    fmus = mass_fmus(folder)

    def archive(coupling: str, step: float = 0.001, stop: float = 10.0):
        return archive_scene(folder / f"{coupling}_{step}.ssp",
                     {name: (fmu, "CoSimulation", "") for name, fmu in fmus.items()},
                     LINKS, stop=stop, step=step, master=f'coupling="{coupling}"')
    return archive


def test_a_causal_run_far_from_its_closed_form_says_so(oscillator, tmp_path, capsys):
    path = oscillator("causal")
    out = tmp_path / "causal.csv"
    assert main(["run", str(path), "--out", str(out)]) == 0
    printed = capsys.readouterr()
    statistics = json.loads(out.with_suffix(".stats.json").read_text())
    held = statistics["coupling_error"]
    print(held)
    # measured: 0.72 % of mass2.F's range per step (x1 0.51 %, v1 0.70 %)
    assert 0.005 < held["largest"] < 0.01
    assert set(held["per_connection"]) == {"mass1.x1", "mass1.v1", "mass2.F"}
    warnings = [w for w in statistics["warnings"] if "coupling error" in w]
    assert len(warnings) == 1
    assert "mass2.F" in warnings[0] and "--coupling strong" in warnings[0]
    assert "--step auto" in warnings[0] and "Model Exchange" in warnings[0]
    assert "coupling error" in printed.err + printed.out
    assert "error estimate: a connected value off by up to 0.72 %" in printed.out
    # and the run is indeed far off: half the amplitude after 10 s
    result = dsim.simulate(path)
    assert np.max(np.abs(result["mass1.x1"] - exact_x1(result["time"]))) > 0.1 * 0.1


def test_a_strong_run_close_to_its_closed_form_does_not_warn(oscillator):
    result = dsim.simulate(oscillator("strong"))
    held = result.statistics["coupling_error"]
    assert held["largest"] < 1e-4  # measured 1.3e-5: second differences, not first
    assert not [w for w in result.warnings if "coupling error" in w]
    assert np.max(np.abs(result["mass1.x1"] - exact_x1(result["time"]))) < 1e-3 * 0.1


def test_a_run_without_connections_has_no_estimate(built):
    result = dsim.simulate(built["ssp"] / "spring_mass_linear.ssp", stop=0.05)
    assert result.statistics["coupling_error"] is None


def test_the_watch_takes_first_differences_of_held_and_second_of_iterated_values():
    watch = CouplingErrorWatch([0, 1], ["held", "iterated"], [False, True])
    for t in np.linspace(0.0, 1.0, 11):  # u = t^2 at h = 0.1: u'' h^2 = 0.02
        watch.add(np.array([t * t, t * t]))
    held, iterated = watch.relative()
    assert held == pytest.approx(1.9 / 10)  # the last step: 1 - 0.81 over a range of 1
    assert iterated == pytest.approx(0.02 / 8)
