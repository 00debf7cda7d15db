"""examples/four_post_road.py (docs/inputs.md): the four-post rig driven by a road
profile from a CSV file through a table component runs, and matches its monolithic
twin as the docs say (here over 0.1 s with the rigid plate, to stay short)."""
import numpy as np


def test_the_road_driven_rig_matches_its_twin(built, tmp_path):
    from examples.four_post_road import ROAD, packed, road_profile, run

    profile = road_profile()
    again = road_profile()
    assert all(np.array_equal(profile[k], again[k]) for k in profile)  # seeded
    assert profile["fl"][0] == 0.0 and len(profile["time"]) == 1001
    # the rear posts see the front's road 0.19 s later
    lag = int(round(ROAD["wheelbase"] / ROAD["speed"] / ROAD["interval"]))
    assert np.allclose(profile["rl"][lag:], profile["fl"][:-lag], rtol=0, atol=1e-12)
    scene = packed(tmp_path)
    found = run(stop=0.1, parameter_set="rigid", scene=scene)
    # docs/inputs.md: the glued run within 1e-9 of the twin's peak (gluing to 1e-10 m)
    assert found["heights"] < 1e-9 and found["centre"] < 1e-9 and found["forces"] < 1e-8
