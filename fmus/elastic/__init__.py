"""Linear elastic finite-element bodies (scikit-fem) as glueable cores.

``ElasticBody`` implements :class:`dsim.fmus.interface.InterfaceCore`; ``frame`` builds the
ladder-frame scenes of SCENES.md; ``slave`` holds the ElasticBody FMU's model class, which its
script ``elastic_body_fmu`` imports. See docs/elastic_body.md.
"""
from .assembly import STEEL, Material
from .core import ElasticBody, PointLoad
from .geometry import box, in_box, load_mesh, merge_meshes, rectangle
from .reduction import ReductionError, craig_bampton_error

__all__ = ["ElasticBody", "PointLoad", "Material", "STEEL", "rectangle", "box", "load_mesh",
           "in_box", "merge_meshes", "craig_bampton_error", "ReductionError"]
