"""What every `dsim` command pays before it starts: its parser registers the commands
of the other packages (`dsim serve`, `dsim build-fmus`) without importing the web
application or the finite-element twins (a third of a second of each command's start,
measured 0.70 s against 0.37 s for `dsim --version`)."""
import json
import subprocess
import sys

HEAVY = ("fastapi", "starlette", "uvicorn", "jinja2", "skfem", "dsim.serve.app",
         "dsim.build_fmus.twins")


def test_the_parser_imports_neither_the_web_application_nor_the_twins():
    script = ("import json, sys\nfrom dsim.master.tools.cli import parser\n"
              "commands = parser()._subparsers._group_actions[0].choices\n"
              f"print(json.dumps([sorted(commands), [m for m in {HEAVY!r} "
              "if m in sys.modules]]))")
    said = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                          check=True).stdout
    commands, imported = json.loads(said)
    assert {"run", "serve", "build-fmus"} <= set(commands)  # still registered
    assert imported == []
