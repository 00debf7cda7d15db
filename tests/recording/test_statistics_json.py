"""The statistics JSON: indented for a small scene; with many components one line per
top-level key and per component, the same data (master/recording/observers/statistics_writer.py)."""
import json
import math

from dsim.master.recording.observers import ONE_LINE_EACH, statistics_json


def statistics(components: int) -> dict:
    table = {"do_steps": 3, "seconds": 0.25, "functions": {"fmi2DoStep": {"calls": 3,
                                                                          "seconds": 0.1}}}
    return {"scene": "s", "status": "interrupted", "message": "a \"quoted\"\nline",
            "master": {"step": 1e-3, "tolerance": math.inf}, "iterations": {"total": 4},
            "components": {f"m{i}": dict(table, do_steps=i) for i in range(components)},
            "units": {"time": "s", "m1.x[1]": "m"}, "warnings": [], "residual": math.nan}


def test_a_small_scene_is_indented_as_before():
    small = statistics(ONE_LINE_EACH)
    assert statistics_json(small) == json.dumps(small, indent=2, default=str)


def test_many_components_one_line_each_and_the_same_data():
    many = statistics(ONE_LINE_EACH + 1)
    text = statistics_json(many)
    back = json.loads(text)
    assert math.isnan(back.pop("residual")) and math.isnan(many.pop("residual"))
    assert back == many
    lines = text.splitlines()
    assert lines[0] == "{" and lines[-1] == "}"
    assert lines[1] == '  "scene": "s",' and '  "message": "a \\"quoted\\"\\nline",' in lines
    each = [line for line in lines if line.startswith('    "m')]
    assert len(each) == ONE_LINE_EACH + 1 and json.loads("{" + each[7].rstrip(",") + "}") \
        == {"m7": many["components"]["m7"]}
    # the braces, a line per key (the residual was popped above), the components and
    # their closing brace
    assert len(lines) == 2 + (len(many) + 1) + len(each) + 1
