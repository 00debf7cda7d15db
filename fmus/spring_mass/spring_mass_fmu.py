"""The SpringMass FMU's script (what pythonfmu builds and loads): the model class is
:class:`fmus.spring_mass.slave.SpringMass`, imported here.

pythonfmu 0.7 runs this script again for every instance it makes (to find the model
class among the names it defines), in this module's namespace, and keeps what that run
makes (the classes' method resolution lists it reads are never released): a class
defined here would be made again, with its methods and variables, for each of 10,000
instances.  Imported, it is made once.  pythonfmu also releases one reference to this
module's namespace per instance that it never took: the script holds one for it
(``_HELD``), or the namespace would be freed under the module after a few instances.
The ElasticBody, Linkage2D and FlexibleLink2D scripts do the same, with the same lines.
"""
import os
import sys

# Another dsim FMU in this process may have imported the fmus package from its own
# resources folder, which its master may since have deleted: look in ours first.
_OWN = os.path.join(os.path.dirname(os.path.abspath(__file__)), "fmus")
if "fmus" in sys.modules and os.path.isdir(_OWN) and _OWN not in sys.modules["fmus"].__path__:
    sys.modules["fmus"].__path__.insert(0, _OWN)

globals().setdefault("_HELD", []).append(globals())

from fmus.spring_mass.slave import SpringMass  # noqa: E402,F401 (the model class)
