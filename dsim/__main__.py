"""``python -m dsim``: the command line (``dsim run`` under its supervising process)."""
from dsim.master.tools.supervisor import console

console()
