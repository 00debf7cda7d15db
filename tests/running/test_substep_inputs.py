"""Inputs over substeps: a component that takes several communication steps per macro
step (``--substeps``) gets its Real inputs extrapolated with their slope
(fmi2SetRealInputDerivatives) where its FMU declares canInterpolateInputs, and held
where it does not.

The scene: a first-order lag (tests/support/third_party/block.c, u = 0, y0 = 1,
tau = 1 s, stepped exactly: y = exp(-t)) drives the C oscillator (oscillator.c built
with -DINTERPOLATE: m = k = 1, s0 = 0, the trapezoidal rule with the force taken at
both ends of each step).  Closed form of s'' + s = exp(-t), s(0) = s'(0) = 0:
s = (exp(-t) - cos t + sin t) / 2.  The same binary, declaring canInterpolateInputs or
not, at the same macro step and substeps: held inputs lag the force by half a macro
step (first order in H), extrapolated ones are second order."""
from __future__ import annotations

import shutil

import numpy as np
import pytest

import dsim
from tests.support.scenes import archive_scene

pytestmark = pytest.mark.skipif(shutil.which("gcc") is None, reason="no C compiler")


def parameters(**values) -> str:
    """An ssd:ParameterBindings of inline Real values."""
    inner = "".join(f'<ssv:Parameter name="{name}"><ssv:Real value="{value!r}"/>'
                    "</ssv:Parameter>" for name, value in values.items())
    return ('<ssd:ParameterBindings><ssd:ParameterBinding><ssd:ParameterValues>'
            '<ssv:ParameterSet xmlns:ssv="http://ssp-standard.org/SSP1/'
            'SystemStructureParameterValues" version="1.0" name="p"><ssv:Parameters>'
            f"{inner}</ssv:Parameters></ssv:ParameterSet></ssd:ParameterValues>"
            "</ssd:ParameterBinding></ssd:ParameterBindings>")


RECORDED = ('<ssd:Connectors><ssd:Connector name="s" kind="output"><ssc:Real/>'
            "</ssd:Connector></ssd:Connectors>")


@pytest.fixture(scope="module")
def scenes(tmp_path_factory):
    """The lag driving the oscillator: ``held`` (the FMU declares no interpolation) and
    ``ramped`` (it declares canInterpolateInputs), one binary; and the ramped FMU."""
    from tests.support.third_party.build import BLOCK_VARIABLES, OSCILLATOR_VARIABLES, c_fmu

    folder = tmp_path_factory.mktemp("substep_inputs")
    block = c_fmu(folder, "block", "block.c", BLOCK_VARIABLES)
    found = {}
    for name, declared in (("held", False), ("ramped", True)):
        fmu = c_fmu(folder, name, "oscillator.c", OSCILLATOR_VARIABLES,
                    defines=("INTERPOLATE",), interpolate_inputs=declared)
        found[name] = archive_scene(
            folder / f"{name}.ssp", {"lag": (block, "", parameters(y0=1.0, tau=1.0)),
                                     "m": (fmu, "", RECORDED)},
            connections=[("lag", "y", "m", "F_in")], stop=10.0, step=0.1)
        found[f"{name}.fmu"] = fmu
    return found


def error(result) -> float:
    """The largest distance of the oscillator from the closed form (m)."""
    t = result["time"]
    return float(np.max(np.abs(result["m.s"] - 0.5 * (np.exp(-t) - np.cos(t) + np.sin(t)))))


def calls(result, function: str) -> int:
    return result.statistics["components"]["m"]["functions"].get(function, {}).get("calls", 0)


def test_extrapolated_inputs_make_the_error_ten_times_smaller(scenes):
    held = dsim.simulate(scenes["held"], substeps={"m": 4})
    ramped = dsim.simulate(scenes["ramped"], substeps={"m": 4})
    assert held.ok and ramped.ok
    print(f"held {error(held):.3g}, extrapolated {error(ramped):.3g}")
    assert 0.035 < error(held) < 0.042  # measured 0.0384
    assert 0.003 < error(ramped) < 0.004  # measured 0.00348
    assert error(held) / error(ramped) > 9
    assert ramped.statistics["substeps_input_derivatives"] == ["m"]
    assert held.statistics["substeps_input_derivatives"] == []
    # the slope at each of the 4 substeps of the 100 macro steps, and the extrapolated
    # values at the 3 substeps after each macro step's first
    assert calls(ramped, "fmi2SetRealInputDerivatives") == 400
    assert calls(held, "fmi2SetRealInputDerivatives") == 0
    assert calls(ramped, "fmi2SetReal") - calls(held, "fmi2SetReal") == 300


def test_held_inputs_are_first_order_extrapolated_ones_second(scenes):
    errors = {name: [error(dsim.simulate(scenes[name], step=step, substeps={"m": 4}))
                     for step in (0.1, 0.05)] for name in ("held", "ramped")}
    print(errors)
    held, ramped = (errors[name][0] / errors[name][1] for name in ("held", "ramped"))
    assert 1.8 < held < 2.2  # measured 0.0384 / 0.0191
    assert 3.6 < ramped < 4.4  # measured 0.00348 / 0.000867


def test_one_step_per_macro_step_is_unchanged(scenes):
    """substeps 1: no derivative is given, the FMU that declares interpolation runs
    bit for bit as the one that does not."""
    held, ramped = (dsim.simulate(scenes[name]) for name in ("held", "ramped"))
    assert np.array_equal(held["m.s"], ramped["m.s"])
    assert calls(ramped, "fmi2SetRealInputDerivatives") == 0
    assert ramped.statistics["substeps_input_derivatives"] == []
    assert calls(ramped, "fmi2SetReal") == calls(held, "fmi2SetReal")


def test_the_oscillator_honours_its_input_derivative(scenes, tmp_path):
    """The C FMU alone (fmpy): F(0) = 0 with slope 1 N/s set once, 100 steps of 0.01 s;
    s'' + s = t, s(0) = s'(0) = 0: s = t - sin t."""
    from fmpy import extract, read_model_description
    from fmpy.fmi2 import FMU2Slave

    fmu = scenes["ramped.fmu"]
    description = read_model_description(fmu)
    assert description.coSimulation.canInterpolateInputs
    refs = {v.name: v.valueReference for v in description.modelVariables}
    slave = FMU2Slave(guid=description.guid, unzipDirectory=extract(fmu, tmp_path / "x"),
                      modelIdentifier=description.coSimulation.modelIdentifier,
                      instanceName="alone")
    slave.instantiate()
    slave.setupExperiment(startTime=0.0)
    slave.enterInitializationMode()
    slave.exitInitializationMode()
    slave.setReal([refs["F_in"]], [0.0])
    slave.setRealInputDerivatives([refs["F_in"]], [1], [1.0])
    for k in range(100):
        slave.doStep(currentCommunicationPoint=k * 0.01, communicationStepSize=0.01)
    s = slave.getReal([refs["s"]])[0]
    slave.terminate()
    slave.freeInstance()
    assert abs(s - (1.0 - np.sin(1.0))) < 1e-5


def test_a_step_taken_again_extrapolates_from_the_values_before_it():
    """The slopes of InputSlopes: u = t^2 written at the macro steps' starts; a step
    taken again from 0.2 (a rejected step) and from 0.1 (further back) uses the values
    before that time, never those of the step given up."""
    from dsim.master.running.fmi.input_slopes import InputSlopes

    slopes = InputSlopes([0], (None, None), None, None)
    found = []
    for time in (0.0, 0.1, 0.2, 0.2, 0.1, 0.15):
        slopes.wrote([time ** 2])
        found.append(float(slopes.slope(time)[0]))
    # (0.01 - 0) / 0.1, (0.04 - 0.01) / 0.1 twice, 0.1 again from 0, 0.15 from 0.1
    assert np.allclose(found, [0.0, 0.1, 0.3, 0.3, 0.1, 0.25], rtol=1e-12, atol=1e-15)
