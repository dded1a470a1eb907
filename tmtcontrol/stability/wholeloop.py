"""Whole-loop linearisation of the sampled closed loop (beyond the paper).

The 1-D models (``stability.sampled``, ``stability.lawloop``) explain the
normal axis with an effective mass and an ideal robot. This module
linearises the *simulated* loop itself: the one-period step that the
scenario's simulator compiles (the full robot of eq. (1), the controller's
model D*^, h*^ of eq. (5) with any mass mismatch, the inner loop of eq. (6),
the force filter, the law's own update, the computation delay), frozen at one
point of the path (tangential reference held, velocity and acceleration zero,
constant k_e). The step is ``simulation.closedloop.build_step``, the one
loop of every arm (on a 6-D task the tool orientation held too).

At that point the step is an autonomous map ``s -> s_next``. Its fixed
point (Newton, started from the law's 1-D equilibrium, ``stability.lawloop``)
is the steady state in contact; the Jacobian ``A = d s_next / d s`` there
(CasADi, exact) and its spectral radius decide local stability of the
sampled loop at that point. The state is the joints q, dq (n each), the
force filter, the normal damping, the delay queue and the law's state; the
controller's bookkeeping states (approach phase, approach command, f_d ramp,
surface estimate) are constants in contact and are left out of ``A``. :func:`whole_loop_limit` bisects on k_e
at several points of the path and takes the smallest limit. The plant is
always integrated with the scenario's RK4 substeps (CVODES has no
Jacobian here). Units are SI.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import casadi as ca
import numpy as np

from ..control.laws import get_law
from .continuous import AnalysisError, critical_damping
from .lawloop import law_loop
from .sampled import largest_stable
from ..simulation.geometry import surface_error

__all__ = ["WholeLoop", "WholeLoopModel", "whole_loop", "whole_loop_limit", "equilibrium_damping"]

_BOOKKEEPING = ("approach", "x_app", "ramp", "x_e_hat")

_BUILT: dict = {}
"""Symbolic step and Jacobian per closed-loop structure (numbers are inputs)."""


def _build(sc):
    """The step of ``sc``'s structure as ``(s, [u; p]) -> (s_next, f_e)`` and its
    Jacobian in s, with the loop that owns it (``simulation.Simulator``) and the
    dynamic states."""
    from ..simulation.simulator import Simulator

    loop = Simulator(sc, compile=False)
    layout, step = loop.layout, loop.step
    s = ca.SX.sym("s", layout.size)
    u = ca.SX.sym("u", step.size1_in(1))
    p = ca.SX.sym("p", step.size1_in(2))
    s_next, log = step(s, u, p)
    up = ca.vertcat(u, p)
    f = ca.Function("whole_step", [s, up], [s_next, log[loop.f_e]], ["s", "up"], ["s_next", "f_e"])
    # The Jacobian by algorithmic differentiation through f (MX), not expanded into one SX
    # graph: that graph had 205,000 operations (20x the step), took as long to build as
    # everything else here and evaluated 2-3x slower than the forward sweeps it replaces.
    s_mx, up_mx = ca.MX.sym("s", layout.size), ca.MX.sym("up", up.numel())
    jac = ca.Function("whole_jacobian", [s_mx, up_mx], [ca.jacobian(f(s_mx, up_mx)[0], s_mx)], ["s", "up"], ["A"])
    return loop, dynamic_states(layout), f, jac


def dynamic_states(layout) -> np.ndarray:
    """Indices of the state ``layout``'s dynamic entries: all but the
    controller's bookkeeping (constants in contact)."""
    return np.array([i for name, sl in layout.slices.items() if name not in _BOOKKEEPING
                     for i in range(sl.start, sl.stop)])


def equilibrium_damping(scenario, k_e: float) -> float:
    """The normal impedance damping (N s/m) the loop runs with in steady
    contact at stiffness ``k_e`` (N/m): ``impedance.b`` when fixed; with
    ``controller.damping_schedule.kind = "zeta"`` the schedule's fixed point
    (``simulation.closedloop.damping_schedule``): eq. (25)'s
    ``2 zeta sqrt(m (k + k_hat))`` with the estimate at the law's steady
    force, ``k_hat = f_e/(f_e/k_e - delta)`` (delta the x_e error), clamped
    as the schedule clamps it. Below twice the schedule's force threshold
    the schedule holds its start value. Near a fixed point the damping's
    own deviation does not enter the linearised loop (it multiplies the
    impedance filter's and the inner loop's velocity errors, zero there),
    so the loop is linearised with this constant b and K_D = b/m."""
    sc = scenario
    sch, b0 = sc.controller.damping_schedule, float(sc.impedance.b[0])
    if sch.kind != "zeta":
        return b0
    ctl, m, k = sc.controller, float(sc.impedance.m[0]), float(sc.impedance.k[0])
    law = get_law(ctl.law.kind)
    delta = surface_error(sc)
    f = law.steady_force(ctl.law, ctl.f_d, k, k_e, delta) if law.steady_force else ctl.f_d
    start = min(max(b0, sch.b_min), sch.b_max)
    depth = f / k_e - delta
    if not (f > 2 * sch.force_threshold and depth > 0):
        return start
    k_hat = min(max(f / depth, sch.min_stiffness), sch.k_max)
    return float(min(max(sch.zeta * critical_damping(m, k, k_hat), sch.b_min), sch.b_max))


@dataclass(frozen=True)
class WholeLoop:
    """The linearised sampled loop at one path point and stiffness.

    ``path_time`` (s) locates the point on the circle; ``s_eq`` is the fixed
    point of the step (the closed-loop state), ``f_eq`` the contact force
    there (N), ``A`` the Jacobian over the dynamic states ``states``,
    ``spectral_radius`` its largest eigenvalue magnitude (< 1: locally
    stable), ``residual`` max |step(s_eq) - s_eq| and ``m_p`` the robot's
    effective normal mass at the point (kg)."""
    k_e: float
    Ts: float
    path_time: float
    s_eq: np.ndarray
    f_eq: float
    A: np.ndarray
    states: tuple[str, ...]
    spectral_radius: float
    residual: float
    m_p: float

    @property
    def stable(self) -> bool:
        return self.spectral_radius < 1.0


class WholeLoopModel:
    """The scenario's step, its Jacobian and its numbers, built once; call
    :meth:`at` for a stiffness and a path point."""

    def __init__(self, scenario):
        from ..simulation.simulator import structure

        if not get_law(scenario.controller.law.kind).linear_analysis:
            raise AnalysisError(f"controller.law: {scenario.controller.law.kind!r} has no linear verdict "
                                "(a continuum of equilibria)")
        sc = scenario
        if sc.simulation.integrator != "fixed":
            sc = sc.replace(simulation={"integrator": "fixed", "substeps": sc.simulation.substeps})
        sc = sc.replace(trajectory={**sc.trajectory.model_dump(), "approach_gap": 0.0})
        self.scenario = sc
        key = structure(sc)
        if key not in _BUILT:
            if len(_BUILT) >= 16:
                _BUILT.clear()
            _BUILT[key] = _build(sc)
        self.loop, self.dynamic, self._f, self._jac = _BUILT[key]
        self.sim, self.layout, self.law = self.loop, self.loop.layout, self.loop.law
        self.path = self.loop.path(sc)
        self.U, self.P, self.s0, self.t = self.loop.inputs(sc, self.path)
        self._warm: dict = {}

    def _u(self, i: int, k_e: float) -> np.ndarray:
        from ..simulation.closedloop import INPUT

        u = self.U[:, i].copy()
        u[INPUT["vel_t"]] = 0.0
        u[INPUT["acc_t"]] = 0.0
        u[INPUT["k_e"]] = k_e
        u[INPUT["noise"]] = 0.0
        return u

    def at(self, k_e: float, path_time: float = 0.0) -> WholeLoop:
        """The linearised loop at stiffness ``k_e`` (N/m), the path frozen at
        ``path_time`` (s, along the circle)."""
        sc, loop = self.scenario, self.loop
        if not (np.isfinite(k_e) and k_e > 0):
            raise AnalysisError(f"k_e: must be > 0, got {k_e!r}")
        period = sc.trajectory.period
        i = int(round((path_time % period) / sc.controller.Ts)) % self.t.size
        u = np.r_[self._u(i, k_e), self.P]
        ctl = sc.controller
        from ..simulation.geometry import surface_of

        surface = surface_of(sc)
        # the tangential point and its joint angles on the surface (near the checked path's pose there)
        from ..simulation.trajectory import path_reference

        ref = path_reference(np.array([self.t[i]]), sc.trajectory)
        near = self.path.q[:, int(round((self.t[i] % period) / period * self.path.q.shape[1])) % self.path.q.shape[1]]
        on_surface = surface.to_base(np.r_[0.0, ref.pos[:, 0]])
        n = surface.normal(on_surface)                            # the inward normal there
        q_surface = loop.joints_at(on_surface, near, sc)
        m_p = loop.normal_mass(q_surface, n)
        L = self.layout

        def from_previous(s_prev, k_prev):
            # the equilibrium found at this point for a nearby stiffness (bisection): the force and
            # the law state carry over, the penetration scales as 1/k_e
            s = s_prev.copy()
            s[L["b_n"]] = equilibrium_damping(sc, k_e)
            pen = float(surface.signed_distance(loop.tool_position(s[L["q"]]))[0])
            s[L["q"]] = loop.joints_at(surface.to_base(np.r_[pen * k_prev / k_e, ref.pos[:, 0]]), s[L["q"]], sc)
            return s

        def from_1d():
            # the law's 1-D equilibrium at this effective mass
            kd, kp = sc.impedance.gains
            alpha = sc.sensor.pole(ctl.Ts)
            b = equilibrium_damping(sc, k_e)
            if sc.controller.damping_schedule.kind == "zeta":      # the closed loop's K_D = b/m then
                kd = (b / sc.impedance.m[0],)
            one_d = law_loop(self.law, ctl.law, m=sc.impedance.m[0], b=b, k=sc.impedance.k[0],
                             k_e=k_e, Ts=ctl.Ts, m_p=m_p, f_d=ctl.f_d, delta=surface_error(sc), kd=kd[0],
                             kp=kp[0], alpha=alpha, d_e=sc.environment.damping, delay=ctl.delay_samples,
                             settle=0.5)
            s = self.s0.copy()
            s[L["q"]] = loop.joints_at(surface.to_base(np.r_[float(one_d.z_eq[0]), ref.pos[:, 0]]), q_surface, sc)
            s[L["dq"]] = 0.0
            s[L["b_n"]] = b
            s[L["f_filt"]] = one_d.f_eq
            s[L["law"]] = one_d.z_eq[3:3 + len(self.law.states)]
            return s

        guesses = ([lambda: from_previous(*self._warm[i])] if i in self._warm else []) + [from_1d]
        s_eq = None
        for guess in guesses:
            try:
                start = self._held(guess(), u)
            except ValueError:       # scaled from a far stiffness, the guess left the workspace
                continue
            s_eq, residual = self._newton(start, u)
            if residual < 1e-8:
                self._warm[i] = (s_eq, float(k_e))
                break
        if s_eq is None:
            raise AnalysisError(f"k_e = {k_e:.6g} N/m: the equilibrium lies outside the robot's workspace "
                                f"(penetration f_d/k_e = {ctl.f_d / k_e:.3g} m)")
        if not np.isfinite(residual):
            raise AnalysisError(f"k_e = {k_e:.6g} N/m: no fixed point found at path time {self.t[i]:g} s "
                                "(the Newton iteration diverged)")
        A_full = np.array(self._jac(s_eq, u))
        d = self.dynamic
        A = A_full[np.ix_(d, d)]
        rho = float(np.max(np.abs(np.linalg.eigvals(A))))
        names = tuple(f"{name}[{j}]" if sl.stop - sl.start > 1 else name
                      for name, sl in L.slices.items() if name not in _BOOKKEEPING
                      for j in range(sl.stop - sl.start))
        if self.law.states:
            names = names[:-len(self.law.states)] + tuple(self.law.states)
        f_eq = float(self._f(s_eq, u)[1])
        return WholeLoop(float(k_e), ctl.Ts, float(self.t[i]), s_eq, f_eq, A, names, rho, residual, m_p)

    def _held(self, s, u):
        """``s`` with the mid-period hold's state (if the loop has one) at its
        value there: the last torque is the one computed at ``s`` (the
        extrapolation is bilinear in it and the flag; Newton from a flag of 0
        found a fixed point off the surface)."""
        L = self.layout
        if L["held"].stop > L["held"].start:
            s = s.copy()
            s[L["held"]] = 1.0
            s[L["tau_prev"]] = np.ravel(np.array(self._f(s, u)[0]))[L["tau_prev"]]
        return s

    def _newton(self, s, u, iters=30, tol=1e-11):
        d = self.dynamic
        eye = np.eye(d.size)
        for _ in range(iters):
            r = (np.ravel(np.array(self._f(s, u)[0])) - s)[d]
            if not np.all(np.isfinite(r)):
                break
            if np.max(np.abs(r) / (1.0 + np.abs(s[d]))) < tol:
                break
            J = np.array(self._jac(s, u))[np.ix_(d, d)] - eye
            s = s.copy()
            s[d] += np.linalg.lstsq(J, -r, rcond=None)[0]
        r = (np.ravel(np.array(self._f(s, u)[0])) - s)[d]
        return s, float(np.max(np.abs(r)))


def whole_loop(scenario, k_e: float, path_time: float = 0.0) -> WholeLoop:
    """:meth:`WholeLoopModel.at` for one stiffness and path point."""
    return WholeLoopModel(scenario).at(k_e, path_time)


def whole_loop_limit(scenario, points: int = 8, rtol: float = 1e-4, model: WholeLoopModel | None = None,
                     guess: float | None = None, k_lo: float = 10.0, k_hi: float = 1e9,
                     within: float | None = None) -> tuple[float, list[tuple[float, float]]]:
    """Largest k_e (N/m) for which the linearised whole loop is stable at
    every one of ``points`` equally spaced path points. Per point: bracket
    the first unstable stiffness (around ``guess``, e.g. the 1-D limit, when
    that brackets it, else on a log grid from ``k_lo`` to ``k_hi``:
    ``stability.sampled.largest_stable``, the upper edge of the stable band
    that contains ``within``, the scenario's smallest stiffness), then
    bisect to ``rtol``. Returns the smallest limit and the list of
    (path_time, limit); a point stable up to ``k_hi`` gives ``inf``, one
    unstable at ``within`` and below it 0."""
    mdl = model or WholeLoopModel(scenario)
    period = mdl.scenario.trajectory.period
    limits = []
    for j in range(points):
        tp = j * period / points
        stable = lambda ke: mdl.at(ke, tp).spectral_radius < 1.0
        lo = hi = None
        if guess is not None and np.isfinite(guess) and guess > 0 and stable(guess / 1.25) \
                and not stable(guess * 1.25):
            lo, hi = guess / 1.25, guess * 1.25
        else:
            try:
                limits.append((tp, largest_stable(stable, k_lo, k_hi, rtol, points=19, within=within)))
            except AnalysisError:
                if within is None or k_lo >= within:
                    raise
                # a soft surface below the scenario's smallest stiffness put the equilibrium beyond the
                # workspace or a curved part's axis: the band is searched from that stiffness up
                limits.append((tp, largest_stable(stable, within, k_hi, rtol, points=19, within=within)))
            continue
        while hi / lo > 1 + rtol:
            mid = math.sqrt(lo * hi)
            lo, hi = (mid, hi) if stable(mid) else (lo, mid)
        limits.append((tp, float(lo)))
    return min(l for _, l in limits), limits
