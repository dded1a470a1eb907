"""Robot dynamics, eq. (1): the symbolic 3-link PUMA 560 (kinematics, joint-space
and Cartesian dynamics, friction, inverse kinematics), built with CasADi."""

from .puma560 import PUMA560_LINKS, LinkParameters, Puma560

__all__ = ["Puma560", "PUMA560_LINKS", "LinkParameters"]
