"""The ElasticBody FMU's script (what pythonfmu builds and loads): the model class is
:class:`fmus.elastic.slave.ElasticBody`, imported here.

Why it imports its model class instead of defining it, and holds ``_HELD``:
fmus/spring_mass/spring_mass_fmu.py.  The lines below are the same in every dsim FMU's
script: each runs alone, before its own ``fmus`` package can be imported.
"""
import os
import sys

# Another dsim FMU in this process may have imported the fmus package from its own
# resources folder, which its master may since have deleted: look in ours first.
_OWN = os.path.join(os.path.dirname(os.path.abspath(__file__)), "fmus")
if "fmus" in sys.modules and os.path.isdir(_OWN) and _OWN not in sys.modules["fmus"].__path__:
    sys.modules["fmus"].__path__.insert(0, _OWN)

globals().setdefault("_HELD", []).append(globals())

from fmus.elastic.slave import ElasticBody  # noqa: E402,F401 (the model class)
