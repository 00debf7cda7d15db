"""``python -m dsim``: the command line."""
import sys

from master.cli import main

sys.exit(main())
