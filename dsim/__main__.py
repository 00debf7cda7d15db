"""``python -m dsim``: the command line."""
from dsim.master.tools.cli import console

console()
