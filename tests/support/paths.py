"""Where the tests run from: the repository's root, and the ``dsim`` command line."""
import sys
from pathlib import Path

#: the repository's root (the folder of pyproject.toml)
ROOT = Path(__file__).resolve().parents[2]
#: ``dsim`` as this interpreter runs it
DSIM = [sys.executable, "-m", "dsim"]
