"""The small plain-C FMUs of tests/support/third_party/kinds, of every FMI kind (1.0
Co-Simulation, 2.0 and 3.0 Model Exchange and Co-Simulation), are real FMUs: fmpy
validates them, runs them alone (Model Exchange with its CVODE and Euler solvers,
Co-Simulation with a small output interval) and their results match the models'
closed forms; their FMU states, input interpolation, direct feedthrough and error
returns behave as the standard says, and a sanitizer-instrumented driver finds no
memory error or leak in them."""
from __future__ import annotations

import os
import shutil
import subprocess
import sys
import zipfile
from concurrent.futures import ThreadPoolExecutor
from ctypes import POINTER, c_char, c_double, c_int, c_size_t, c_uint, c_void_p
from xml.etree import ElementTree

import numpy as np
import pytest
from fmpy import extract, read_model_description, simulate_fmu
from fmpy.fmi1 import FMU1Slave, FMICallException
from fmpy.fmi2 import FMU2Model, FMU2Slave
from fmpy.fmi3 import FMU3Model, FMU3Slave
from fmpy.validation import validate_fmu
from scipy.linalg import expm

from tests.support.third_party.kinds import (CO_SIMULATION, MODEL_EXCHANGE, MODELS, build_fmu,
                                             build_memcheck)

ME, CS = MODEL_EXCHANGE, CO_SIMULATION
BOTH = (ME, CS)
#: every FMU the tests build: key -> build_fmu's arguments
BUILDS = {f"{m}-fmi{v[0]}": dict(model=m, fmi_version=v, interfaces=(CS,) if v == "1.0"
                                 else BOTH) for m in MODELS for v in ("1.0", "2.0", "3.0")}
BUILDS.update({
    "oscillator-fmi2-me": dict(model="oscillator", fmi_version="2.0", interfaces=(ME,)),
    "oscillator-fmi2-cs": dict(model="oscillator", fmi_version="2.0", interfaces=(CS,)),
    "oscillator-fmi3-me": dict(model="oscillator", fmi_version="3.0", interfaces=(ME,)),
    "oscillator-fmi3-cs": dict(model="oscillator", fmi_version="3.0", interfaces=(CS,)),
    "oscillator-fmi2-nostate": dict(model="oscillator", fmi_version="2.0",
                                    can_save_state=False),
    "oscillator-fmi3-nostate": dict(model="oscillator", fmi_version="3.0",
                                    can_save_state=False),
    "feedthrough-fmi1-gain": dict(model="feedthrough", fmi_version="1.0",
                                  interfaces=(CS,), identifier="gain"),
})
#: (FMI version, interface) of every way to run a model alone
RUNS = [("1.0", CS), ("2.0", ME), ("2.0", CS), ("3.0", ME), ("3.0", CS)]
RUN_IDS = ["fmi1-cs", "fmi2-me", "fmi2-cs", "fmi3-me", "fmi3-cs"]
CS_RUNS = [r for r in RUNS if r[1] == CS]
CS_IDS = [i for i, r in zip(RUN_IDS, RUNS) if r[1] == CS]
ME_VERSIONS = ["2.0", "3.0"]


def _workers() -> int:
    return max(2, os.cpu_count() or 2)


@pytest.fixture(scope="module")
def fmus(tmp_path_factory):
    """Every FMU of BUILDS, compiled once (in parallel: gcc runs in subprocesses)."""
    if shutil.which("gcc") is None:
        pytest.skip("no C compiler (gcc)")
    folder = tmp_path_factory.mktemp("kinds")
    with ThreadPoolExecutor(_workers()) as pool:
        paths = pool.map(lambda key: build_fmu(folder, name=key.replace("-", "_"),
                                               **BUILDS[key]), BUILDS)
        return dict(zip(BUILDS, paths))


def fmu_of(fmus, model: str, version: str):
    return fmus[f"{model}-fmi{version[0]}"]


def simulate(fmus, model, run, **options):
    """fmpy's simulate_fmu of a model in one of RUNS (CVODE with a tight tolerance for
    Model Exchange unless told otherwise, an output interval of 0.01 s)."""
    version, interface = run
    options.setdefault("output_interval", 0.01)
    if interface == ME and options.get("solver", "CVode") == "CVode":
        options.setdefault("relative_tolerance", 1e-8)
    return simulate_fmu(str(fmu_of(fmus, model, version)), fmi_type=interface, **options)


def fmi1_function(instance, name, *argtypes):
    """An FMI 1.0 function of the instance's library with its true signature: fmpy
    0.3.32 declares some (fmiDoStep, fmiSetRealInputDerivatives, ...) as returning a
    string, so that any status but fmiOK crashes it, and its
    setRealInputDerivatives calls fmiInitializeSlave."""
    function = instance.fmu.dll[f"{instance.fmu.modelIdentifier}_{name}"]
    function.argtypes, function.restype = [c_void_p, *argtypes], c_int
    return function


class Instance:
    """One instance of an FMU through fmpy's low-level classes, whatever its FMI
    version and interface."""

    CLASSES = {("1.0", CS): FMU1Slave, ("2.0", ME): FMU2Model, ("2.0", CS): FMU2Slave,
               ("3.0", ME): FMU3Model, ("3.0", CS): FMU3Slave}

    def __init__(self, path, interface=CS, guid=None):
        self.md = read_model_description(str(path))
        self.version, self.interface = self.md.fmiVersion, interface
        self.vr = {v.name: v.valueReference for v in self.md.modelVariables}
        self.folder = extract(str(path))
        kind = self.md.coSimulation if interface == CS else self.md.modelExchange
        self.fmu = self.CLASSES[self.version, interface](
            guid=guid or self.md.guid, unzipDirectory=self.folder,
            modelIdentifier=kind.modelIdentifier, instanceName="test")
        try:
            self.fmu.instantiate()
            if not self.fmu.component:  # fmpy's FMI 1.0 does not check
                raise Exception("Failed to instantiate the FMU")
        except Exception:
            self.fmu.freeLibrary()
            shutil.rmtree(self.folder, ignore_errors=True)
            raise

    def get(self, *names):
        vrs = [self.vr[n] for n in names]
        return (self.fmu.getFloat64 if self.version == "3.0" else self.fmu.getReal)(vrs)

    def set(self, **values):
        vrs = [self.vr[n] for n in values]
        setter = self.fmu.setFloat64 if self.version == "3.0" else self.fmu.setReal
        setter(vrs, [float(v) for v in values.values()])

    def initialize(self, parameters=None, start_time=0.0):
        """Set parameters, initialize and (Model Exchange) do the initial event."""
        if self.version == "2.0":
            self.fmu.setupExperiment(startTime=start_time)
        self.set(**(parameters or {}))
        if self.version == "1.0":
            self.fmu.initialize(tStart=start_time)
            return
        if self.version == "2.0":
            self.fmu.enterInitializationMode()
        else:
            self.fmu.enterInitializationMode(startTime=start_time)
        self.fmu.exitInitializationMode()
        if self.interface == ME:
            self.event()
            self.fmu.enterContinuousTimeMode()

    def event(self):
        """An event update (Model Exchange); returns nextEventTime or None."""
        update = (self.fmu.newDiscreteStates if self.version == "2.0"
                  else self.fmu.updateDiscreteStates)
        needed, _, _, _, defined, next_time = update()
        assert not needed
        return next_time if defined else None

    def step(self, t, h):
        if self.version == "1.0":  # fmpy's doStep would crash on an error (see above)
            do_step = fmi1_function(self, "fmiDoStep", c_double, c_double, c_char)
            status = do_step(self.fmu.component, t, h, b"\x01")
            if status > 1:
                raise FMICallException("fmi1DoStep", status)
        else:
            self.fmu.doStep(currentCommunicationPoint=t, communicationStepSize=h)

    def set_slope(self, name, slope):
        """The input's first derivative (fmi*SetRealInputDerivatives, order 1)."""
        if self.version == "1.0":
            function = fmi1_function(self, "fmiSetRealInputDerivatives", POINTER(c_uint),
                                     c_size_t, POINTER(c_int), POINTER(c_double))
            status = function(self.fmu.component, (c_uint * 1)(self.vr[name]), 1,
                              (c_int * 1)(1), (c_double * 1)(slope))
            if status > 1:
                raise FMICallException("fmi1SetRealInputDerivatives", status)
        else:
            self.fmu.setRealInputDerivatives([self.vr[name]], [1], [slope])

    # Model Exchange
    def states(self) -> np.ndarray:
        x = np.zeros(self.md.numberOfContinuousStates)
        self.fmu.getContinuousStates(x.ctypes.data_as(POINTER(c_double)), x.size)
        return x

    def derivatives(self, t, x) -> np.ndarray:
        x = np.ascontiguousarray(x, dtype=float)
        dx = np.zeros_like(x)
        self.fmu.setTime(t)
        self.fmu.setContinuousStates(x.ctypes.data_as(POINTER(c_double)), x.size)
        get = (self.fmu.getDerivatives if self.version == "2.0"
               else self.fmu.getContinuousStateDerivatives)
        get(dx.ctypes.data_as(POINTER(c_double)), dx.size)
        return dx

    def close(self):
        self.fmu.terminate()
        self.fmu.freeInstance()
        shutil.rmtree(self.folder, ignore_errors=True)


@pytest.fixture
def instances():
    """Open Instances (``instances(path, interface)``), closed after the test."""
    opened = []

    def open_instance(path, interface=CS, **kwargs):
        opened.append(Instance(path, interface, **kwargs))
        return opened[-1]

    yield open_instance
    for instance in opened:
        instance.close()


def max_error(actual, expected) -> float:
    return float(np.max(np.abs(np.asarray(actual) - np.asarray(expected))))


# ---------------------------------------------------------------- closed forms

def oscillator_exact(t, x0=1.0, v0=0.0, m=1.0, k=1.0, d=0.0, force=0.0):
    """x, v of m x'' + d x' + k x = force (constant), underdamped."""
    s, w0 = d / (2 * m), np.sqrt(k / m)
    wd = np.sqrt(w0 ** 2 - s ** 2)
    x_eq = force / k
    a0 = x0 - x_eq
    decay, c, sn = np.exp(-s * t), np.cos(wd * t), np.sin(wd * t)
    x = x_eq + decay * (a0 * c + (v0 + s * a0) / wd * sn)
    v = decay * (v0 * c - (s * v0 + a0 * w0 ** 2) / wd * sn)
    return x, v


def ball_impacts(h0=1.0, g=9.81, e=0.7, v_min=0.1):
    """Times of the impacts and of the rest of the ball."""
    v1 = np.sqrt(2 * g * h0)
    times, t, w = [np.sqrt(2 * h0 / g)], np.sqrt(2 * h0 / g), v1
    while e * w >= v_min:
        w *= e
        t += 2 * w / g
        times.append(t)
    return np.array(times)


def ball_exact(t, h0=1.0, g=9.81, e=0.7, v_min=0.1):
    """h, v of the bouncing ball at the times t (not at an impact)."""
    impacts = ball_impacts(h0, g, e, v_min)
    t = np.asarray(t, dtype=float)
    n = np.searchsorted(impacts, t)  # impacts before t
    start = np.where(n == 0, 0.0, impacts[np.maximum(n - 1, 0)])
    speed = np.where(n == 0, 0.0, np.sqrt(2 * g * h0) * e ** n)
    tau = t - start
    h = np.where(n == 0, h0, 0.0) + speed * tau - g / 2 * tau ** 2
    v = speed - g * tau
    rest = n >= len(impacts)
    return np.where(rest, 0.0, h), np.where(rest, 0.0, v)


def last_impact(t, h, v, g=9.81):
    """The time of the last impact before each sample, from its h and v (in flight)."""
    return t - (np.sqrt(v ** 2 + 2 * g * np.maximum(h, 0.0)) - v) / g


def two_mass_matrix(m1=1.0, k1=10.0, d1=0.0, m2=1.0, k2=10.0, d2=0.0, kc=100.0, dc=0.0):
    """s' = A s of the monolithic two-mass oscillator, s = (x1, v1, x2, v2)."""
    return np.array([[0, 1, 0, 0],
                     [-(k1 + kc) / m1, -(d1 + dc) / m1, kc / m1, dc / m1],
                     [0, 0, 0, 1],
                     [kc / m2, dc / m2, -(k2 + kc) / m2, -(d2 + dc) / m2]])


def signals(**columns):
    """An fmpy input table from columns of (time, value) pairs on the same times."""
    names = list(columns)
    times = [t for t, _ in columns[names[0]]]
    rows = [(t, *[columns[n][i][1] for n in names]) for i, t in enumerate(times)]
    return np.array(rows, dtype=[("time", float)] + [(n, float) for n in names])


# ---------------------------------------------------------------- descriptions

@pytest.mark.parametrize("key", list(BUILDS))
def test_validates(fmus, key):
    assert validate_fmu(str(fmus[key])) == []


def test_fmpy_validate_command_agrees(fmus):
    """`fmpy validate` on the command line finds no problem in any of them."""
    def run(path):
        return subprocess.run([sys.executable, "-m", "fmpy", "validate", str(path)],
                              capture_output=True, text=True)

    with ThreadPoolExecutor(_workers()) as pool:
        for key, done in zip(fmus, pool.map(run, fmus.values())):
            assert done.returncode == 0 and "No problems found" in done.stdout, \
                (key, done.stdout, done.stderr)


@pytest.mark.parametrize("version", ["1.0", "2.0", "3.0"])
@pytest.mark.parametrize("model", list(MODELS))
def test_declarations(fmus, model, version):
    """The modelDescription.xml declares what the C code does: interfaces and their
    capabilities, states in the C code's order, event indicators, units, the outputs'
    dependencies."""
    spec = MODELS[model]
    md = read_model_description(str(fmu_of(fmus, model, version)))
    assert md.numberOfContinuousStates == len(spec.states)
    assert md.numberOfEventIndicators == len(spec.event_indicators)
    assert (md.modelExchange is None) == (version == "1.0")
    if version == "1.0":  # fmpy does not read FMI 1.0's capabilities
        with zipfile.ZipFile(fmu_of(fmus, model, version)) as archive:
            root = ElementTree.fromstring(archive.read("modelDescription.xml"))
        capabilities = root.find("Implementation/CoSimulation_StandAlone/Capabilities")
        assert capabilities.get("canHandleVariableCommunicationStepSize") == "true"
        assert capabilities.get("canInterpolateInputs") == "true"
        assert root.get("guid") == md.guid
    else:
        assert md.coSimulation.canHandleVariableCommunicationStepSize
    variables = {v.name: v for v in md.modelVariables}
    units = {u.name: u for u in md.unitDefinitions}
    for var in spec.variables:
        declared = variables[var.name]
        assert declared.valueReference == var.vr
        assert declared.causality == var.causality
        assert declared.unit == var.unit
        if var.unit and version != "1.0":
            assert units[var.unit].baseUnit is not None
    if version == "1.0":
        return
    assert md.coSimulation.canGetAndSetFMUstate and md.modelExchange.canGetAndSetFMUstate
    if version == "2.0":
        assert md.coSimulation.canInterpolateInputs
    assert [d.variable.derivative.name for d in md.derivatives] == list(spec.states)
    outputs = {u.variable.name: [d.name for d in u.dependencies] for u in md.outputs}
    assert outputs == {v.name: list(v.depends) for v in spec.variables
                       if v.causality == "output"}
    if version == "3.0":
        assert [u.variable.name for u in md.eventIndicators] == list(spec.event_indicators)
        assert sum(v.causality == "independent" for v in md.modelVariables) == 1


def test_feedthrough_declared(fmus):
    """The outputs that depend directly on inputs say so (dsim's ports need it)."""
    expected = {"oscillator": {"P.a_x": ["P.f_x"], "P.u_x": [], "P.v_x": []},
                "feedthrough": {"y": ["u"]},
                "mass1": {"a1": ["F"], "x1": [], "v1": []},
                "mass2": {"F": ["x1", "v1"], "x2": [], "v2": [], "a2": ["x1", "v1"]}}
    for version in ("2.0", "3.0"):
        for model, outputs in expected.items():
            md = read_model_description(str(fmu_of(fmus, model, version)))
            inputs = {v.name for v in md.modelVariables if v.causality == "input"}
            found = {u.variable.name: [d.name for d in u.dependencies if d.name in inputs]
                     for u in md.outputs}
            assert found == outputs, (model, version)


def test_interface_choice_and_no_state(fmus):
    for key, me, cs in [("oscillator-fmi2-me", True, False),
                        ("oscillator-fmi2-cs", False, True),
                        ("oscillator-fmi3-me", True, False),
                        ("oscillator-fmi3-cs", False, True)]:
        md = read_model_description(str(fmus[key]))
        assert (md.modelExchange is not None, md.coSimulation is not None) == (me, cs)
    for key in ("oscillator-fmi2-nostate", "oscillator-fmi3-nostate"):
        md = read_model_description(str(fmus[key]))
        assert not md.coSimulation.canGetAndSetFMUstate
        assert not md.modelExchange.canGetAndSetFMUstate
    guids = {read_model_description(str(path)).guid for path in fmus.values()}
    assert len(guids) == len(fmus)


@pytest.mark.parametrize("run", RUNS, ids=RUN_IDS)
@pytest.mark.parametrize("model", list(MODELS))
def test_start_values_are_the_c_codes(fmus, instances, model, run):
    """The parameters' and inputs' start values of the C code are the XML's; the
    states are those of the parameters after initialization."""
    version, interface = run
    instance = instances(fmu_of(fmus, model, version), interface)
    spec = MODELS[model]
    starts = [v for v in spec.variables if v.start is not None]
    assert instance.get(*[v.name for v in starts]) == [v.start for v in starts]
    instance.initialize()
    if interface == ME:
        assert list(instance.states()) == instance.get(*spec.states)


# ---------------------------------------------------------------- the models alone

@pytest.mark.parametrize("run", RUNS, ids=RUN_IDS)
def test_oscillator_free(fmus, run):
    r = simulate(fmus, "oscillator", run, stop_time=10.0,
                 output=["P.u_x", "P.v_x", "P.a_x"])
    x, v = oscillator_exact(r["time"])
    tolerance = 1e-5 if run[1] == ME else 1e-6
    assert max_error(r["P.u_x"], x) < tolerance
    assert max_error(r["P.v_x"], v) < tolerance
    assert max_error(r["P.a_x"], -r["P.u_x"]) < 1e-12  # a = (F - k x - d v) / m
    assert r["time"][-1] == pytest.approx(10.0)


@pytest.mark.parametrize("run", RUNS, ids=RUN_IDS)
def test_oscillator_damped_and_forced(fmus, run):
    """d = 0.3, m = 2, k = 3, v0 = 0.5 and a constant force of 2 N on P.f_x."""
    p = dict(m=2.0, k=3.0, d=0.3, x0=1.0, v0=0.5)
    force = signals(**{"P.f_x": [(0.0, 2.0), (10.0, 2.0)]})
    r = simulate(fmus, "oscillator", run, stop_time=10.0, start_values=p, input=force,
                 output=["P.u_x", "P.v_x", "P.a_x"])
    x, v = oscillator_exact(r["time"], force=2.0, **p)
    tolerance = 1e-5 if run[1] == ME else 1e-6
    assert max_error(r["P.u_x"], x) < tolerance
    assert max_error(r["P.v_x"], v) < tolerance
    assert max_error(r["P.a_x"], (2.0 - 3.0 * x - 0.3 * v) / 2.0) < 10 * tolerance


@pytest.mark.parametrize("version", ME_VERSIONS)
def test_oscillator_euler(fmus, version):
    """fmpy's explicit Euler: first order in its step (1e-3 s)."""
    r = simulate(fmus, "oscillator", (version, ME), solver="Euler", step_size=1e-3,
                 output_interval=1e-3, stop_time=2.0, output=["P.u_x", "P.v_x"])
    x, v = oscillator_exact(r["time"])
    assert 1e-5 < max_error(r["P.u_x"], x) < 2e-3


@pytest.mark.parametrize("run", RUNS, ids=RUN_IDS)
def test_bouncing_ball(fmus, run):
    """The first two impacts at t1 = sqrt(2 h0/g) and t1 + 2 e v1/g (within 1e-4 s);
    the flights in between as the closed form; at rest after the last bounce."""
    r = simulate(fmus, "bouncing_ball", run, stop_time=3.0, output=["h", "v"])
    t, h, v = r["time"], r["h"], r["v"]
    impacts = ball_impacts()
    for i in (0, 1):  # samples in the flight after impact i tell its time
        flight = (t > impacts[i] + 0.02) & (t < impacts[i + 1] - 0.02)
        assert flight.sum() > 10
        assert max_error(last_impact(t[flight], h[flight], v[flight]), impacts[i]) < 1e-4
    away = np.min(np.abs(t[:, None] - impacts[None, :]), axis=1) > 1e-3
    h_exact, v_exact = ball_exact(t)
    assert max_error(h[away], h_exact[away]) < 1e-5
    assert max_error(v[away], v_exact[away]) < 1e-4
    assert h.min() > -1e-9
    resting = t > impacts[-1] + 1e-3
    assert resting.sum() > 10 and np.all(h[resting] == 0.0) and np.all(v[resting] == 0.0)


@pytest.mark.parametrize("version", ME_VERSIONS)
def test_bouncing_ball_euler(fmus, version):
    """fmpy's explicit Euler (1e-4 s) finds the impacts through the event indicator,
    to the accuracy of its step."""
    r = simulate(fmus, "bouncing_ball", (version, ME), solver="Euler", step_size=1e-4,
                 output_interval=1e-4, stop_time=1.6, output=["h", "v"])
    t, h, v = r["time"], r["h"], r["v"]
    impacts = ball_impacts()
    for i in (0, 1):
        flight = (t > impacts[i] + 0.02) & (t < impacts[i + 1] - 0.02)
        assert max_error(last_impact(t[flight], h[flight], v[flight]), impacts[i]) < 1e-3
    assert v.max() > 0.5 * 0.7 * np.sqrt(2 * 9.81)  # it bounced


@pytest.mark.parametrize("T", [0.5, 0.37])
@pytest.mark.parametrize("run", RUNS + [("2.0", "Euler"), ("3.0", "Euler")],
                         ids=RUN_IDS + ["fmi2-me-euler", "fmi3-me-euler"])
def test_time_event(fmus, run, T):
    """x = t before T, 2T - t after, to 1e-6; r switches at T exactly (Model
    Exchange: nextEventTime; Co-Simulation: its step ends there inside fmi*DoStep).
    The output grid of 0.03 s does not contain T."""
    options = dict(stop_time=1.0, output_interval=0.03, start_values={"T": T},
                   output=["x", "r"])
    if run[1] == "Euler":
        run, options["solver"], options["step_size"] = (run[0], ME), "Euler", 0.03
    r = simulate(fmus, "time_event", run, **options)
    t = r["time"]
    assert max_error(r["x"], np.where(t < T, t, 2 * T - t)) < 1e-6
    assert np.all(r["r"][t < T - 1e-9] == 1.0) and np.all(r["r"][t > T + 1e-9] == -1.0)


@pytest.mark.parametrize("run", RUNS, ids=RUN_IDS)
def test_feedthrough_alone(fmus, run):
    """y = g u + c for a ramp u = 2t: at once in Model Exchange; in Co-Simulation the
    input held over a step (fmpy sets it at the step's start): y(t + h) = g u(t) + c."""
    u = signals(u=[(0.0, 0.0), (1.0, 2.0)])
    r = simulate(fmus, "feedthrough", run, stop_time=1.0, output_interval=0.1,
                 start_values={"g": 0.5, "c": 1.0}, input=u, output=["u", "y"])
    t, y = r["time"], r["y"]
    if run[1] == ME:
        assert max_error(y, 0.5 * 2 * t + 1.0) < 1e-12
    else:
        assert max_error(y[1:], 0.5 * 2 * t[:-1] + 1.0) < 1e-12


def test_model_identifier(fmus):
    """The model identifier is the build's: it names the library and prefixes the
    FMI 1.0 functions (gain_fmiDoStep, ...)."""
    path = fmus["feedthrough-fmi1-gain"]
    assert read_model_description(str(path)).coSimulation.modelIdentifier == "gain"
    with zipfile.ZipFile(path) as archive:
        assert "binaries/linux64/gain.so" in archive.namelist()
    r = simulate_fmu(str(path), stop_time=0.5, output_interval=0.1,
                     input=signals(u=[(0.0, 4.0), (1.0, 4.0)]), output=["y"])
    assert np.all(r["y"] == 0.5 * 4.0 + 1.0)


@pytest.mark.parametrize("run", RUNS, ids=RUN_IDS)
def test_mass1_alone(fmus, run):
    r = simulate(fmus, "mass1", run, stop_time=2.0, output=["x1", "v1", "a1"])
    x, v = oscillator_exact(r["time"], x0=0.1, k=10.0)
    tolerance = 1e-5 if run[1] == ME else 1e-6
    assert max_error(r["x1"], x) < tolerance and max_error(r["v1"], v) < 10 * tolerance


@pytest.mark.parametrize("run", RUNS, ids=RUN_IDS)
def test_mass2_alone(fmus, run):
    """Mass 1 held at x1 = 0.05: x2 = kc x1/(k2 + kc) (1 - cos(w t)), F = kc (x2 - x1)."""
    inputs = signals(x1=[(0.0, 0.05), (2.0, 0.05)], v1=[(0.0, 0.0), (2.0, 0.0)])
    r = simulate(fmus, "mass2", run, stop_time=2.0, input=inputs,
                 output=["F", "x2", "v2", "a2"])
    w = np.sqrt(110.0)
    x2 = 100.0 * 0.05 / 110.0 * (1 - np.cos(w * r["time"]))
    tolerance = 1e-5 if run[1] == ME else 1e-6
    assert max_error(r["x2"], x2) < tolerance
    assert max_error(r["F"], 100.0 * (r["x2"] - 0.05)) < 1e-12
    assert max_error(r["a2"], -10.0 * r["x2"] - r["F"]) < 1e-12


# ---------------------------------------------------------------- coupled

@pytest.mark.parametrize("version", ME_VERSIONS)
def test_two_masses_model_exchange_coupled(fmus, instances, version):
    """The two halves' Model Exchange interfaces, coupled in one ODE (RK4, 1e-3 s),
    are the monolithic linear system: expm(A t) s0."""
    one = instances(fmu_of(fmus, "mass1", version), ME)
    two = instances(fmu_of(fmus, "mass2", version), ME)
    one.initialize()
    two.initialize()

    def f(t, s):
        two.set(x1=s[0], v1=s[1])
        two.derivatives(t, s[2:])  # sets time and states of mass 2
        (force,) = two.get("F")
        one.set(F=force)
        return np.concatenate([one.derivatives(t, s[:2]), two.derivatives(t, s[2:])])

    s = np.concatenate([one.states(), two.states()])
    assert list(s) == [0.1, 0.0, 0.0, 0.0]
    h, A, errors = 1e-3, two_mass_matrix(), []
    for n in range(2000):
        t = n * h
        k1 = f(t, s)
        k2 = f(t + h / 2, s + h / 2 * k1)
        k3 = f(t + h / 2, s + h / 2 * k2)
        k4 = f(t + h, s + h * k3)
        s = s + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        if (n + 1) % 100 == 0:
            errors.append(max_error(s, expm(A * (t + h)) @ [0.1, 0, 0, 0]))
    assert max(errors) < 1e-6


@pytest.mark.parametrize("run", CS_RUNS, ids=CS_IDS)
def test_two_masses_co_simulated(fmus, instances, run):
    """The two halves as Co-Simulation FMUs exchanging their coupling variables every
    step (inputs held over the step): the error against expm(A t) s0 is of the first
    order in the step, as a non-iterative co-simulation's."""
    version = run[0]

    def error(h):
        one = instances(fmu_of(fmus, "mass1", version))
        two = instances(fmu_of(fmus, "mass2", version))
        one.initialize()
        two.initialize()
        A, worst, n_steps = two_mass_matrix(), 0.0, round(2.0 / h)
        for n in range(n_steps):
            t = n * h
            x1, v1 = one.get("x1", "v1")
            two.set(x1=x1, v1=v1)
            (force,) = two.get("F")  # direct feedthrough of x1, v1
            one.set(F=force)
            two.step(t, h)
            one.step(t, h)
            if (n + 1) % round(0.1 / h) == 0:
                s = [*one.get("x1", "v1"), *two.get("x2", "v2")]
                worst = max(worst, max_error(s, expm(A * (t + h)) @ [0.1, 0, 0, 0]))
        return worst

    coarse, fine = error(2e-3), error(1e-3)
    assert fine < 0.05  # amplitudes: 0.1 m, 1 m/s
    assert 1.7 < coarse / fine < 2.3


@pytest.mark.parametrize("run", RUNS, ids=RUN_IDS)
def test_feedthrough_algebraic_loop(fmus, instances, run):
    """Two feedthroughs y1 -> u2, y2 -> u1: fixed-point iteration on the outputs read
    right after setting the inputs converges to y1 = (g1 c2 + c1) / (1 - g1 g2)."""
    version, interface = run
    path = fmu_of(fmus, "feedthrough", version)
    first, second = instances(path, interface), instances(path, interface)
    first.initialize({"g": 0.5, "c": 1.0})
    second.initialize({"g": 0.4, "c": 2.0})
    expected = (0.5 * 2.0 + 1.0) / (1 - 0.5 * 0.4)

    def solve():
        y1 = 0.0
        for _ in range(40):
            second.set(u=y1)
            (y2,) = second.get("y")
            first.set(u=y2)
            (y1,) = first.get("y")
        return y1, y2

    assert solve() == pytest.approx((expected, 0.4 * expected + 2.0), abs=1e-14)
    if interface == CS:  # and after a step
        first.step(0.0, 0.1)
        second.step(0.0, 0.1)
        assert solve() == pytest.approx((expected, 0.4 * expected + 2.0), abs=1e-14)


# ---------------------------------------------------------------- co-simulation API

@pytest.mark.parametrize("version", ["1.0", "2.0"])
def test_interpolated_inputs(fmus, instances, version):
    """canInterpolateInputs: with the slope of the force set each step (a ramp
    F = t, steps of 0.1 s) the oscillator follows x = t + cos t - sin t to round-off;
    held inputs are first order in the step.  A new value of the input holds it
    again."""
    path = fmu_of(fmus, "oscillator", version)
    errors = {}
    for with_slope in (True, False):
        osc = instances(path)
        osc.initialize()
        h, worst = 0.1, 0.0
        for n in range(50):
            t = n * h
            osc.set(**{"P.f_x": t})
            if with_slope:
                osc.set_slope("P.f_x", 1.0)
            osc.step(t, h)
            (x,) = osc.get("P.u_x")
            t1 = t + h
            worst = max(worst, abs(x - (t1 + np.cos(t1) - np.sin(t1))))
            if with_slope:  # the input at the end of the step is the ramp's
                assert osc.get("P.f_x")[0] == pytest.approx(t1, abs=1e-12)
        errors[with_slope] = worst
    assert errors[True] < 1e-9 and errors[False] > 1e-3

    feed = instances(fmu_of(fmus, "feedthrough", version))
    feed.initialize()
    feed.set(u=1.0)
    feed.set_slope("u", 2.0)
    feed.step(0.0, 0.25)
    assert feed.get("u", "y") == pytest.approx([1.5, 0.5 * 1.5 + 1.0], abs=1e-14)
    feed.set(u=3.0)  # holds again
    feed.step(0.25, 0.25)
    assert feed.get("u", "y") == pytest.approx([3.0, 2.5], abs=1e-14)


@pytest.mark.parametrize("run", [("2.0", CS), ("2.0", ME), ("3.0", CS), ("3.0", ME)],
                         ids=["fmi2-cs", "fmi2-me", "fmi3-cs", "fmi3-me"])
def test_fmu_state(fmus, instances, run):
    """Get, set, serialize and free FMU states across the time event of time_event:
    restoring a state restores the discrete state r and the next event too."""
    version, interface = run
    te = instances(fmu_of(fmus, "time_event", version), interface)
    te.initialize()
    if interface == ME:
        x = te.states()
        for n in range(40):  # to 0.4 s with Euler (x' = 1)
            x = x + 0.01 * te.derivatives(0.01 * n, x)
        te.fmu.setTime(0.4)
        te.fmu.setContinuousStates(x.ctypes.data_as(POINTER(c_double)), 1)
    else:
        te.step(0.0, 0.4)
    state = te.fmu.getFMUState()
    serialized = te.fmu.serializeFMUState(state)

    def after():
        if interface == ME:
            te.fmu.setTime(0.5)
            te.fmu.enterEventMode()
            assert te.event() is None  # no more time events
            te.fmu.enterContinuousTimeMode()
        else:
            te.step(0.4, 0.2)
        return te.get("x", "r")

    first = after()
    assert first[1] == -1.0
    te.fmu.setFMUState(state)
    assert te.get("r") == [1.0]
    assert after() == first
    copy = te.fmu.deserializeFMUState(serialized)
    te.fmu.setFMUState(copy)
    assert te.get("r") == [1.0]
    assert after() == first
    te.fmu.freeFMUState(copy)
    te.fmu.freeFMUState(state)
    assert not state and not copy


@pytest.mark.parametrize("key", ["oscillator-fmi2-nostate", "oscillator-fmi3-nostate"])
def test_no_state(fmus, instances, key):
    osc = instances(fmus[key])
    osc.initialize()
    with pytest.raises(FMICallException):
        osc.fmu.getFMUState()
    osc.step(0.0, 0.1)  # still runs


@pytest.mark.parametrize("run", RUNS, ids=RUN_IDS)
def test_errors_not_crashes(fmus, instances, run):
    """fmi*Error on a null instance, an unknown value reference, a variable that is not
    settable (an output; a parameter after initialization), a wrong guid; empty calls of
    the types the models do not have succeed."""
    version, interface = run
    path = fmu_of(fmus, "oscillator", version)
    with pytest.raises(Exception, match="(?i)instantiate"):
        Instance(path, interface, guid="{00000000-0000-0000-0000-000000000000}")
    osc = instances(path, interface)
    osc.initialize()
    fmu = osc.fmu
    values = (c_double * 1)()
    vrs = (c_uint * 1)(osc.vr["P.u_x"])
    raw = {"1.0": lambda c: fmu.fmi1GetReal(c, vrs, 1, values),
           "2.0": lambda c: fmu.fmi2GetReal(c, vrs, 1, values),
           "3.0": lambda c: fmu.fmi3GetFloat64(c, vrs, 1, values, 1)}[version]
    raw(fmu.component)
    with pytest.raises(FMICallException):
        raw(None)
    get = fmu.getFloat64 if version == "3.0" else fmu.getReal
    with pytest.raises(FMICallException):
        get([99])
    with pytest.raises(FMICallException):
        osc.set(**{"P.u_x": 1.0})
    with pytest.raises(FMICallException):
        osc.set(m=2.0)
    osc.set(**{"P.f_x": 1.0})  # inputs are settable
    if version == "3.0":
        assert list(fmu.getInt32([])) == [] and list(fmu.getBoolean([])) == []
    else:
        assert list(fmu.getInteger([])) == [] and list(fmu.getBoolean([])) == []
    if interface == CS:
        with pytest.raises(FMICallException):
            osc.step(0.0, -0.1)


# ---------------------------------------------------------------- memory

MEMCHECKS = [(m, v, True) for m in MODELS for v in ("1.0", "2.0", "3.0")] + \
    [("oscillator", "2.0", False), ("bouncing_ball", "3.0", False)]


def test_memory_safety(tmp_path_factory):
    """memcheck.c drives every FMU (skeleton + model) through its API, both interfaces,
    FMU states and failing calls, under AddressSanitizer/LeakSanitizer/UBSan."""
    if shutil.which("gcc") is None:
        pytest.skip("no C compiler (gcc)")
    folder = tmp_path_factory.mktemp("memcheck")
    try:
        build_memcheck(folder, "feedthrough", "2.0", name="probe")
    except subprocess.CalledProcessError as error:
        pytest.skip(f"gcc has no sanitizers here: {error.stderr[-300:]}")

    def check(case):
        model, version, state = case
        program = build_memcheck(folder, model, version, state,
                                 name=f"{model}_{version[0]}_{int(state)}")
        return case, subprocess.run([str(program)], capture_output=True, text=True,
                                    env={**os.environ, "ASAN_OPTIONS": "detect_leaks=1"})

    with ThreadPoolExecutor(_workers()) as pool:
        for case, done in pool.map(check, MEMCHECKS):
            assert done.returncode == 0, (case, done.stderr[-2000:])
