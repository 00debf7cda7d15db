"""The Linkage2D FMU models what its ``mechanism`` description says: a user's own
linkage, written as JSON, with no scene known to the FMU."""
import json
import math
import shutil

import numpy as np
from fmpy import simulate_fmu

from dsim.build_fmus.scenes import SceneWriter
from dsim.fmus.linkage.description import mechanism_from_text, mechanism_to_text
from dsim.fmus.linkage.scenes import crank_slider_mechanism, four_bar_part
from dsim.master.tools.cli import main


def test_a_description_round_trips_every_element():
    whole = crank_slider_mechanism()
    text = mechanism_to_text(whole)
    assert mechanism_from_text(text) == whole
    assert mechanism_to_text(four_bar_part("coupler")).count('"ports"') == 1


def test_the_fmu_alone_swings_its_default_pendulum(built):
    """A 1 m bar pinned at one end, released horizontal: at the bottom its rate is
    sqrt(3 g / L) (energy), which the trapezoidal rule keeps to 1e-4 at H = 1 ms."""
    result = simulate_fmu(str(built["fmus"] / "Linkage2D.fmu"), stop_time=1.0,
                          step_size=1e-3, output_interval=1e-3, output=["theta", "omega"])
    bottom = np.argmin(np.abs(result["theta"] + math.pi / 2))
    assert abs(result["theta"][bottom] + math.pi / 2) < 0.01
    assert abs(abs(result["omega"]).max() - math.sqrt(3 * 9.81)) < 1e-4 * math.sqrt(3 * 9.81)


def truss_scene(folder, built, description: str):
    """Two 1 m bars described in the scene's parameters, pinned to ground 1.2 m apart
    and glued tip to tip at (0.6, 0.8): a triangle."""
    scene = SceneWriter("truss", "two bars pinned to ground 1.2 m apart, tips glued")
    left, right = json.loads(description), json.loads(description)
    left["bodies"][0].update(x=0.3, y=0.4, theta=math.atan2(0.8, 0.6))
    right["bodies"][0].update(x=0.9, y=0.4, theta=math.atan2(0.8, -0.6))
    right["revolutes"][0]["point_j"] = [1.2, 0.0]
    for name, values in (("left", left), ("right", right)):
        scene.component(name, "Linkage2D", {"mechanism": json.dumps(values)},
                        outputs=["theta", "omega"])
    scene.joint("tips", "left.A", "right.A", dofs="x y")
    scene.write(folder, 0.0, 0.5, step=1e-3, tolerance=1e-10, start="consistent")
    (folder / "resources").mkdir(exist_ok=True)
    shutil.copy(built["fmus"] / "Linkage2D.fmu", folder / "resources")
    return folder


PENDULUM = {"bodies": [{"name": "bar", "mass": 1.0, "inertia": 1 / 12, "x": 0.5}],
            "revolutes": [{"name": "O", "body_i": "bar", "point_i": [-0.5, 0.0],
                           "body_j": None, "point_j": [0.0, 0.0]}],
            "ports": [{"name": "A", "body": "bar", "point": [0.5, 0.0]}],
            "gravity": [0.0, -9.81]}


def test_a_user_mechanism_glued_from_its_description(built, tmp_path):
    """The truss stands still under gravity; each bar's moment about its ground pin
    (tip at (0.6, 0.8), weight 9.81 N at (0.3, 0.4)) asks a horizontal push of
    0.3 * 9.81 / 0.8 = 3.679 N at the tips, and by symmetry no vertical force."""
    folder = truss_scene(tmp_path / "scene", built, json.dumps(PENDULUM))
    assert main(["run", str(folder), "--out", str(tmp_path / "r.csv"), "--quiet"]) == 0
    from dsim.master.recording.results import read_columns

    run = read_columns(tmp_path / "r.csv")
    assert np.max(np.abs(run["left.omega"])) < 1e-9
    assert np.max(np.abs(run["tips.f_x"] - 0.3 * 9.81 / 0.8)) < 1e-6
    assert np.max(np.abs(run["tips.f_y"])) < 1e-6


def test_a_bad_description_is_one_line_and_exit_2(built, tmp_path, capsys):
    bad = dict(PENDULUM, bodies=[{"name": "bar", "mass": 1.0, "inertia": 1 / 12,
                                  "x": 0.5, "colour": "red"}])
    folder = truss_scene(tmp_path / "scene", built, json.dumps(bad))
    assert main(["run", str(folder), "--out", str(tmp_path / "r.csv"), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "bodies[0]: unknown field colour" in err
    assert "Traceback" not in err
