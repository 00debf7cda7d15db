"""dsim's co-simulation master: SSP in, T-T glued FMUs, results out."""
from importlib.metadata import PackageNotFoundError, version

try:  # the installed distribution's version (pyproject.toml), never a second copy of it
    __version__ = version("dsim")
except PackageNotFoundError:  # run from a source tree that was never installed
    __version__ = "0+unknown"
