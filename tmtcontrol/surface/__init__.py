"""Contact surfaces: one interface, asked by the loop, the analyses, the metrics, the figures and the export.

A :class:`Surface` answers, at a point of the base frame: the task frame
(inward normal first), the task coordinates (the normal coordinate is the
penetration depth, so the contact law of section III reads
``f_e = k_e (x - x_e)``), the signed distance, and the mapping between task
coordinates and the base frame; symbolically (CasADi) for the closed loop and
numerically for everything else. :func:`contact_force` is the contact law.
:class:`Plane`, :class:`Sphere`, :class:`Cylinder` and :class:`HeightMap` are the shapes. Nothing above this package asks which
shape it is.
"""

from .base import Surface, contact_force
from .curved import SIDES, Cylinder, Sphere
from .heightmap import HeightMap
from .plane import Plane, normal_frame, tilt_frame

SHAPES = {"plane": Plane, "sphere": Sphere, "cylinder": Cylinder, "heightmap": HeightMap}
"""Each shape's class by its :attr:`Surface.kind`."""


def make_surface(kind: str, R, c, radius=None, side=None, axis=None, heights=None, spacing=None) -> Surface:
    """The surface of shape ``kind`` whose tangent plane at ``c`` (m, base
    frame) has the task frame ``R`` (columns: inward normal, tangents): the
    plane itself, the sphere or cylinder of ``radius`` (m) touching it there,
    the tool on its ``side`` (default outside), a cylinder's axis along
    ``axis`` (projected onto the tangent plane; default R's third column), or
    the height map of ``heights`` (m) on a grid of ``spacing`` (m)."""
    import numpy as np

    R = np.asarray(R, dtype=float)
    if axis is not None:                   # the axis becomes the frame's third column
        t2 = np.asarray(axis, dtype=float) - (np.asarray(axis, dtype=float) @ R[:, 0]) * R[:, 0]
        t2 /= np.linalg.norm(t2)
        R = np.column_stack([R[:, 0], np.cross(t2, R[:, 0]), t2])
    cls = SHAPES[kind]
    if heights is not None:
        return cls(R, c, heights, spacing)
    return cls(R, c) if not cls.turns else cls(R, c, radius, side or "outside")

__all__ = ["Surface", "Plane", "Sphere", "Cylinder", "HeightMap", "SHAPES", "make_surface", "SIDES", "contact_force", "normal_frame",
           "tilt_frame"]
