"""The causal kernel (dsim.master.running.fmi.causal_kernel.CausalKernel) against the
template step it replaces: a system without joints must give the same CSV, byte for
byte, the same ending and the same FMI calls counted whether its steps go through the
kernel or through the coupling's template step (one exchange_with per subsystem).

Scenes of the plain-C block FMU (tests/support/third_party/block.c): a ring of Real
connections (every FMU fused), one with a scaled connection (the transfer's linear
map), one with an Integer connection (two FMUs the kernel calls through exchange_with,
beside fused ones), and rings where one block fails in its step (fmi2Error,
fmi2Discard) or makes its output NaN, at a step in the middle of the run.
"""
from __future__ import annotations

import json

import pytest

import dsim
from dsim.master.running.backends.base import Backend
from dsim.master.running.backends.inprocess import InProcessBackend
from tests.support.scene_files import HEADER, scene_folder


def block(name: str, parameters: dict, connectors: str) -> str:
    """A block component with Real/Integer connectors and parameter values."""
    values = "".join(
        f'<ssv:Parameter name="{key}"><ssv:{"Integer" if isinstance(value, int) else "Real"} '
        f'value="{value!r}"/></ssv:Parameter>' for key, value in parameters.items())
    bindings = ("<ssd:ParameterBindings><ssd:ParameterBinding><ssd:ParameterValues>"
                f'<ssv:ParameterSet version="1.0" name="{name}"><ssv:Parameters>{values}'
                "</ssv:Parameters></ssv:ParameterSet></ssd:ParameterValues>"
                "</ssd:ParameterBinding></ssd:ParameterBindings>") if values else ""
    return (f'<ssd:Component name="{name}" source="resources/block.fmu">'
            f"<ssd:Connectors>{connectors}</ssd:Connectors>{bindings}</ssd:Component>")


REAL_IO = ('<ssd:Connector name="u" kind="input"><ssc:Real/></ssd:Connector>'
           '<ssd:Connector name="y" kind="output"><ssc:Real/></ssd:Connector>')
COUNT_OUT = '<ssd:Connector name="count" kind="output"><ssc:Integer/></ssd:Connector>'
EXTRA_IN = '<ssd:Connector name="extra" kind="input"><ssc:Integer/></ssd:Connector>'


def scene(folder, fmu, parameters: dict, integer: bool = False, scaled: bool = False):
    """A ring b1 -> b2 -> b3 -> b1 of y -> u (``parameters``: name -> values of the
    block); ``integer``: b1.count feeds b3.extra too; ``scaled``: b2.u = 2 b1.y + 0.5."""
    components = [block("b1", parameters.get("b1", {}), REAL_IO + (COUNT_OUT if integer else "")),
                  block("b2", parameters.get("b2", {}), REAL_IO),
                  block("b3", parameters.get("b3", {}), REAL_IO + (EXTRA_IN if integer else ""))]
    scale = '<ssc:LinearTransformation factor="2.0" offset="0.5"/>' if scaled else ""
    links = [("b1", "y", "b2", "u", scale), ("b2", "y", "b3", "u", ""),
             ("b3", "y", "b1", "u", "")]
    if integer:
        links.append(("b1", "count", "b3", "extra", ""))
    connections = "".join(
        f'<ssd:Connection startElement="{a}" startConnector="{ac}" endElement="{b}" '
        f'endConnector="{bc}">{inside}</ssd:Connection>' for a, ac, b, bc, inside in links)
    text = ('<?xml version="1.0" encoding="UTF-8"?>' + HEADER.format(name="ring")
            + '<ssd:System name="root"><ssd:Elements>' + "".join(components)
            + f"</ssd:Elements><ssd:Connections>{connections}</ssd:Connections></ssd:System>"
            '<ssd:DefaultExperiment startTime="0" stopTime="0.05"><ssd:Annotations>'
            '<ssc:Annotation type="org.dsim.master"><glue:Master xmlns:glue="urn:dsim:gluing:1" '
            'step="0.001"/></ssc:Annotation></ssd:Annotations></ssd:DefaultExperiment>'
            "</ssd:SystemStructureDescription>")
    return scene_folder(folder, text, {"block.fmu": fmu})


def run(folder, out):
    """One run writing ``out``: (status, message, CSV bytes, calls per component and
    FMI function, the iterations' statistics)."""
    result = dsim.simulate(folder, out=out, handle_signals=False)
    statistics = json.loads(out.with_suffix(".stats.json").read_text())
    calls = {name: {function: entry["calls"] for function, entry in c["functions"].items()}
             for name, c in statistics["components"].items()}
    return result.status, result.message, out.read_bytes(), calls, statistics["iterations"]


CASES = {
    "ring": ({}, False, False),
    "scaled connection": ({}, False, True),
    "an Integer connection": ({}, True, False),
    "a step fails": ({"b2": {"failure": 2, "fail_time": 0.0305}}, False, False),
    "a step is discarded": ({"b3": {"failure": 3, "fail_time": 0.0205}}, False, False),
    "an output turns NaN": ({"b2": {"failure": 1, "fail_time": 0.0105}}, True, False),
}


@pytest.mark.parametrize("case", CASES)
def test_the_kernel_steps_as_the_template_step(block_fmus, tmp_path, monkeypatch, case):
    parameters, integer, scaled = CASES[case]
    folder = scene(tmp_path / "scene", block_fmus["state"], parameters, integer, scaled)
    made = []
    kernel = InProcessBackend.causal_kernel

    def watched(self, transfer, outputs):
        made.append(kernel(self, transfer, outputs))
        return made[-1]

    monkeypatch.setattr(InProcessBackend, "causal_kernel", watched)
    fused = run(folder, tmp_path / "kernel.csv")
    assert len(made) == 1  # the run went through the kernel
    fused_count = sum(entry[-1] is None for entry in made[0].entries)
    assert fused_count == (1 if integer else 3)  # b1 and b3 move an Integer: exchange_with
    monkeypatch.setattr(InProcessBackend, "causal_kernel", Backend.causal_kernel)
    template = run(folder, tmp_path / "template.csv")
    assert fused == template
    status, message, rows, calls, _ = fused
    if parameters:
        assert status == "failed" and message
    else:
        assert status == "completed"
        assert len(rows.splitlines()) == 52  # the header, t = 0 and 50 steps
        assert all(c["fmi2DoStep"] == 50 for c in calls.values())
