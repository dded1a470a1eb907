"""tmtcontrol: force-tracking impedance control with the trajectory modification technique."""
__version__ = "0.1.0"
from .robot import Puma560, PUMA560_LINKS, LinkParameters
