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
(CasADi, exact: on its virtual machine, or, where the deciding limit has
compiled the periodic analysis's tangent-linear step, that step's columns,
``WholeLoopModel.tangent``) and its spectral radius decide local stability
of the sampled loop at that point. The state is the joints q, dq (n each), the
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
from ..simulation.environment import belief_after_approach, has_approach, surface_error

__all__ = ["WholeLoop", "WholeLoopModel", "on_the_surface", "whole_loop", "whole_loop_limit", "equilibrium_damping"]

_BOOKKEEPING = ("approach", "x_app", "ramp", "x_e_hat")

_BUILT: dict = {}
"""Symbolic step and Jacobian per closed-loop structure (numbers are inputs)."""


def _build(sc):
    """The step of ``sc``'s structure as ``(s, [u; p]) -> (s_next, f_e, tau)`` and its
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
    f = ca.Function("whole_step", [s, up], [s_next, log[loop.f_e], log[loop.log["tau"]]], ["s", "up"],
                    ["s_next", "f_e", "tau"])
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


@dataclass(frozen=True, eq=False)
class WholeLoop:
    """The linearised sampled loop at one path point and stiffness.

    ``path_time`` (s) locates the point on the circle; ``s_eq`` is the fixed
    point of the step (the closed-loop state), ``f_eq`` the contact force
    there (N), ``A`` the Jacobian over the dynamic states ``states``,
    ``spectral_radius`` its largest eigenvalue magnitude (< 1: locally
    stable), ``residual`` max |step(s_eq) - s_eq|, ``m_p`` the robot's
    effective normal mass at the point (kg), ``tau`` the torque applied
    from ``s_eq`` (N m) and ``clipped`` the joints (1-based) whose torque
    sits on the drive's clip there (``robot.saturate``): the loop has no
    input on them, and the force ``f_eq`` is what the clipped torque holds,
    not f_d."""
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
    clipped: tuple[int, ...] = ()
    tau: np.ndarray | None = None

    @property
    def stable(self) -> bool:
        return self.spectral_radius < 1.0


class NoFixedPoint(AnalysisError):
    """No equilibrium at a stiffness and path point from any start, the loop
    itself run toward it for :data:`RELAX_SECONDS` among them."""


RELAX_SECONDS = 1.0
"""How long the frozen loop runs toward its equilibrium before the damped
Newton of the last guess (:meth:`WholeLoopModel.at`), s."""


def on_the_surface(sc):
    """The scenario started on the surface, as the whole loop is analysed: without its guarded
    approach, and with the controller's surface belief as the approach leaves it (the surface found
    along the believed normal: the part offset's component along the normal where the approach meets
    the part gone, the estimate ``x_e_error`` plus the detection depth deep,
    :func:`~tmtcontrol.simulation.environment.approach_depth`).
    Review 26: the offset's normal part was kept, the PUMA-on-a-dome periodic limit 6 % low (150,666
    against 160,056 N/m, a simulated bisection 158k-163k) and a stable run called beyond_limit."""
    if has_approach(sc):
        x_e_error, offset = belief_after_approach(sc)   # along the normal where the approach met the part
        sc = sc.replace(controller={**sc.controller.model_dump(), "x_e_error": x_e_error,
                                    "part_offset": tuple(float(v) for v in offset)})
    return sc.replace(trajectory={**sc.trajectory.model_dump(), "approach_gap": 0.0})


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
        sc = on_the_surface(sc)
        self.scenario = sc
        key = structure(sc)
        if key not in _BUILT:
            if len(_BUILT) >= 16:
                _BUILT.clear()
            _BUILT[key] = _build(sc)
        self.loop, self.dynamic, self._f, self._jac = _BUILT[key]
        self.sim, self.layout, self.law = self.loop, self.loop.layout, self.loop.law
        self.path = self.loop.path(sc)
        # inputs over one period at least: a shorter run's would wrap a frozen point's path time back to the
        # run's start (review 56: at cycles = 0.5 the point at 3 s took 1 s's inputs, its limit 4.5 % high)
        whole = sc if sc.trajectory.cycles >= 1.0 else sc.replace(trajectory={**sc.trajectory.model_dump(),
                                                                              "cycles": 1.0})
        self.U, self.P, self.s0, self.t = self.loop.inputs(whole, self.path)
        self._warm: dict = {}
        self._found: dict = {}         # per path point: the fallback guess that found its last equilibrium
        from ..simulation.limits import limits_of

        self.torque_clip = limits_of(self.sim.plant, sc).torque_clip
        """The drive's clip per joint (N m; inf: none, ``robot.saturate`` off)."""
        self._clips: dict = {}         # (path index, k_e) -> the joints on the clip at the equilibrium found
        self.tangent = None
        """A compiled tangent-linear step of this loop on :func:`dynamic_states`
        (``simulation.closedloop.build_tangent``, a ``Rollout``; the periodic
        analysis's), set by a caller that has one: the Jacobians are then its
        columns, one compiled period each (~0.5 ms for the UR5's 17 where the
        virtual machine's Jacobian takes ~8 ms); the same derivative wherever
        the contact does not switch within the period (the tangent step has no
        contact refinement), at a fixed point in contact always."""

    def _index(self, path_time: float) -> int:
        """The control sample of the path's period nearest ``path_time`` (s)."""
        sc = self.scenario
        return int(round((path_time % sc.trajectory.period) / sc.controller.Ts)) % self.t.size

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
        i = self._index(path_time)
        u = np.r_[self._u(i, k_e), self.P]
        ctl = sc.controller
        from ..simulation.geometry import surface_of, under_the_commanded_path

        surface = surface_of(sc)
        # the tangential point and its joint angles on the surface (near the checked path's pose there)
        from ..simulation.trajectory import path_reference

        ref = path_reference(np.array([self.t[i]]), sc.trajectory)
        near = self.path.q[:, int(round((self.t[i] % period) / period * self.path.q.shape[1])) % self.path.q.shape[1]]
        on_surface = surface.to_base(under_the_commanded_path(sc, np.r_[0.0, ref.pos[:, 0]]))
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

        def kept():
            # the equilibrium found here for a nearby stiffness as it is (its tool off the path's point where a
            # model error moves it there; from_previous puts it back on the path's point)
            s = self._warm[i][0].copy()
            s[L["b_n"]] = equilibrium_damping(sc, k_e)
            return s

        def relaxed():
            # review 17: with the controller's model mass 20-30 % off, the UR5's equilibrium lies ~18 mm off the
            # path, too far for Newton from the 1-D guess: run the frozen loop from it toward its equilibrium
            # (where that is stable), then a damped Newton
            x = self._relax(self._held(from_1d(), u), u)
            if x is None:               # the run did not settle: no stable equilibrium attracts it from there
                raise ValueError("not settling")
            return x

        # every result before review 17 came from the first two starts; the others (with a damped Newton) are
        # tried only where those fail, the kept equilibrium first at a point whose last one a fallback found
        warm = i in self._warm
        guesses = ([("previous", lambda: from_previous(*self._warm[i]))] if warm else []) + [("1-D", from_1d)] \
            + ([("kept", kept)] if warm else []) + [("relaxed", relaxed)]
        if warm and self._found.get(i) == "fallback":
            guesses.insert(0, guesses.pop(2))                    # "kept"
        s_eq = None
        for name, guess in guesses:
            try:
                start = self._held(guess(), u)
            except ValueError:       # scaled from a far stiffness, the guess left the workspace (or did not settle)
                continue
            fallback = name in ("kept", "relaxed")
            s_eq, residual = self._newton(start, u, damped=fallback)
            if residual < 1e-8:
                self._warm[i] = (s_eq, float(k_e))
                self._found[i] = "fallback" if fallback else None
                break
        if s_eq is None:
            raise AnalysisError(f"k_e = {k_e:.6g} N/m: the equilibrium lies outside the robot's workspace "
                                f"(penetration f_d/k_e = {ctl.f_d / k_e:.3g} m)")
        relative = (float(np.max(np.abs(self._residual(s_eq, u)) / (1.0 + np.abs(s_eq[self.dynamic]))))
                    if np.isfinite(residual) else math.inf)
        if not relative < 1e-8:
            # review 17: a Newton that stopped short (residual 0.98 on the UR5 with a 30 % heavier model) gave the
            # spectral radius of a point that is no equilibrium, and the bisection used it as a verdict; relative
            # to the states (a force state of 10 N at 5e8 N/m rounds to ~1e-8 N)
            raise NoFixedPoint(f"k_e = {k_e:.6g} N/m: no fixed point found at path time {self.t[i]:g} s "
                               + ("(the Newton iteration diverged)" if not np.isfinite(residual) else
                                  f"(Newton's relative residual {relative:.2g} from every start)"))
        A = self._jacobian(s_eq, u)
        if not np.all(np.isfinite(A)):
            raise AnalysisError(f"k_e = {k_e:.6g} N/m: the loop's Jacobian at its fixed point (path time "
                                f"{self.t[i]:g} s) is not finite")
        rho = float(np.max(np.abs(np.linalg.eigvals(A))))
        names = tuple(f"{name}[{j}]" if sl.stop - sl.start > 1 else name
                      for name, sl in L.slices.items() if name not in _BOOKKEEPING
                      for j in range(sl.stop - sl.start))
        if self.law.states:
            names = names[:-len(self.law.states)] + tuple(self.law.states)
        _, f_eq, tau = self._f(s_eq, u)
        f_eq, tau = float(f_eq), np.ravel(np.array(tau))
        clipped = tuple(int(j) + 1 for j in np.flatnonzero(np.abs(tau) >= self.torque_clip * (1 - 1e-12)))
        if len(self._clips) > 100_000:
            self._clips.clear()
        self._clips[i, float(k_e)] = clipped
        return WholeLoop(float(k_e), ctl.Ts, float(self.t[i]), s_eq, f_eq, A, names, rho, residual, m_p, clipped,
                         tau)

    def clipped_at(self, k_e: float, path_time: float = 0.0) -> tuple[int, ...]:
        """:attr:`WholeLoop.clipped` of the equilibrium :meth:`at` found for
        this stiffness and path point, as it found it (a bisection's, from its
        warm starts: asked afresh, Newton may find none from the starts it has
        then); :meth:`at` again where it found none before."""
        found = self._clips.get((self._index(path_time), float(k_e)))
        return found if found is not None else self.at(k_e, path_time).clipped

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

    def _jacobian(self, s, u) -> np.ndarray:
        """``d step/d s`` at ``s`` on the dynamic states (``u``: inputs and
        parameters stacked): from the compiled tangent step when there is one
        (:attr:`tangent`), else CasADi's Jacobian on its virtual machine."""
        d = self.dynamic
        t = self.tangent
        if t is None or t.how == "vm":
            return np.array(self._jac(s, u))[np.ix_(d, d)]
        uu, p = u[:t.nu], u[t.nu:]
        eye = np.eye(d.size)
        return np.column_stack([t.once(np.r_[s, eye[j]], uu, p)[0][s.size:] for j in range(d.size)])

    def _residual(self, s, u) -> np.ndarray:
        return (np.ravel(np.array(self._f(s, u)[0])) - s)[self.dynamic]

    def _newton(self, s, u, iters=30, tol=1e-11, damped: bool = False):
        """Newton on the step's fixed point from ``s``: (the last iterate, its
        largest residual; inf where it left the finite numbers). ``damped``:
        each step halved until the residual's norm falls (at most 12 times),
        for a start that is near but not within Newton's basin."""
        d = self.dynamic
        eye = np.eye(d.size)
        for _ in range(iters):
            r = self._residual(s, u)
            if not np.all(np.isfinite(r)):
                break
            if np.max(np.abs(r) / (1.0 + np.abs(s[d]))) < tol:
                break
            J = self._jacobian(s, u) - eye
            if not np.all(np.isfinite(J)):       # review 17: lstsq's LAPACK error escaped as a crash of simulate
                return s, math.inf
            try:
                step = np.linalg.lstsq(J, -r, rcond=None)[0]
            except np.linalg.LinAlgError:
                return s, math.inf
            s = s.copy()
            if damped:
                # a finite residual whose square overflows has the norm inf: no better (review 54: the
                # overflow's RuntimeWarning was printed as a stray "warning:" line by analyze)
                with np.errstate(over="ignore"):
                    norm, base = float(np.linalg.norm(r)), s[d].copy()
                    for _ in range(12):
                        s[d] = base + step
                        r_new = self._residual(s, u)
                        if np.all(np.isfinite(r_new)) and float(np.linalg.norm(r_new)) < norm:
                            break
                        step = step / 2
            else:
                s[d] += step
        r = self._residual(s, u)
        return s, float(np.max(np.abs(r))) if np.all(np.isfinite(r)) else math.inf

    def _relax(self, s, u, seconds: float = RELAX_SECONDS):
        """``s`` after ``seconds`` of the loop frozen at this path point (its
        dynamic states stepped, the rest held), or None if the run leaves the
        finite numbers or is not settling: its last step moves the state more
        than a tenth of the step a tenth of the run before (a stable
        equilibrium's pull shrinks it; an unstable stiffness's grows)."""
        d = self.dynamic
        x = s.copy()
        steps = max(10, int(round(seconds / self.scenario.controller.Ts)))
        early = None
        for j in range(steps):
            nxt = np.ravel(np.array(self._f(x, u)[0]))
            if not np.all(np.isfinite(nxt[d])):
                return None
            move = float(np.max(np.abs(nxt[d] - x[d]) / (1.0 + np.abs(x[d]))))
            if j == steps // 10:
                early = move
            x[d] = nxt[d]
        return x if move <= 0.1 * early or move < 1e-12 else None


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
    unstable at ``within`` and below it 0. A stiffness without a fixed point
    (:class:`NoFixedPoint`: none from any start, the loop run toward it
    among them) counts as unstable."""
    mdl = model or WholeLoopModel(scenario)
    period = mdl.scenario.trajectory.period
    limits = []
    for j in range(points):
        tp = j * period / points
        def stable(ke):
            try:
                return mdl.at(ke, tp).spectral_radius < 1.0
            except NoFixedPoint:
                # a stable equilibrium attracts the loop run toward it from the 1-D guess (the last start): none
                # found from any start is no stable one (review 17: the radius of a point that was no
                # equilibrium was taken instead)
                return False
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
