"""Every name the project's Python uses is defined: a module-level constant lost in a
merge (benchmarks/scaling.py's GUIDE once was) fails here, not in a benchmark run hours
later.  Only pyflakes' undefined-name findings count; unused imports are not errors."""
import subprocess

from pyflakes import api, messages, reporter

from tests.support.paths import ROOT


class Collected(reporter.Reporter):
    """A pyflakes reporter that keeps the findings instead of printing them."""

    def __init__(self):
        super().__init__(None, None)
        self.found = []

    def flake(self, message):
        self.found.append(message)

    def syntaxError(self, filename, msg, lineno, offset, text):
        self.found.append(f"{filename}:{lineno}: syntax error: {msg}")

    def unexpectedError(self, filename, msg):
        self.found.append(f"{filename}: {msg}")


UNDEFINED = (messages.UndefinedName, messages.UndefinedExport, messages.UndefinedLocal)


def test_no_python_file_of_the_project_uses_an_undefined_name():
    files = subprocess.run(["git", "ls-files", "*.py"], cwd=ROOT, capture_output=True,
                           text=True, check=True).stdout.split()
    assert len(files) > 100
    collected = Collected()
    for name in files:
        api.checkPath(str(ROOT / name), collected)
    wrong = [str(m) for m in collected.found
             if isinstance(m, str) or isinstance(m, UNDEFINED)]
    assert wrong == []


def test_the_check_finds_an_undefined_name(tmp_path):
    bad = tmp_path / "bad.py"
    bad.write_text("TEXT = [*GUIDE]\n")
    collected = Collected()
    api.checkPath(str(bad), collected)
    assert [type(m) for m in collected.found] == [messages.UndefinedName]
