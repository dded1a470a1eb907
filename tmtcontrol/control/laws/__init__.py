"""Force-tracking laws, one module each, and their registry.

========================  ======================================================
``tmt``                   eq. (18), the paper's trajectory modification technique
``known``                 eqs. (11)-(12) with an assumed stiffness
``integral``              reference driven by the integrated force error
``adaptive_damping``      Jung-Hsia-Bonitz 2004 adaptive velocity offset, k = 0
``rls``                   RLS estimates of k_e, x_e, then eqs. (11)-(12)
========================  ======================================================

A new law is one module declaring a :class:`~.base.Law` and one
:func:`~.base.register_law` line here.
"""

from .base import MEASUREMENTS, OUTPUTS, Law, LawParameters, get_law, laws, on_register, register_law, unregister_law
from .adaptive_damping import ADAPTIVE_DAMPING
from .integral import INTEGRAL
from .known import KNOWN
from .rls import RLS
from .tmt import TMT

register_law(TMT)
register_law(KNOWN)
register_law(INTEGRAL)
register_law(ADAPTIVE_DAMPING)
register_law(RLS)

__all__ = ["Law", "LawParameters", "MEASUREMENTS", "OUTPUTS", "register_law", "unregister_law", "get_law",
           "laws", "on_register", "TMT", "KNOWN", "INTEGRAL", "ADAPTIVE_DAMPING", "RLS"]
