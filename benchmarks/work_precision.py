"""Work against precision: error against the closed form versus CPU seconds, for dsim's
fixed steps in each coupling, dsim's error-controlled step (``--step auto``) at several
tolerances, and other masters at their fixed steps, on the same FMUs in the same run.

The system is the two-mass oscillator split in two FMUs (tests/support/third_party/kinds,
compiled here with gcc into FMI 2.0 co-simulation FMUs): mass1 gives its position and
speed, mass2 gives the coupling force back; m1 = m2 = 1 kg, k1 = k2 = 10 N/m, coupling
spring 100 N/m, x1(0) = 0.1 m, from 0 to 2 s.  The error is max |x1 - exact| over every
recorded point (exact: the matrix exponential of the four states).  The other masters:
FMPy's ``simulate_ssp``, where libcosimpy is installed libcosim (C++) with its fixed-step
algorithm, and where ecospy is installed (with Debian's libtbb12, which its native
library needs) ECOS (C++) with its fixed-step algorithm, each exchanging the connections
once per step.  dsim records a row every 0.1 s with ``--step auto`` and every step at a
fixed one; libcosim and ECOS every step through their own CSV writers (ECOS's prints six
decimals, so its error is known to 5e-7 m).

CPU seconds of this process (a shared machine makes wall time mostly waiting), the
least of ``--repeat`` runs; every configuration runs in the same process, in turn.

    python -m benchmarks.work_precision   # writes docs/work_precision.md and its plot
"""
from __future__ import annotations

import argparse
import shutil
import tempfile
import zipfile
from datetime import date
from pathlib import Path

import numpy as np
from scipy.linalg import expm

from benchmarks import cpu_seconds, machine
import dsim

ROOT = Path(__file__).resolve().parent.parent
STOP = 2.0
#: the closed form's system matrix (states x1, v1, x2, v2)
SYSTEM = np.array([[0, 1, 0, 0], [-110, 0, 100, 0], [0, 0, 0, 1], [100, 0, -110, 0]], float)
#: each master's connectors: (component, name, kind)
CONNECTORS = [("mass1", "x1", "output"), ("mass1", "v1", "output"), ("mass1", "F", "input"),
              ("mass2", "x1", "input"), ("mass2", "v1", "input"), ("mass2", "F", "output")]
LINKS = [("mass1", "x1", "mass2", "x1"), ("mass1", "v1", "mass2", "v1"),
         ("mass2", "F", "mass1", "F")]


def exact_x1(times, damping: float = 0.0) -> np.ndarray:
    """mass1's position at ``times`` (s), closed form; ``damping``: d1 (N.s/m)."""
    system = SYSTEM - damping * np.outer([0, 1, 0, 0], [0, 1, 0, 0])
    return np.array([(expm(system * t) @ [0.1, 0.0, 0.0, 0.0])[0] for t in times])


def two_mass_ssp(path: Path, fmus: dict, step: float, master: str = "") -> Path:
    """The oscillator as an .ssp every master reads: connectors declared on each
    component (FMPy's runner needs them), dsim's master annotation for the step."""
    components = "".join(
        f'<ssd:Component name="{name}" source="resources/{name}.fmu" '
        'implementation="CoSimulation"><ssd:Connectors>'
        + "".join(f'<ssd:Connector name="{c}" kind="{k}"><ssc:Real/></ssd:Connector>'
                  for n, c, k in CONNECTORS if n == name)
        + "</ssd:Connectors></ssd:Component>" for name in fmus)
    links = "".join(f'<ssd:Connection startElement="{a}" startConnector="{ac}" '
                    f'endElement="{b}" endConnector="{bc}"/>' for a, ac, b, bc in LINKS)
    ssd = f"""<?xml version="1.0" encoding="UTF-8"?>
<ssd:SystemStructureDescription version="1.0" name="two_masses"
    xmlns:ssd="http://ssp-standard.org/SSP1/SystemStructureDescription"
    xmlns:ssc="http://ssp-standard.org/SSP1/SystemStructureCommon">
  <ssd:System name="root"><ssd:Elements>{components}</ssd:Elements>
    <ssd:Connections>{links}</ssd:Connections></ssd:System>
  <ssd:DefaultExperiment startTime="0" stopTime="{STOP!r}"><ssd:Annotations>
    <ssc:Annotation type="org.dsim.master"><glue:Master xmlns:glue="urn:dsim:gluing:1"
      step="{step!r}" {master}/></ssc:Annotation></ssd:Annotations></ssd:DefaultExperiment>
</ssd:SystemStructureDescription>"""
    with zipfile.ZipFile(path, "w") as archive:
        archive.writestr("SystemStructure.ssd", ssd)
        for name, fmu in fmus.items():
            archive.write(fmu, f"resources/{name}.fmu")
    return path



def run_dsim(ssp: Path, **settings) -> tuple[np.ndarray, np.ndarray, dict]:
    """dsim's times, x1 and statistics."""
    result = dsim.simulate(ssp, handle_signals=False, **settings)
    if not result.ok:
        raise RuntimeError(result.message)
    return result["time"], result["mass1.x1"], result.statistics


def run_fmpy(ssp: Path, step: float):
    """FMPy's SSP runner: a row per step, its values after the step (time: the step's
    start)."""
    from fmpy.ssp.simulation import simulate_ssp

    rows = simulate_ssp(str(ssp), stop_time=STOP, step_size=step)
    return rows["time"] + step, rows["mass1.x1"], {}


def libcosim_available() -> bool:
    """Whether libcosim's Python binding (libcosimpy, from PyPI) is installed."""
    try:
        from libcosimpy.CosimLogging import CosimLogLevel, log_output_level
    except ImportError:
        return False
    log_output_level(CosimLogLevel.ERROR)
    return True


def run_libcosim(ssp: Path, step: float, folder: Path):
    """libcosim's fixed-step run with its CSV file observer; mass1's file read back."""
    from libcosimpy.CosimExecution import CosimExecution
    from libcosimpy.CosimObserver import CosimObserver

    shutil.rmtree(folder, ignore_errors=True)
    folder.mkdir(parents=True)
    execution = CosimExecution.from_ssp_file(str(ssp), step_size=round(step * 1e9))
    observer = CosimObserver.create_to_dir(str(folder))
    execution.add_observer(observer)
    execution.simulate_until(round(STOP * 1e9))
    del execution, observer  # the files closed now
    found = sorted(folder.glob("mass1*.csv"))
    header = found[0].read_text().splitlines()[0].split(",")
    data = np.loadtxt(found[0], delimiter=",", skiprows=1)
    names = [h.strip().split(" ")[0].strip('"') for h in header]
    return data[:, names.index("Time")], data[:, names.index("x1")], {}


#: ECOS's name in the rows, the table and the plot
ECOS = "ECOS"


def ecos_missing() -> str:
    """Why ECOS cannot run here, '' where it can: ecospy (PyPI) not installed, or its
    native library not loading (it needs libtbb.so.12, Debian's libtbb12)."""
    try:
        from ecospy import EcosLib
    except ImportError as error:
        return f"ecospy is not installed ({error}; `pip install ecospy`)"
    except OSError as error:  # ctypes could not load libecosc.so or what it links
        return (f"ecospy's native library did not load ({error}; it needs Debian's "
                "libtbb12)")
    EcosLib.set_log_level("err")
    return ""


def run_ecos(ssp: Path, step: float, folder: Path):
    """ECOS's fixed-step run of the .ssp with its CSV writer on mass1's x1; the file read
    back.  Times are the step count times the step: the writer prints them to six
    significant digits.  ``step(n)`` rather than ``step_until``, which (ecospy 0.7.2)
    stops a step short where the summed time passes the stop (1.99 s at h = 0.01 s)."""
    from ecospy import EcosSimulation

    shutil.rmtree(folder, ignore_errors=True)
    folder.mkdir(parents=True)
    csv = folder / "mass1.csv"
    with EcosSimulation(step_size=step, ssp_path=str(ssp)) as simulation:
        simulation.add_csv_writer(str(csv), identifiers=["mass1::x1"])
        simulation.init()
        simulation.step(round(STOP / step))
        simulation.terminate()  # the file flushed and closed
    names = [name.strip() for name in csv.read_text().split("\n", 1)[0].split(",")]
    data = np.loadtxt(csv, delimiter=",", skiprows=1, ndmin=2)
    x1 = next(i for i, name in enumerate(names) if name.startswith("mass1::x1"))
    return data[:, names.index("iterations")] * step, data[:, x1], {}


#: dsim's Newton tolerances where it iterates (strong coupling)
TIGHT = 'tolerance="1e-13" relativeTolerance="1e-13"'


def dsim_configurations(folder: Path, fmus: dict, causal, strong, tolerances,
                        **settings) -> list:
    """dsim's configurations: the causal coupling at the fixed steps ``causal``, the
    strong one at ``strong`` and step auto (strong) at ``tolerances``, each run with
    ``settings``: (master, setting, run) triples."""
    configurations = []
    for h in causal:
        configurations.append(("dsim causal", f"h = {h:g} s", lambda h=h: run_dsim(
            two_mass_ssp(folder / "causal.ssp", fmus, h, 'coupling="causal"'), **settings)))
    for h in strong:
        configurations.append(("dsim strong", f"h = {h:g} s", lambda h=h: run_dsim(
            two_mass_ssp(folder / "strong.ssp", fmus, h, f'coupling="strong" {TIGHT}'),
            **settings)))
    for tolerance in tolerances:
        configurations.append(("dsim strong, step auto", f"E = {tolerance:g}",
                               lambda e=tolerance: run_dsim(
            two_mass_ssp(folder / "auto.ssp", fmus, 0.1, f'coupling="strong" {TIGHT}'),
            step="auto", error_tolerance=e, **settings)))
    return configurations


def measured(configurations, repeat: int, damping: float = 0.0) -> list[dict]:
    """Each (master, setting, run) configuration's error against the closed form (mass1
    damped by ``damping`` N.s/m), least CPU seconds of ``repeat`` runs, and steps."""
    rows = []
    for master, setting, run in configurations:
        seconds, (times, x1, statistics) = min((cpu_seconds(run) for _ in range(repeat)),
                                              key=lambda pair: pair[0])
        error = float(np.max(np.abs(x1 - exact_x1(times, damping))))
        control = statistics.get("step_control") or {}
        steps = control.get("accepted_steps") or statistics.get("steps") or len(times)
        rows.append({"master": master, "setting": setting, "error": error,
                     "seconds": seconds, "steps": steps,
                     "rejected": control.get("rejected_steps")})
        print(f"{master:24} {setting:14} error {error:9.3g}  {seconds:7.3f} s  {steps} steps")
    return rows


def measure(folder: Path, fmus: dict, repeat: int) -> list[dict]:
    """Every master's configurations on the steady oscillator: error, CPU, steps."""
    configurations = dsim_configurations(
        folder, fmus, (1e-2, 3e-3, 1e-3, 3e-4, 1e-4),
        (1e-2, 5e-3, 2.5e-3, 1.25e-3, 6.25e-4, 3.125e-4), (1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8))
    for h in (1e-2, 1e-3, 1e-4):
        configurations.append(("FMPy simulate_ssp", f"h = {h:g} s", lambda h=h: run_fmpy(
            two_mass_ssp(folder / "fmpy.ssp", fmus, h), h)))
    if libcosim_available():
        for h in (1e-2, 1e-3, 1e-4):
            configurations.append(("libcosim", f"h = {h:g} s", lambda h=h: run_libcosim(
                two_mass_ssp(folder / "cosim.ssp", fmus, h), h, folder / "cosim")))
    if not ecos_missing():
        for h in (1e-2, 1e-3, 1e-4, 1e-5):
            configurations.append((ECOS, f"h = {h:g} s", lambda h=h: run_ecos(
                two_mass_ssp(folder / "ecos.ssp", fmus, h), h, folder / "ecos")))
    return measured(configurations, repeat)


def table(rows: list[dict]) -> list[str]:
    """The rows as a markdown table: master, setting, error, CPU, steps."""
    lines = ["| master | setting | max \\|x1 - exact\\| (m) | CPU s | steps (taken again) |",
             "|---|---|---|---|---|"]
    for row in rows:
        again = f" ({row['rejected']})" if row["rejected"] is not None else ""
        lines.append(f"| {row['master']} | {row['setting']} | {row['error']:.3g} | "
                     f"{row['seconds']:.3f} | {row['steps']}{again} |")
    return lines


def plot(rows: list[dict], png: Path) -> None:
    """Error against CPU seconds, log-log, one curve per master and mode."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    figure, axes = plt.subplots(figsize=(7.5, 5))
    for master in dict.fromkeys(row["master"] for row in rows):
        mine = sorted((r for r in rows if r["master"] == master), key=lambda r: r["seconds"])
        axes.loglog([r["seconds"] for r in mine], [r["error"] for r in mine], "o-",
                    label=master)
    axes.set_xlabel("CPU seconds of the run")
    axes.set_ylabel("max |x1 - closed form| (m)")
    axes.set_title("Two-mass oscillator, two FMI 2.0 co-simulation FMUs, 0..2 s")
    axes.grid(True, which="both", alpha=0.3)
    axes.legend()
    figure.tight_layout()
    figure.savefig(png, dpi=110)
    plt.close(figure)


def page(rows: list[dict], ecos_why: str = "") -> str:
    """docs/work_precision.md; ``ecos_why``: why ECOS was not measured, if it was not."""
    lines = [
        "# Work against precision (`python -m benchmarks.work_precision`)",
        "",
        f"Measured {date.today().isoformat()} on {machine()}, by "
        "`benchmarks/work_precision.py` (its docstring says how): the two-mass oscillator "
        "split in two FMI 2.0 co-simulation FMUs (position and speed one way, force back), "
        "0..2 s, max |x1 - closed form| against CPU seconds of the run, every master on the "
        "same FMUs in the same process.",
        "",
        "![error against CPU seconds](figures/work_precision.png)",
        ""] + table(rows)
    if ecos_why:
        lines += ["", f"ECOS was not measured: {ecos_why}."]
    lines += ["", "What it shows, read from this run's rows:", ""]
    lines += _reading(rows)
    return "\n".join(lines) + "\n"


def _reading(rows: list[dict]) -> list[str]:
    """Sentences with this run's numbers: the most accurate peer, and dsim's error
    control against it and against dsim's own fixed steps."""
    peers = [r for r in rows if not r["master"].startswith("dsim")]
    auto = [r for r in rows if r["master"] == "dsim strong, step auto"]
    fixed = [r for r in rows if r["master"] == "dsim strong"]
    said = []
    if peers:
        best = min(peers, key=lambda r: r["error"])
        beaten = [r for r in auto if r["error"] < best["error"]]
        said.append(f"- The peers' best error is {best['error']:.3g} m ({best['master']}, "
                    f"{best['setting']}, {best['seconds']:.3f} s); they exchange each "
                    "connection once per step, so their error falls only as the step.")
        if beaten:
            cheapest = min(beaten, key=lambda r: r["seconds"])
            said.append(f"- dsim's error-controlled step passes it at {cheapest['setting']}: "
                        f"{cheapest['error']:.3g} m in {cheapest['seconds']:.3f} s "
                        f"({best['seconds'] / cheapest['seconds']:.2g} times less CPU).")
    said += _ecos_against_dsim(rows)
    if auto and fixed:
        for row in auto:
            reaching = [r for r in fixed if r["error"] <= row["error"]]
            if reaching:
                first = min(reaching, key=lambda r: r["seconds"])
                said.append(f"- {row['setting']}: {row['error']:.3g} m in "
                            f"{row['seconds']:.3f} s; the strong coupling's cheapest fixed "
                            f"step at least as accurate, {first['setting']}, takes "
                            f"{first['seconds']:.3f} s.")
    said.append("- On this steady oscillation a fixed step chosen after the fact is cheaper "
                "than the error-controlled one, which pays three FMU steps (a step and its "
                "two halves) for each accepted one; an estimate at no extra step was "
                "measured and not taken (docs/method.md says why).")
    return said


#: the transient: mass1 damped (d1, N.s/m), over 0..TRANSIENT_STOP s (|x1| falls from
#: 0.1 m to 0.003 m in 4 s)
DAMPING, TRANSIENT_STOP = 20.0, 4.0


def transient(folder: Path, fmus: dict, repeat: int) -> list[dict]:
    """dsim alone on the damped oscillator (a motion that dies out): the strong and the
    causal coupling at fixed steps, step auto at several tolerances; each row's error
    against the damped closed form and its CPU seconds."""
    return measured(dsim_configurations(
        folder, fmus, (1e-3, 1e-4), (1e-2, 5e-3, 2.5e-3, 1.25e-3, 6.25e-4, 3.125e-4),
        (1e-4, 1e-5, 1e-6, 1e-7), parameters={"mass1.d1": DAMPING}, stop=TRANSIENT_STOP),
        repeat, DAMPING)


def transient_page(rows: list[dict]) -> str:
    """The page's section on the damped oscillator, with its reading."""
    lines = ["", "## A motion that dies out: mass1 damped", "",
             f"The same FMUs with mass1 damped (d1 = {DAMPING:g} N.s/m, 0..{TRANSIENT_STOP:g} "
             "s: |x1| falls from 0.1 m to 0.003 m), dsim alone, against the damped closed "
             "form; the fixed steps of both couplings beside step auto (output every 0.1 s).",
             ""] + table(rows)
    lines += ["", "Step auto against the largest fixed step of any coupling that reaches its "
              "error, read from this run:", ""]
    fixed = [r for r in rows if "step auto" not in r["master"]]
    for row in (r for r in rows if "step auto" in r["master"]):
        reaching = [r for r in fixed if r["error"] <= row["error"]]
        if not reaching:
            lines.append(f"- {row['setting']}: {row['error']:.3g} m in {row['seconds']:.3f} s; "
                         "no fixed step run here reaches it.")
            continue
        largest = max(reaching, key=lambda r: float(r["setting"].split()[2]))
        verdict = "less" if row["seconds"] < largest["seconds"] else "more"
        lines.append(f"- {row['setting']}: {row['error']:.3g} m in {row['seconds']:.3f} s, "
                     f"{verdict} than {largest['master']} at {largest['setting']} "
                     f"({largest['error']:.3g} m, {largest['seconds']:.3f} s: "
                     f"{row['seconds'] / largest['seconds']:.2f} times).")
    return "\n".join(lines) + "\n"


#: where the shipped scenes under --step auto are measured (their bands and steps)
SCENES_LINK = ("\nThe shipped scenes under `--step auto` (their difference from the monolithic "
               "reference against the scene's own fixed step, and the step over time): "
               "[docs/step_auto_scenes.md](step_auto_scenes.md).\n")


#: errors within this share of each other are equal errors, for ECOS against dsim
SAME_ERROR = 0.02


def _ecos_against_dsim(rows: list[dict]) -> list[str]:
    """A sentence on ECOS's CPU against dsim's where their errors are equal (within
    :data:`SAME_ERROR`): dsim's cheapest such run for each ECOS step; none where there
    is no such pair."""
    dsim_rows = [r for r in rows if r["master"].startswith("dsim")]
    pairs = []
    for row in (r for r in rows if r["master"] == ECOS):
        equal = [r for r in dsim_rows
                 if abs(r["error"] - row["error"]) <= SAME_ERROR * row["error"]]
        if equal:
            pairs.append((row, min(equal, key=lambda r: r["seconds"])))
    if not pairs:
        return []
    return ["- ECOS against dsim at equal error (within "
            f"{100 * SAME_ERROR:g} %): " + "; ".join(
                f"{ours['error']:.3g} m, ECOS {ours['setting']} in {ours['seconds']:.3f} s, "
                f"{theirs['master']} {theirs['setting']} in {theirs['seconds']:.3f} s "
                f"({theirs['seconds'] / ours['seconds']:.2g} times ECOS's CPU)"
                for ours, theirs in pairs) + "; ECOS steps its FMUs on parallel threads "
            "(TBB), and its CPU seconds are those of every thread."]


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--out", default=str(ROOT / "docs" / "work_precision.md"))
    args = parser.parse_args(argv)
    folder = Path(tempfile.mkdtemp(prefix="dsim-work-"))
    try:
        from tests.support.third_party.kinds.build import mass_fmus

        fmus = mass_fmus(folder, interfaces=("CoSimulation",))  # compiled with gcc
        rows = measure(folder, fmus, args.repeat)
        damped = transient(folder, fmus, args.repeat)
    finally:
        shutil.rmtree(folder, ignore_errors=True)
    ecos_why = ecos_missing()
    out = Path(args.out)
    plot(rows, out.parent / "figures" / "work_precision.png")
    out.write_text(page(rows, ecos_why) + transient_page(damped) + SCENES_LINK)
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
