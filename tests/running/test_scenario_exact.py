"""``--events exact`` (docs/scenarios.md): a step an event falls inside is cut at the
event's time, so the change takes effect there and not at the next communication
point; refused in one line where a step cannot be cut."""
import json

import numpy as np
import pytest

import dsim
from dsim.master.errors import InputError
from dsim.fmus.spring_mass.core import ChainParameters, SpringMassChain

POSITIONS = ("left.x[1]", "right.x[1]", "right.x[2]")


def _testbed(tmp_path, stop=3.0, step=0.01):
    from examples.testbed import Testbed, write_scene

    bed = Testbed(x0=0.01)
    return bed, write_scene(bed, tmp_path, "testbed", step, stop, tolerance=1e-12)


def _stiffer_at(tmp_path, time, name="stiffer.json"):
    path = tmp_path / name
    path.write_text(json.dumps({"events": [{"time": time, "model": "j", "variable": "k0",
                                            "action": "override", "value": 400.0}]}))
    return path


def _twin_cut(bed, step, steps, cut_step, part):
    """The testbed as one chain whose step ``cut_step`` is taken in two parts, the
    first ``part`` s long, its joint spring 400 N/m from the second part on."""
    def chain(k0):
        params = ChainParameters(n=3)
        params.m[:3] = bed.m1, bed.m2, bed.m3
        params.k[:2], params.c[:2] = (k0, bed.k), (bed.c0, bed.c)
        params.k_ground[0], params.x0[0], params.F0[2] = bed.kg, bed.x0, bed.F0
        made = SpringMassChain(params)
        made.initialize(0.0)
        return made

    one = chain(bed.k0)
    rows = [one.x[:3].copy()]
    for n in range(steps):
        if n == cut_step:
            one.step(n * step, part)
            state, one = one.get_state(), chain(400.0)
            one.set_state(state)
            one.step(n * step + part, step - part)
        else:
            one.step(n * step, step)
        rows.append(one.x[:3].copy())
    return np.array(rows)


def test_an_event_inside_a_step_takes_effect_at_its_own_time(built, tmp_path):
    """The testbed's joint four times as stiff at 1.004 s, steps of 0.01 s: the step
    from 1 s is taken as 4 ms then 6 ms, the law changed between (the monolithic chain
    cut the same: measured 5e-15 of each position's peak); the CSV keeps its rows on
    the 0.01 s grid; without --events exact the change waits for 1.01 s."""
    bed, scene = _testbed(tmp_path)
    scenario = _stiffer_at(tmp_path, 1.004)
    exact = dsim.simulate(scene, scenario=scenario, events="exact", handle_signals=False)
    assert exact.status == "completed", exact.message
    assert np.allclose(exact["time"], np.arange(301) * 0.01, rtol=0, atol=1e-12)
    twin = _twin_cut(bed, 0.01, 300, 100, 0.004)
    for k, name in enumerate(POSITIONS):
        assert np.max(np.abs(exact[name] - twin[:, k])) <= 1e-9 * np.max(np.abs(twin[:, k]))
    [applied] = exact.statistics["scenario"]["applied"]
    assert (applied["time"], applied["old"], applied["new"]) == (1.004, 100.0, 400.0)
    at_point = dsim.simulate(scene, scenario=scenario, handle_signals=False)
    assert at_point.statistics["scenario"]["applied"][0]["time"] == 1.01
    assert np.max(np.abs(at_point["left.x[1]"] - exact["left.x[1]"])) > 1e-4


def test_an_event_on_a_communication_point_is_the_same_exact_or_not(built, tmp_path):
    _, scene = _testbed(tmp_path)
    scenario = _stiffer_at(tmp_path, 1.0)
    exact = dsim.simulate(scene, scenario=scenario, events="exact", handle_signals=False)
    at_point = dsim.simulate(scene, scenario=scenario, handle_signals=False)
    for name in POSITIONS:
        assert np.array_equal(exact[name], at_point[name])


def test_dsim_info_says_which_step_is_cut(built, tmp_path, capsys):
    from dsim.master.tools.cli import main

    _, scene = _testbed(tmp_path)
    scenario = _stiffer_at(tmp_path, 1.004)
    assert main(["info", str(scene), "--scenario", str(scenario), "--events", "exact"]) == 0
    assert ("t = 1.004 s -> at t = 1.004 s (the step from point 100 cut there): j.k0 "
            "(joint law): override 400.0") in capsys.readouterr().out


def test_exact_events_refused_where_a_step_cannot_be_cut(built, tmp_path):
    from tests.support.scenes import oscillator_scene
    from tests.support.third_party.build import OSCILLATOR_VARIABLES, c_fmu

    _, scene = _testbed(tmp_path)
    scenario = _stiffer_at(tmp_path, 1.004)
    with pytest.raises(InputError, match="with --step auto the steps land on the output"):
        dsim.simulate(scene, scenario=scenario, events="exact", step="auto",
                      handle_signals=False)
    with pytest.raises(InputError, match="--events chooses when a scenario's events take "
                                         "effect: give --scenario with it"):
        dsim.simulate(scene, events="exact", handle_signals=False)
    with pytest.raises(InputError, match="events 'soon' is not one of: point, exact"):
        dsim.simulate(scene, scenario=scenario, events="soon", handle_signals=False)
    fixed = c_fmu(tmp_path / "c", "oscillator", "oscillator.c", OSCILLATOR_VARIABLES,
                  variable_step=False)
    folder = oscillator_scene(tmp_path / "scene", built, fixed)
    empty = tmp_path / "empty.json"
    empty.write_text('{"events": []}')
    with pytest.raises(InputError, match="--events exact cuts steps at the events' times, "
                       "and 'third' takes no communication step of another size "
                       r"\(canHandleVariableCommunicationStepSize is false\)"):
        dsim.simulate(folder, scenario=empty, events="exact", handle_signals=False)
