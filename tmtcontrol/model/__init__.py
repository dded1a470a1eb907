"""Robot dynamics, eq. (1): one robot interface (:func:`load_robot`, :class:`Robot`)
with two sources behind it, the paper's symbolic 3-link PUMA 560 (kinematics,
joint-space and Cartesian dynamics, friction, inverse kinematics) and any
fixed-base serial arm from a URDF (parsed in :mod:`.urdf`, Featherstone's
algorithms in :mod:`.featherstone`), built with CasADi."""

from .puma560 import PUMA560_LINKS, LinkParameters, Puma560
from .robot import Robot, RobotFunctions, URDFError, load_robot

__all__ = ["Puma560", "PUMA560_LINKS", "LinkParameters", "Robot", "RobotFunctions", "URDFError", "load_robot"]
