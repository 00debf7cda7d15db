"""``python -m dsim``: the command line."""
from master.cli import console

console()
