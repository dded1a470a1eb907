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

PACKAGE_LAWS = (TMT, KNOWN, INTEGRAL, ADAPTIVE_DAMPING, RLS)
"""The package's own declarations, whose code the package's digest covers."""

for _law in PACKAGE_LAWS:
    register_law(_law)


def is_package_law(law: Law) -> bool:
    """Whether ``law`` is one of :data:`PACKAGE_LAWS` itself (by identity): a
    declaration made elsewhere, even from a package law's pieces
    (``TMT.replace(name=...)``), is not, whatever module its functions
    come from."""
    return any(law is own for own in PACKAGE_LAWS)


__all__ = ["Law", "LawParameters", "MEASUREMENTS", "OUTPUTS", "register_law", "unregister_law", "get_law",
           "laws", "on_register", "PACKAGE_LAWS", "is_package_law", "TMT", "KNOWN", "INTEGRAL", "ADAPTIVE_DAMPING", "RLS"]
