"""Rigid bodies: the shape of the body's lower surface.

Conventions (all lengths in metres, or any one consistent length unit):

* The half-space surface is z = 0 and the body presses down on it from above.
* A body's lower surface is given by ``Z(x, y) >= 0``: the height of the body's surface above its own
  lowest point, at offsets ``(x, y)`` from the body's reference point (for the symmetric shapes, the
  lowest point itself, so ``Z(0, 0) = 0``).
* Where the body has no surface (past the width of a cylinder, outside a height map) ``Z = +inf``: it can
  never touch there.  Its slope is 0 there.

Evaluation is vectorised: ``x`` and ``y`` are numpy arrays that broadcast against each other (for example
``x`` of shape ``(n, 1)`` and ``y`` of shape ``(1, m)`` give an ``(n, m)`` result).

Modules by concern: ``base`` (the :class:`Body` interface, the validation shared by all bodies),
``analytic`` (bodies given by formulas), ``maps`` (bodies from sampled heights: maps and profiles),
``mesh`` (triangle meshes rasterised to maps), ``rough`` (periodic surfaces from samples, roughness
riding on a smooth body), ``factory`` (a scene's [body] table: shapes, keys,
:func:`make_body`).
"""

from petroll.model.bodies.analytic import Cylinder, CylinderSection, Ellipsoid, Sphere
from petroll.model.bodies.base import PYTHON_SOURCE, Body
from petroll.model.bodies.factory import BODY_KEYS, LINE_BODY_KEYS, make_body
from petroll.model.bodies.maps import HeightMap, HeightProfile
from petroll.model.bodies.mesh import mesh_height_map

__all__ = [
    "BODY_KEYS",
    "LINE_BODY_KEYS",
    "PYTHON_SOURCE",
    "Body",
    "Cylinder",
    "CylinderSection",
    "Ellipsoid",
    "HeightMap",
    "HeightProfile",
    "Sphere",
    "make_body",
    "mesh_height_map",
]
