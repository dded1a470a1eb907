"""What a force-tracking law is: a declaration, and the registry of laws.

A law chooses the normal-axis command of the position-based impedance
controller (eqs. 2-6) from the sampled measurements. Like python-control's
``nlsys`` it is declared, not wired: a :class:`Law` names its parameters (a
pydantic model: units, defaults, ranges), its internal state with initial
values, and one symbolic CasADi update

    update(y, p, s) -> {"x_r", "x_c", "dx_c", "ddx_c", "s_next"}

from the measurements ``y`` (:data:`MEASUREMENTS`: normal position x and
velocity dx (m, m/s, task frame, x grows into the surface), measured force
f_m (N), desired force f_d (N), the controller's surface estimate x_e_hat
(m), control period Ts (s) and the normal impedance m, b, k (kg, N s/m,
N/m; b may be scheduled online)), its parameters ``p`` and its state ``s``
(dicts of symbols by name) to the reference x_r (logged), the command
x_c, dx_c, ddx_c of eq. (4) and the next state. The closed loop asks a law
for these and never for its name.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any, Callable

import casadi as ca
import numpy as np

from ...settings import Settings

__all__ = ["LawParameters", "Law", "MEASUREMENTS", "OUTPUTS", "register_law", "unregister_law", "get_law", "laws",
           "on_register"]

MEASUREMENTS = ("x", "dx", "f_m", "f_d", "x_e_hat", "Ts", "m", "b", "k")
"""Inputs of every law's update, in this order (see the module docstring)."""

OUTPUTS = ("x_r", "x_c", "dx_c", "ddx_c")
"""Scalar outputs of every law's update besides ``s_next``."""


class LawParameters(Settings):
    """Base of every law's parameter schema: ``kind`` (the law's name) and
    numeric fields (floats, SI units in each field's description); frozen,
    no unknown keys, its copies validated (:class:`~tmtcontrol.settings.Settings`)."""

    kind: str


@dataclass(frozen=True)
class Law:
    """A force-tracking law, declared.

    Attributes
    ----------
    name : str
        The value of ``controller.law`` that selects it.
    parameters : type[LawParameters]
        Its parameter schema (``kind: Literal[name]`` plus numeric fields).
    states : tuple of str
        Names of its internal state, in order.
    update : callable
        ``update(y, p, s) -> dict`` with :data:`OUTPUTS` and ``"s_next"``
        (a dict by state name), all CasADi expressions.
    initial : callable
        ``initial(params) -> dict`` of initial state values (default zeros).
    uses_impedance_filter : bool
        Whether the normal command goes through the impedance filter of
        eqs. (2)-(4) (then the stiffness-scheduled damping applies to it).
    needs : tuple of str
        What it must be told about the environment: ``"x_e"`` (surface
        location) and/or ``"k_e"`` (stiffness).
    summary : str
        One line: what it does and where it comes from.
    steady_force : callable, optional
        Its steady-state claim, ``steady_force(params, f_d, k, k_e, delta)
        -> f_e`` (N) for a constant stiffness k_e (N/m), impedance stiffness
        k (N/m) and surface-location error ``delta`` (m, estimate minus true
        surface). The derivation checks compare it with the equilibrium of
        the symbolic closed loop.
    linear_analysis : bool
        Whether the spectral radius at its equilibrium decides local
        stability (False for a law with a continuum of equilibria, such as
        parameter estimates that the data do not identify).
    characteristic_polynomial : callable, optional
        Its documented continuous-time normal-axis characteristic polynomial
        with the ideal inner loop, ``(params, m, b, k, k_e, f_d, delta) ->
        coefficients`` (highest power first; ``delta`` the surface-location
        error, m); checked against ``stability.lawloop``.
    """
    name: str
    parameters: type[LawParameters]
    states: tuple[str, ...]
    update: Callable[[dict, dict, dict], dict]
    initial: Callable[[Any], dict] | None = None
    uses_impedance_filter: bool = True
    needs: tuple[str, ...] = ("x_e",)
    summary: str = ""
    steady_force: Callable[..., float] | None = None
    linear_analysis: bool = True
    characteristic_polynomial: Callable[..., list] | None = None

    @property
    def parameter_names(self) -> tuple[str, ...]:
        """Numeric parameter fields, in declaration order (``kind`` excluded)."""
        return tuple(n for n in self.parameters.model_fields if n != "kind")

    def parameter_vector(self, params: LawParameters) -> np.ndarray:
        return np.array([float(getattr(params, n)) for n in self.parameter_names])

    def initial_state(self, params: LawParameters) -> np.ndarray:
        init = self.initial(params) if self.initial is not None else {}
        unknown = set(init) - set(self.states)
        if unknown:
            raise ValueError(f"law {self.name!r}: initial() names unknown states {sorted(unknown)}")
        return np.array([float(init.get(n, 0.0)) for n in self.states])

    def function(self, sym=ca.SX) -> ca.Function:
        """The update as a named CasADi Function
        ``law_<name>: [y, p, s] -> [x_r, x_c, dx_c, ddx_c, s_next]``
        (built once per law declaration and symbol type)."""
        key = (self.name, self.update, tuple(self.states), tuple(self.parameter_names), sym)
        if key not in _FUNCTIONS:
            _FUNCTIONS[key] = self._build_function(sym)
        return _FUNCTIONS[key]

    def _build_function(self, sym) -> ca.Function:
        y = sym.sym("y", len(MEASUREMENTS))
        p = sym.sym("p", len(self.parameter_names))
        s = sym.sym("s", len(self.states))
        out = self.update(dict(zip(MEASUREMENTS, ca.vertsplit(y))),
                          dict(zip(self.parameter_names, ca.vertsplit(p))) if self.parameter_names else {},
                          dict(zip(self.states, ca.vertsplit(s))) if self.states else {})
        missing = [k for k in (*OUTPUTS, "s_next") if k not in out]
        if missing:
            raise ValueError(f"law {self.name!r}: update() does not return {missing}")
        nxt = out["s_next"]
        if set(nxt) != set(self.states):
            raise ValueError(f"law {self.name!r}: s_next must give exactly the states {self.states}")
        s_next = ca.vertcat(*[nxt[n] for n in self.states]) if self.states else sym(0, 1)
        return ca.Function(f"law_{self.name}", [y, p, s], [*(out[k] for k in OUTPUTS), s_next],
                           ["y", "p", "s"], [*OUTPUTS, "s_next"])

    def replace(self, **changes) -> "Law":
        return dataclasses.replace(self, **changes)


_REGISTRY: dict[str, Law] = {}
_FUNCTIONS: dict = {}
"""Built update Functions by declaration (a Function is immutable)."""
_LISTENERS: list[Callable[[], None]] = []


def register_law(law: Law, *, replace: bool = False) -> Law:
    """Add ``law`` to the registry (the scenario schema is rebuilt to accept
    it). Re-registering a name needs ``replace=True``."""
    if not isinstance(law, Law):
        raise TypeError("register_law: expected a Law")
    kind = law.parameters.model_fields.get("kind")
    if kind is None or kind.default != law.name:
        raise ValueError(f"law {law.name!r}: its parameters need kind: Literal[{law.name!r}] = {law.name!r}")
    if law.name in _REGISTRY and not replace:
        raise ValueError(f"law {law.name!r} is already registered")
    _REGISTRY[law.name] = law
    for listener in _LISTENERS:
        listener()
    return law


def unregister_law(name: str) -> None:
    """Remove a law (for tests that register a temporary one)."""
    _REGISTRY.pop(name)
    for listener in _LISTENERS:
        listener()


def on_register(listener: Callable[[], None]) -> None:
    """Call ``listener()`` whenever the registry changes."""
    _LISTENERS.append(listener)


def get_law(name: str) -> Law:
    try:
        return _REGISTRY[name]
    except KeyError:
        raise ValueError(f"controller.law: unknown law {name!r} (known: {', '.join(_REGISTRY)})") from None


def laws() -> dict[str, Law]:
    """The registered laws by name, in registration order."""
    return dict(_REGISTRY)
