"""The four-post rig (SCENES.md four_post, docs/four_post.md) driven by a road profile
from a file: a table component (docs/inputs.md), as OMSimulator reads one, feeds the
posts, and the glued run is compared with the same model in one solver.

The road (:func:`road_profile`): a band-limited random road from a seeded generator, a
sum of sines with random phases whose amplitudes follow the ISO 8608 displacement
spectrum of a class B road, Gd(n) = 64e-6 m^3 (n / 0.1 cycle/m)^-2, over 0.2 to 5
cycles/m, driven at 10 m/s (2 to 50 Hz); the left and right tracks independent, the rear
posts 1.9 m behind the front ones (the pads' centres: 0.19 s later); faded in over its
first 0.2 s so that the rig starts at rest.  It is written as resources/road.csv
(columns ``fl``, ``fr``, ``rl``, ``rr``: heights, m, every 2 ms: half of the steps
interpolate between rows).

The scene (``four_post_road``): four_post_flexible with the posts' own bumps off and a
component ``road`` of type text/csv whose outputs are the file's columns; each column
feeds its post's free port ``Q`` (the post mass) through a LinearTransformation of
factor k = 2e5 N/m: the force k z_road of the post's spring to a road under it (its
damper stays on fixed ground).  A connection gives each post the road's value at the
start of every step, which the post's trapezoidal rule takes at the step's end.

Monolithic twin: :func:`examples.four_post.monolithic` with the same force, the table's
value at the start of each step, in place of the posts' bumps (``base_force``): the same
model, inputs and step in one solver, so the difference is what gluing leaves.

``python -m examples.four_post_road`` writes the scene to results/four_post_road/ and
results/four_post_road.ssp, runs it and its twin and writes
docs/figures/four_post_road.png; ``--stop``, ``--parameter-set`` shorten it.
"""
from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
from lxml import etree

from dsim.build_fmus.four_post_scenes import (CORNERS, FIDELITY, FOUR_POST, four_post,
                                              fidelity_values)
from dsim.build_fmus.scenes import SSC, SSD, write_parameter_sets

ROOT = Path(__file__).resolve().parent.parent
#: the road: class B (ISO 8608), 0.2 to 5 cycles/m, 10 m/s, 2 s, rows every 2 ms
ROAD = {"roughness": 64e-6, "n0": 0.1, "band": (0.2, 5.0), "waves": 200, "speed": 10.0,
        "duration": 2.0, "interval": 0.002, "fade": 0.2, "wheelbase": 1.9, "seed": 44}
#: the posts' spring to the road, N/m (the scenes' post_k)
SPRING = FOUR_POST["post_k"]


def _q(namespace: str, tag: str) -> str:
    """An element name in ``namespace`` (lxml's Clark notation)."""
    return f"{{{namespace}}}{tag}"


def road_profile(seed: int = ROAD["seed"]) -> dict[str, np.ndarray]:
    """``time`` and the road height under each post (m), ``fl``, ``fr``, ``rl``,
    ``rr``: the module docstring's random road, the same for the same ``seed``."""
    r = ROAD
    rng = np.random.default_rng(seed)
    low, high = r["band"]
    n = np.linspace(low, high, r["waves"])                      # spatial frequency, 1/m
    dn = n[1] - n[0]
    amplitude = np.sqrt(2 * r["roughness"] * (n / r["n0"]) ** -2 * dn)   # m
    time = np.round(np.arange(0.0, r["duration"] + r["interval"] / 2, r["interval"]), 12)
    delay = r["wheelbase"] / r["speed"]
    columns = {"time": time}
    for side in ("l", "r"):
        phase = rng.uniform(0.0, 2 * np.pi, r["waves"])

        def height(t, phase=phase):
            x = r["speed"] * np.asarray(t)[:, None]             # distance travelled, m
            z = np.sum(amplitude * np.sin(2 * np.pi * n * x + phase), axis=1)
            fade = np.clip(np.asarray(t) / r["fade"], 0.0, 1.0)
            return z * 0.5 * (1 - np.cos(np.pi * fade))           # faded in from 0
        columns[f"f{side}"] = height(time)
        columns[f"r{side}"] = height(np.maximum(time - delay, 0.0))
    return {name: columns[name] for name in ("time", "fl", "fr", "rl", "rr")}


def write_road(path: Path, profile: dict) -> None:
    """The road as a CSV table: ``time`` first, then one column per post (m)."""
    names = list(profile)
    rows = np.column_stack([profile[name] for name in names])
    path.write_text(",".join(names) + "\n" + "".join(
        ",".join(repr(float(v)) for v in row) + "\n" for row in rows))


def write_scene(folder: Path, profile: dict) -> Path:
    """The scene folder four_post_road: four_post_flexible without the bumps, the road
    table component and its connections; its fidelity parameter sets too."""
    p = FOUR_POST
    scene = four_post("flexible")
    scene.name = "four_post_road"
    scene.root.set("name", scene.name)
    scene.root.set("description", "The four-post rig (four_post_flexible) driven by a "
                   "random road from resources/road.csv (examples/four_post_road.py)")
    for element in scene.elements.iter(_q(SSD, "Component")):
        if element.get("name", "").startswith("post_"):  # the bumps off
            for parameter in element.iter("{*}Parameter"):
                if parameter.get("name") == "bump_duration[1]":
                    parameter[0].set("value", "0.0")
    road = etree.SubElement(scene.elements, _q(SSD, "Component"), name="road",
                            type="text/csv", source="resources/road.csv")
    connectors = etree.SubElement(road, _q(SSD, "Connectors"))
    connections = etree.SubElement(scene.system, _q(SSD, "Connections"))
    for corner in CORNERS:
        connector = etree.SubElement(connectors, _q(SSD, "Connector"), name=corner,
                                     kind="output")
        etree.SubElement(connector, _q(SSC, "Real"))
        connection = etree.SubElement(connections, _q(SSD, "Connection"),
                                      startElement="road", startConnector=corner,
                                      endElement=f"post_{corner}", endConnector="Q.f_x")
        etree.SubElement(connection, _q(SSC, "LinearTransformation"),
                         factor=repr(SPRING), offset="0.0")
    scene.file("resources/road.csv", lambda target: write_road(target, profile))
    scene.write(folder, 0.0, ROAD["duration"], step=p["step"], tolerance=p["tolerance"],
                maxIterations=20, predictor=p["predictor"], refreshAfter=10)
    write_parameter_sets(folder, {
        name: {f"body.{key}": value for key, value in fidelity_values(name).items()}
        for name in FIDELITY})
    return folder


def packed(out: Path = ROOT / "results") -> Path:
    """results/four_post_road.ssp (the scene folder beside it), with the built FMUs."""
    from dsim.build_fmus.build import pack_scene

    folder = write_scene(out / "four_post_road", road_profile())
    return pack_scene(folder, ROOT / "build" / "fmus", out)


def road_force(profile: dict, step: float):
    """The force on each post at the end time t1 of a step, as the glued run gives it:
    k times the table's value at the step's start (dsim's interpolation)."""
    from dsim.master.running.tables import TableData, values_at

    data = TableData(profile["time"], np.array([profile[c] for c in CORNERS]),
                     (False,) * 4)
    return lambda t1: SPRING * values_at(data, t1 - step)


def run(stop: float = ROAD["duration"], parameter_set: str = "fine", png: Path | None = None,
        scene: Path | None = None) -> dict:
    """The glued scene and its monolithic twin over 0 .. ``stop`` s with the plate of
    fidelity set ``parameter_set``: each signal's largest difference relative to the
    twin's peak, iterations per step, wall times; the plot at ``png``."""
    import dsim
    from examples.four_post import compare, monolithic

    scene = scene or packed()
    result = dsim.simulate(scene, stop=stop, parameter_set=parameter_set)
    if not result.ok:
        raise RuntimeError(f"four_post_road: {result.message}")
    step = FOUR_POST["step"]
    twin = monolithic("flexible", fidelity=parameter_set, stop=stop,
                      base_force=road_force(road_profile(), step))
    report = {**compare(result.signals, twin),
              "iterations": result.statistics["iterations"]["mean_per_step"],
              "glued_seconds": result.statistics["wall_seconds"],
              "monolithic_seconds": twin["seconds"]}
    if png is not None:
        plot(result.signals, twin["columns"], png)
    return report


def plot(glued: dict, twin: dict, png: Path) -> None:
    """The road under the front-left post, the heave and pitch of the plate and the
    front-left mount force, glued and monolithic."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from dsim.master.recording.results import save_figure
    from examples.four_post import heave_pitch_roll

    figure, axes = plt.subplots(4, 1, figsize=(10, 9), sharex=True)
    time = np.asarray(glued["time"])
    for name, style in (("road.fl", "C0-"), ("road.rl", "C2-")):
        axes[0].plot(time, 1e3 * np.asarray(glued[name]), style, lw=0.8,
                     label=f"road under {name[-2:]} (the table component's output)")
    axes[0].set_ylabel("road (mm)")
    axes[0].legend(fontsize=8, loc="upper right")
    axes[0].set_title("four_post_road: a class B random road at 10 m/s from road.csv")
    for source, style, label in ((twin, "k-", "monolithic"), (glued, "C1--", "glued (dsim)")):
        heave, pitch, _ = heave_pitch_roll(source)
        axes[1].plot(time, 1e3 * heave, style, lw=1, label=label)
        axes[2].plot(time, 1e3 * pitch, style, lw=1)
        axes[3].plot(time, np.asarray(source["mount_fl.f_z"]) / 1e3, style, lw=1)
    axes[1].set_ylabel("heave (mm)")
    axes[1].legend(fontsize=8, loc="upper right")
    axes[2].set_ylabel("pitch (mrad)")
    axes[3].set_ylabel("front-left mount (kN)")
    axes[3].set_xlabel("time (s)")
    for axis in axes:
        axis.grid(True, alpha=0.3)
    save_figure(figure, png)


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--stop", type=float, default=ROAD["duration"], help="stop time, s")
    parser.add_argument("--parameter-set", default="fine", choices=sorted(FIDELITY),
                        help="the plate's fidelity set (docs/four_post.md)")
    parser.add_argument("--png", default=str(ROOT / "docs" / "figures" / "four_post_road.png"))
    args = parser.parse_args()
    found = run(args.stop, args.parameter_set, Path(args.png))
    print(f"four_post_road ({args.parameter_set}, 0 .. {args.stop:g} s): glued vs monolithic, "
          f"max difference / peak: pad heights {found['heights']:.2e}, mount forces "
          f"{found['forces']:.2e}, plate centre {found['centre']:.2e}; "
          f"{found['iterations']:.3f} iterations per step; glued {found['glued_seconds']:.1f} "
          f"s, monolithic {found['monolithic_seconds']:.1f} s")
