"""Force-tracking laws, one module each, and their registry.

========================  ======================================================
``tmt``                   eq. (18), the paper's trajectory modification technique
``known``                 eqs. (11)-(12) with an assumed stiffness
========================  ======================================================

A new law is one module declaring a :class:`~.base.Law` and one
:func:`~.base.register_law` line here.
"""

from .base import MEASUREMENTS, OUTPUTS, Law, LawParameters, get_law, laws, on_register, register_law, unregister_law
from .known import KNOWN
from .tmt import TMT

register_law(TMT)
register_law(KNOWN)

__all__ = ["Law", "LawParameters", "MEASUREMENTS", "OUTPUTS", "register_law", "unregister_law", "get_law",
           "laws", "on_register", "TMT", "KNOWN"]
