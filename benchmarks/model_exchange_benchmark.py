"""Model Exchange: dsim's integration cost per communication step against fmpy's own
Model Exchange simulation of the same FMU, measured in the same run.

The FMUs are the C test models of tests/support/third_party/kinds (FMI 2.0 Model Exchange,
compiled here with gcc): the oscillator x = cos t and the bouncing ball (state
events).  dsim runs each as the one component of a scene, communication step H,
with its default integrator (DOP853) and with CVODE; fmpy runs
``simulate_fmu(fmi_type="ModelExchange", solver="CVode")`` with an output every H
(fmpy integrates straight through its output points; dsim restarts its integrator
at every communication point, where a master must: the inputs may change there and
a rollback may send the FMU back).  Both are at relative tolerance 1e-8.

Per-step time is the slope between a short and a long run of the same runner
(start-up cancels), the least of the repetitions; the ratio dsim / fmpy is taken
repetition by repetition (runs side by side on a shared machine).  Each runner's
error against the closed form is reported beside its time.

    python -m benchmarks.model_exchange_benchmark   # writes docs/model_exchange_benchmark.md
"""
from __future__ import annotations

import argparse
import platform
import statistics as stats
import tempfile
import time
import zipfile
from datetime import date
from pathlib import Path

import numpy as np
from fmpy import simulate_fmu

from benchmarks import machine
import dsim
from tests.support.closed_forms import bouncing_height
from tests.support.third_party.kinds.build import build_fmu

ROOT = Path(__file__).resolve().parent.parent
STEP = 1e-3
RTOL = 1e-8

#: model -> (recorded variable, closed form of time, short and long stop times)
CASES = {"oscillator": ("P.u_x", np.cos, 0.5, 2.5),
         "bouncing_ball": ("h", bouncing_height, 0.5, 2.2)}


def _scene(folder: Path, fmu: Path, variable: str, method: str) -> Path:
    """A one-component scene of ``fmu`` (Model Exchange) recording ``variable``."""
    solver = ('<ssd:Annotations><ssc:Annotation type="org.dsim.solver"><glue:Solver '
              f'xmlns:glue="urn:dsim:gluing:1" method="{method}" rtol="{RTOL}"/>'
              "</ssc:Annotation></ssd:Annotations>")
    ssd = f"""<?xml version="1.0" encoding="UTF-8"?>
<ssd:SystemStructureDescription version="1.0" name="me"
    xmlns:ssd="http://ssp-standard.org/SSP1/SystemStructureDescription"
    xmlns:ssc="http://ssp-standard.org/SSP1/SystemStructureCommon">
  <ssd:System name="root"><ssd:Elements>
    <ssd:Component name="m" source="resources/m.fmu" implementation="ModelExchange">
      <ssd:Connectors><ssd:Connector name="{variable}" kind="output"><ssc:Real/>
      </ssd:Connector></ssd:Connectors>{solver}</ssd:Component>
  </ssd:Elements></ssd:System>
  <ssd:DefaultExperiment startTime="0" stopTime="1"><ssd:Annotations>
    <ssc:Annotation type="org.dsim.master"><glue:Master xmlns:glue="urn:dsim:gluing:1"
      step="{STEP}"/></ssc:Annotation></ssd:Annotations></ssd:DefaultExperiment>
</ssd:SystemStructureDescription>"""
    path = folder / f"{fmu.stem}_{method}.ssp"
    with zipfile.ZipFile(path, "w") as archive:
        archive.writestr("SystemStructure.ssd", ssd)
        archive.write(fmu, "resources/m.fmu")
    return path


def _timed(function) -> tuple[float, object]:
    start = time.perf_counter()
    result = function()
    return time.perf_counter() - start, result


def measure(model: str, folder: Path, repetitions: int) -> list[dict]:
    """The table's rows of one model: per-step microseconds, ratio to fmpy, error."""
    variable, exact, short, long = CASES[model]
    fmu = build_fmu(folder, model, "2.0", interfaces=("ModelExchange",))
    scenes = {method: _scene(folder, fmu, variable, method) for method in ("DOP853", "cvode")}

    def dsim_run(method):
        def run(stop):
            result = dsim.simulate(scenes[method], stop=stop, handle_signals=False)
            return result["time"], result[f"m.{variable}"]
        return run

    def fmpy_run(stop):
        result = simulate_fmu(str(fmu), fmi_type="ModelExchange", solver="CVode",
                              stop_time=stop, step_size=STEP, output_interval=STEP,
                              relative_tolerance=RTOL, output=[variable])
        return result["time"], result[variable]

    runners = {"fmpy CVode": fmpy_run, "dsim DOP853": dsim_run("DOP853"),
               "dsim CVODE": dsim_run("cvode")}
    steps = round((long - short) / STEP)
    slopes: dict = {name: [] for name in runners}
    errors = {}
    for _ in range(repetitions):
        for name, run in runners.items():
            first, _ = _timed(lambda: run(short))
            second, (t, x) = _timed(lambda: run(long))
            slopes[name].append((second - first) / steps * 1e6)
            errors[name] = float(np.max(np.abs(np.asarray(x) - exact(np.asarray(t)))))
    rows = []
    for name in runners:
        ratios = [a / b for a, b in zip(slopes[name], slopes["fmpy CVode"])]
        rows.append({"model": model, "runner": name, "us_per_step": min(slopes[name]),
                     "ratio": stats.median(ratios), "error": errors[name]})
    return rows


def table(rows: list[dict], repetitions: int) -> str:
    lines = [
        "# Model Exchange: dsim's integration per step against fmpy's",
        "",
        f"Measured {date.today()} on {machine()} with Python "
        f"{platform.python_version()} by `python -m benchmarks.model_exchange_benchmark` "
        f"(communication step {STEP:g} s, rtol {RTOL:g}, {repetitions} repetitions; "
        "per-step time is the slope between a short and a long run (oscillator "
        f"{CASES['oscillator'][2]:g} s and {CASES['oscillator'][3]:g} s; ball "
        f"{CASES['bouncing_ball'][2]:g} s and {CASES['bouncing_ball'][3]:g} s, before the ball "
        "comes to rest), the least of the repetitions; the ratio is the median of the repetitions' ratios to fmpy, each "
        "taken side by side). Error: the largest difference from the closed form over the "
        "long run.",
        "",
        "| model | runner | us per step | / fmpy | error vs closed form |",
        "|---|---|---|---|---|"]
    for row in rows:
        lines.append(f"| {row['model']} | {row['runner']} | {row['us_per_step']:.1f} | "
                     f"{row['ratio']:.2f} | {row['error']:.2e} |")
    lines += ["", "fmpy integrates straight through its output points; dsim restarts its "
              "integrator at every communication point (where the inputs of a co-simulation "
              "may change and a rollback may send the FMU back), which is what the ratio "
              "costs. DOP853 restarts at full order, CVODE's BDF at order one: hence dsim's "
              "default.", ""]
    return "\n".join(lines)


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--out", type=Path, default=ROOT / "docs" / "model_exchange_benchmark.md")
    parser.add_argument("--repetitions", type=int, default=3)
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory() as folder:
        rows = [row for model in CASES for row in measure(model, Path(folder),
                                                          args.repetitions)]
    text = table(rows, args.repetitions)
    args.out.write_text(text)
    print(text)


if __name__ == "__main__":
    main()
