"""What an FMU logs: only its warning and error categories unless ``--fmu-log``.

A plain-C FMU (tests/third_party/block.c built with -DCHATTY) logs 30 messages of
category logEvents per step while that category is on, as some tools' FMUs log every
event, and counts them in its output ``logged``.  dsim asks an FMU that declares
warning and error categories for those only (fmi2SetDebugLogging), so the chatty
FMU logs nothing per step; one that declares no category keeps every category on
(which of its messages matter cannot be told); ``--fmu-log`` turns every category
on and prints each message."""
import subprocess
import sys

import pytest

import dsim
from dsim.master.running.fmi.messages import KEPT, _MESSAGES, problem_categories, record
from tests.support.third_party.build import BLOCK_VARIABLES, Variable, c_fmu, causal_ring_ssp

PER_STEP = 30
STEPS = 50
VARIABLES = BLOCK_VARIABLES + (Variable("logged", 3, "Integer", "output",
                                        initial="calculated"),)
CATEGORIES = ("logEvents", "logStatusWarning", "logStatusDiscard", "logStatusError",
              "logStatusFatal", "logAll")


def chatty_scene(folder, categories):
    fmu = c_fmu(folder, "block", variables=VARIABLES, defines=(f"CHATTY={PER_STEP}",),
                log_categories=categories)
    return causal_ring_ssp(folder / "ring.ssp", fmu, 2, stop=STEPS * 1e-3, step=1e-3,
                           integer_outputs=("logged",))


def logged(result) -> list[float]:
    return [float(result.signals[f"b{i}.logged"][-1]) for i in (1, 2)]


def test_an_fmu_with_warning_and_error_categories_is_asked_for_those_only(tmp_path):
    scene = chatty_scene(tmp_path, CATEGORIES)
    quiet = dsim.simulate(scene)
    assert quiet.status == "completed" and quiet.steps == STEPS
    assert logged(quiet) == [0.0, 0.0]
    loud = dsim.simulate(scene, fmu_log=True)
    assert logged(loud) == [PER_STEP * STEPS] * 2


def test_an_fmu_that_declares_no_category_keeps_every_one(tmp_path):
    result = dsim.simulate(chatty_scene(tmp_path, ()))
    assert logged(result) == [PER_STEP * STEPS] * 2


def test_fmu_log_prints_every_message_with_its_component_and_category(tmp_path):
    scene = chatty_scene(tmp_path, CATEGORIES)
    done = subprocess.run([sys.executable, "-m", "dsim", "run", str(scene), "--fmu-log",
                           "--quiet", "--out", str(tmp_path / "ring.csv")],
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    lines = [line for line in done.stderr.splitlines() if "[OK] logEvents:" in line]
    assert len(lines) == 2 * PER_STEP * STEPS
    assert lines[0].startswith("dsim: fmu b1: [OK] logEvents: block: event 0 of the step")
    quiet = subprocess.run([sys.executable, "-m", "dsim", "run", str(scene), "--quiet",
                            "--out", str(tmp_path / "quiet.csv")],
                           capture_output=True, text=True, timeout=120)
    assert quiet.returncode == 0 and "logEvents" not in quiet.stderr


@pytest.mark.parametrize("categories, chosen", [
    (CATEGORIES, ["logStatusWarning", "logStatusDiscard", "logStatusError",
                  "logStatusFatal"]),
    (("logEvents", "logSingularLinearSystems", "logNonlinearSystems"), []),
    (("Error", "WARNINGS", "info"), ["Error", "WARNINGS"])])
def test_the_categories_asked_for_are_those_of_problems(categories, chosen):
    assert problem_categories(categories) == chosen


def test_an_instance_keeps_its_last_messages_only():
    for k in range(3 * KEPT):
        record("kept-test", 0, f"message {k}")
    try:
        assert [text for _, text in _MESSAGES["kept-test"]] == [
            f"message {k}" for k in range(2 * KEPT, 3 * KEPT)]
    finally:
        _MESSAGES.pop("kept-test")
