"""Contact surfaces: one interface, asked by the loop, the analyses, the metrics, the figures and the export.

A :class:`Surface` answers, at a point of the base frame: the task frame
(inward normal first), the task coordinates (the normal coordinate is the
penetration depth, so the contact law of section III reads
``f_e = k_e (x - x_e)``), the signed distance, and the mapping between task
coordinates and the base frame; symbolically (CasADi) for the closed loop and
numerically for everything else. :func:`contact_force` is the contact law.
:class:`Plane` is the first shape. Nothing above this package asks which
shape it is.
"""

from .base import Surface, contact_force
from .plane import Plane, normal_frame, tilt_frame

__all__ = ["Surface", "Plane", "contact_force", "normal_frame", "tilt_frame"]
