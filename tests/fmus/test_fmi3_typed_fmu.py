"""The FMI 3.0 Co-Simulation FMU typed_array (tests/support/third_party/kinds/typed_array3.c,
built by build_typed_array) is valid and correct in fmpy alone: its arrays (a
parameter k, an input u, an output x, all of 3 Float64), Float32, Int32, Int64, UInt8,
Boolean, String and Enumeration variables read and write as declared, its states
follow the closed form x_i(t) = c_i + (x_i(0) - c_i) exp(-k_i t), c_i = gain8 u_i / k_i,
and its FMU states restore everything."""
from __future__ import annotations

import shutil

import numpy as np
import pytest
from fmpy import extract, read_model_description, simulate_fmu
from fmpy.fmi1 import FMICallException
from fmpy.fmi3 import FMU3Slave
from fmpy.validation import validate_fmu

from tests.support.third_party.kinds.build import (TYPED_ARRAY_MODES, TYPED_ARRAY_VARIABLES,
                                                   build_typed_array)

VR = {name: v[0] for name, v in TYPED_ARRAY_VARIABLES.items()}
OFF, ON = TYPED_ARRAY_MODES["Off"], TYPED_ARRAY_MODES["On"]
K = np.array([1.0, 2.0, 3.0])  # the start of k
U = np.array([1.0, 0.0, 2.0])
OUTPUTS = ["x", "x_sum", "steps", "positive", "mode"]


@pytest.fixture(scope="module")
def fmus(tmp_path_factory):
    if shutil.which("gcc") is None:
        pytest.skip("no C compiler (gcc)")
    folder = tmp_path_factory.mktemp("typed_array")
    return {"state": build_typed_array(folder),
            "nostate": build_typed_array(folder, can_save_state=False)}


def closed_form(t, k=K, u=U, gain8=1, x0=1.0):
    c = gain8 * np.asarray(u) / np.asarray(k)
    return c + (x0 - c) * np.exp(-np.outer(t, k))


class Slave:
    """An instance of typed_array through fmpy's FMU3Slave, its errors logged."""

    def __init__(self, fmu, tmp_path, guid=None):
        self.md = read_model_description(str(fmu))
        self.messages = []
        self.fmu = FMU3Slave(guid=guid or self.md.guid, unzipDirectory=extract(
            str(fmu), str(tmp_path / "unzipped")),
            modelIdentifier=self.md.coSimulation.modelIdentifier, instanceName="ta")
        self.fmu.instantiate(logMessage=lambda env, status, category, message:
                             self.messages.append(message.decode()))
        self.t = 0.0

    def start(self, **parameters):
        for name, value in parameters.items():
            setter = {"k": self.fmu.setFloat64, "offset": self.fmu.setInt64,
                      "label": self.fmu.setString}[name]
            setter([VR[name]], list(value) if isinstance(value, (list, tuple)) else [value])
        self.fmu.enterInitializationMode(startTime=0.0)
        self.fmu.exitInitializationMode()

    def step(self, h=0.01, n=1):
        for _ in range(n):
            self.fmu.doStep(self.t, h)
            self.t += h

    def x(self):
        return np.array(self.fmu.getFloat64([VR["x"]], nValues=3))

    def read(self):
        f = self.fmu
        return dict(x=self.x(), x_sum=f.getFloat32([VR["x_sum"]])[0],
                    steps=f.getInt32([VR["steps"]])[0],
                    positive=f.getBoolean([VR["positive"]])[0],
                    status=f.getString([VR["status"]])[0], mode=f.getInt64([VR["mode"]])[0],
                    label=f.getString([VR["label"]])[0])

    def close(self):
        self.fmu.terminate()
        self.fmu.freeInstance()


@pytest.fixture
def slave(fmus, tmp_path):
    instance = Slave(fmus["state"], tmp_path)
    yield instance
    instance.close()


def test_valid_and_declared(fmus):
    for fmu in fmus.values():
        assert validate_fmu(str(fmu)) == []
    md = read_model_description(str(fmus["state"]))
    assert md.fmiVersion == "3.0" and md.modelExchange is None
    assert md.coSimulation.canGetAndSetFMUstate  # (fmpy spells it so)
    assert md.coSimulation.canHandleVariableCommunicationStepSize
    nostate = read_model_description(str(fmus["nostate"]))
    assert not nostate.coSimulation.canGetAndSetFMUstate
    variables = {v.name: v for v in md.modelVariables}
    assert set(variables) == set(TYPED_ARRAY_VARIABLES)
    for name, (vr, type_, size, start) in TYPED_ARRAY_VARIABLES.items():
        v = variables[name]
        assert (v.valueReference, v.type) == (vr, type_)
        assert v.shape == ((size,) if size > 1 else ())
        if start is None:
            assert v.start is None
        elif size > 1:
            assert [float(s) for s in v.start.split()] == list(start)
        else:
            assert v.start == str(start)
    assert variables["time"].causality == "independent"
    assert variables["k"].causality == "parameter" and variables["k"].variability == "fixed"
    assert {i.name: int(i.value) for i in variables["mode"].declaredType.items} == \
        {"Off": 1, "On": 2}
    depends = {o.variable.name: [d.name for d in o.dependencies] for o in md.outputs}
    assert depends == {"x": [], "x_sum": [], "steps": [], "positive": [], "status": [],
                       "mode": ["u"]}
    assert {u.variable.name for u in md.initialUnknowns} == set(depends)


@pytest.mark.parametrize("case", [
    dict(),
    dict(gain8=2, start_values={"k": [0.5, 2.0, 4.0], "offset": 5, "label": "abc"}),
], ids=["starts", "set"])
def test_simulate_fmu_matches_closed_form(fmus, case):
    """fmpy's simulate_fmu with u = (1, 0, 2) as a structured (time, u[3], gain8) input:
    x is the closed form to 1e-12, the other outputs follow."""
    gain8, start_values = case.get("gain8", 1), case.get("start_values", {})
    k = np.array(start_values.get("k", K))
    signals = np.array([(0.0, U, gain8), (1.0, U, gain8)],
                       dtype=[("time", np.float64), ("u", np.float64, (3,)),
                              ("gain8", np.uint8)])
    r = simulate_fmu(str(fmus["state"]), stop_time=1.0, output_interval=0.01,
                     input=signals, output=OUTPUTS, start_values=start_values)
    assert len(r) == 101 and r["time"][-1] == pytest.approx(1.0)
    assert r["x"].shape == (101, 3)
    error = np.max(np.abs(r["x"] - closed_form(r["time"], k, U, gain8)))
    print(f"max |x - closed form| = {error:.3g}")
    assert error < 1e-12
    assert r["x_sum"].dtype == np.float32
    assert np.array_equal(r["x_sum"], r["x"].sum(axis=1).astype(np.float32))
    assert r["steps"].dtype == np.int32
    assert list(r["steps"]) == [start_values.get("offset", 0) + i for i in range(101)]
    assert r["positive"].all() and (r["mode"] == ON).all()


def test_typed_values_by_hand(slave):
    f = slave.fmu
    assert slave.read()["status"] == "typed:0" and slave.read()["label"] == "typed"
    assert f.getInt64([VR["offset"], VR["mode"]]) == [0, OFF]
    assert f.getUInt8([VR["gain8"]]) == [1]
    slave.start(label="run", offset=10)
    # one call, several arrays: k, u, x and time (nValues = 3 + 3 + 3 + 1)
    assert f.getFloat64([VR["k"], VR["u"], VR["x"], VR["time"]], nValues=10) == \
        [1.0, 2.0, 3.0, 0.0, 0.0, 0.0, 1.0, 1.0, 1.0, 0.0]
    f.setFloat64([VR["u"]], list(U))
    assert f.getInt64([VR["mode"]]) == [ON]  # directly: mode depends on u
    slave.step(0.01, 3)
    values = slave.read()
    assert np.abs(values["x"] - closed_form([0.03])[0]).max() < 1e-12
    assert values["x_sum"] == np.float32(values["x"].sum())
    assert isinstance(values["x_sum"], float) and values["x_sum"] != values["x"].sum()
    assert (values["steps"], values["positive"], values["mode"]) == (13, True, ON)
    assert (values["status"], values["label"]) == ("run:13", "run")
    f.setFloat64([VR["u"]], [0.0, 0.0, 0.0])
    assert f.getInt64([VR["mode"]]) == [OFF]
    # gain8 multiplies u; a negative sum makes positive false
    f.setUInt8([VR["gain8"]], [3])
    f.setFloat64([VR["u"]], [-4.0, -4.0, -4.0])
    x0 = slave.x()
    slave.step(0.5, 4)
    c = 3 * -4.0 / K
    assert np.abs(slave.x() - (c + (x0 - c) * np.exp(-2.0 * K))).max() < 1e-12
    values = slave.read()
    assert values["x_sum"] < 0 and values["positive"] is False
    assert values["status"] == "run:17"


def test_errors(slave):
    f = slave.fmu
    bad = [
        lambda: f.getFloat64([VR["x"]]),  # nValues 1 for an array of 3
        lambda: f.getFloat64([VR["x"], VR["k"]], nValues=7),
        lambda: f.setFloat64([VR["u"]], [1.0, 2.0]),
        lambda: f.getFloat64([99]),  # unknown
        lambda: f.getFloat64([VR["x_sum"]]),  # a Float32
        lambda: f.getFloat32([VR["x"]], nValues=3),
        lambda: f.getInt32([VR["mode"]]),  # an Enumeration is an Int64
        lambda: f.setFloat64([VR["x"]], [0.0, 0.0, 0.0]),  # an output
        lambda: f.setInt64([VR["mode"]], [ON]),
        lambda: f.setString([VR["status"]], ["no"]),
        lambda: f.setString([VR["label"]], ["x" * 64]),  # too long
        lambda: f.setInt64([VR["offset"]], [2 ** 31]),  # steps is an Int32
        lambda: f.getInt8([VR["steps"]]),
        lambda: slave.step(),  # not initialized
    ]
    for call in bad:
        with pytest.raises(FMICallException):
            call()
    assert len(slave.messages) == len(bad)
    assert "nValues is 1, the variables have 3" in slave.messages[0]
    slave.start()
    with pytest.raises(FMICallException):  # fixed parameters are fixed now
        f.setFloat64([VR["k"]], [1.0, 1.0, 1.0])
    with pytest.raises(FMICallException):
        f.setString([VR["label"]], ["late"])
    with pytest.raises(FMICallException):  # the step must start where the FMU is
        f.doStep(0.5, 0.1)
    with pytest.raises(FMICallException):
        f.doStep(0.0, -0.1)
    with pytest.raises(FMICallException):  # no event mode
        f.enterEventMode()
    null_instance = f.dll.fmi3DoStep(None, 0.0, 0.1, True, None, None, None, None)
    assert null_instance == 3  # fmi3Error
    f.setFloat64([VR["u"]], list(U))  # an input: settable at any time
    f.setUInt8([VR["gain8"]], [2])
    f.enterStepMode()
    slave.step()
    assert slave.read()["steps"] == 1


def test_fmu_state_restores_everything(slave):
    f = slave.fmu
    slave.start(offset=-2)
    f.setFloat64([VR["u"]], list(U))
    slave.step(0.01, 10)
    state, t = f.getFMUState(), slave.t
    saved = slave.read()
    assert saved["steps"] == 8 and saved["status"] == "typed:8"
    f.setFloat64([VR["u"]], [0.0, 0.0, 0.0])
    f.setUInt8([VR["gain8"]], [0])
    slave.step(0.05, 6)
    moved = slave.read()
    assert moved["steps"] == 14 and not np.array_equal(moved["x"], saved["x"])
    assert moved["mode"] == OFF
    f.setFMUState(state)
    slave.t = t
    restored = slave.read()
    for key in saved:
        assert np.array_equal(restored[key], saved[key]), key
    assert f.getFloat64([VR["time"], VR["u"]], nValues=4) == [pytest.approx(0.1)] + list(U)
    assert f.getUInt8([VR["gain8"]]) == [1]
    # the same steps again give the same values, bit for bit (also from a serialized state)
    serialized = f.serializeFMUState(state)
    slave.step(0.01, 5)
    again = slave.x()
    copy = f.deserializeFMUState(serialized)
    f.setFMUState(copy)
    f.freeFMUState(copy)
    slave.t = t
    slave.step(0.01, 5)
    assert np.array_equal(slave.x(), again)
    assert np.abs(again - closed_form([slave.t])[0]).max() < 1e-12
    assert slave.read()["status"] == "typed:13"
    f.freeFMUState(state)
    # reset: the start values again
    f.reset()
    assert slave.read()["status"] == "typed:0"
    assert list(slave.x()) == [1.0, 1.0, 1.0]


def test_no_state_and_foreign_token(fmus, tmp_path):
    slave = Slave(fmus["nostate"], tmp_path / "nostate")
    slave.start()
    with pytest.raises(FMICallException):
        slave.fmu.getFMUState()
    slave.step()
    assert slave.read()["steps"] == 1
    slave.close()
    with pytest.raises(Exception, match="Failed to instantiate"):
        Slave(fmus["state"], tmp_path / "foreign", guid="{not-this-fmu}")
