"""Stability along the moving path: the monodromy matrix of the sampled loop (beyond the paper).

``stability.wholeloop`` freezes the path at one point and linearises the
compiled closed-loop step there; the smallest limit over the path is a
conservative bound, since the simulated loop averages the growth at some
points of the circle against the decay at others. This module linearises
the loop *as it runs*: at a constant stiffness k_e the closed loop of the
scenario's arm (the full robot of eq. (1), the controller's model of eq.
(5), the inner loop of eq. (6), the force filter, the law's update, the
computation delay; ``simulation.closedloop.build_step``, the one loop of
every arm) driven by the circle is periodic
with the path's period ``N = period / Ts`` samples. Its steady periodic
orbit ``s_0, s_1, ..., s_N = s_0`` is found by Newton shooting on the
one-period map, and the product of the per-sample Jacobians along the orbit

    Phi = A_(N-1) ... A_1 A_0,     A_j = d step / d s  at s_j

is the monodromy matrix (Floquet theory): the orbit is locally stable iff
its spectral radius is below 1 (for a path standing still, ``Phi = A^N``).
:func:`periodic_search` (and :func:`periodic_limit`, its stiffness) finds
the stiffness where that radius crosses 1 by a bracketing root search
(``scipy.optimize.brentq`` on log k_e), or where first the orbit's transient
growth (how far a perturbation grows within the period before it decays,
from the same rollouts) reaches :data:`GROWTH_BOUND`, or the orbit is lost:
where the frozen loop is unstable on part of the path the radius can stay
far below 1 while a perturbation grows a billionfold there, and the loop as
run leaves its orbit (docs/theory.md, "Transient growth").

The Jacobians are exact (CasADi's forward mode, ``casadi.jtimes``) and
multiplied along the rollout itself: the tangent-linear step
``(s, v) -> (step(s), A(s) v)`` (``simulation.closedloop.build_tangent``:
the controller's side and the plant's right-hand side each carry their own
directional derivative, the Runge-Kutta stages call the plant's) is
compiled once per loop structure (3,880 operations of generated C on the
PUMA, 14,718 on the UR5, 27,372 on the Panda; docs/speed.md gives the
compile times: the Panda's 4.75 s at -O1, where the derivative of the whole
fused step took 13.2 s on the same machine), and one rollout of one
period from ``(s_0, e_j)`` gives the orbit's end point and the monodromy's
column j, so a period costs one rollout per dynamic state (16 on the UR5,
18 on the Panda, without delay).
The step is built without the
contact-switch refinement; along an orbit in permanent contact (checked:
the force stays > 0) it is the simulated step. The controller's bookkeeping
states (approach phase and command, f_d ramp, surface estimate) are
constants in contact and are left out, as in ``stability.wholeloop``; a
scheduled damping (``controller.damping_schedule``) is a dynamic state.
On a 6-D arm the dynamic state is the n joints' q and dq, the force filter,
the damping, the delay queue and the law's state.
Units are SI.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .continuous import AnalysisError
from .wholeloop import _BOOKKEEPING

__all__ = ["PeriodicLoop", "PeriodicModel", "PeriodicLimit", "GROWTH_BOUND", "periodic_loop", "periodic_limit",
           "periodic_search"]


_BUILT: dict = {}
"""Tangent-linear steps (Rollouts) per closed-loop structure."""


@dataclass(frozen=True, eq=False)
class PeriodicLoop:
    """The loop linearised along its steady periodic orbit at one stiffness.

    ``k_e`` (N/m), ``Ts`` (s), ``samples`` per path period, ``s_orbit`` the
    closed-loop state at the start of the period (path time 0) on the
    orbit, ``monodromy`` the product of the per-sample Jacobians over one
    period (dynamic states ``states``), ``spectral_radius`` its largest
    eigenvalue magnitude (< 1: the orbit is locally stable),
    ``per_sample_radius`` = spectral_radius ** (1/samples) (comparable with
    a frozen point's radius), ``residual`` max |s_N - s_0|/(1 + |s_0|) on
    the dynamic states, ``force_range`` the (min, max) contact force along the orbit
    (N), ``newton_iterations`` the shooting iterations used and
    ``transient_growth`` the largest amplification of a perturbation within a
    period: max of ||Phi(t, s)||_2 over starts s every :data:`GROWTH_CHUNK`
    samples and ends t up to one period later (Phi(t, s) the product of the
    per-sample Jacobians from s to t), in balanced coordinates (unit-free, see
    :func:`_window_growth`; each strongly connected group of states on its
    own, the largest group's figure), divided by the largest one-step norm: 1
    when a perturbation only decays after its first step; NaN when not computed
    (``at(growth="if stable")`` on an orbit whose radius is >= 1). The
    spectral radius can be far below 1 while this is huge: the orbit is then
    stable only against perturbations too small to matter
    (:func:`periodic_limit`, :data:`GROWTH_BOUND`)."""
    k_e: float
    Ts: float
    samples: int
    s_orbit: np.ndarray
    monodromy: np.ndarray
    states: tuple[str, ...]
    spectral_radius: float
    residual: float
    force_range: tuple[float, float]
    newton_iterations: int
    transient_growth: float = 1.0

    @property
    def stable(self) -> bool:
        return self.spectral_radius < 1.0

    @property
    def per_sample_radius(self) -> float:
        return self.spectral_radius ** (1.0 / self.samples)


class PeriodicModel:
    """The scenario's tangent-linear step, its one-period inputs and the frozen
    loop (for a starting orbit), built once; :meth:`at` for a stiffness.

    ``compile``: as :class:`~tmtcontrol.simulation.simulator.Simulator`
    (``"auto"``: a cached library is used, else the rollout runs on CasADi's
    virtual machine until enough steps have run to pay for compiling)."""

    def __init__(self, scenario, compile: bool | str = "auto"):
        from ..simulation.rollout import Rollout
        from ..simulation.simulator import structure_key
        from .wholeloop import WholeLoopModel, dynamic_states

        self.frozen = WholeLoopModel(scenario)
        sc = self.scenario = self.frozen.scenario
        loop = self.frozen.loop
        Ts, period = sc.controller.Ts, sc.trajectory.period
        N = int(round(period / Ts))
        if N < 1 or abs(N * Ts - period) > 1e-9 * period:
            raise AnalysisError(f"trajectory.period: {period:g} s is not a whole number of control periods "
                                f"({Ts:g} s); the loop is not periodic")
        self.samples = N
        self.layout = loop.layout
        self.dynamic = dynamic_states(self.layout)
        self.states = self._names()
        key = structure_key(sc, loop.law)
        # (s; v) -> (step(s); A(s) v) with log f_e: the orbit and one column of the monodromy in one rollout
        make = lambda: loop.build_tangent(self.dynamic)
        if key is None:                  # not the package's own law: keyed by its serialisation
            self.rollout = Rollout(make(), compile=compile, chunk=GROWTH_CHUNK)
        else:
            memo = (key, compile)        # a virtual-machine rollout (compile=False) never serves "auto" or True
            if memo not in _BUILT:
                if len(_BUILT) >= 16:
                    _BUILT.clear()
                _BUILT[memo] = Rollout(make, compile=compile, chunk=GROWTH_CHUNK, structure=(f"tangent_{loop.name}",
                                                                         key + "|tangent-pieces" + loop.cache_tag))
            self.rollout = _BUILT[memo]
        U, self.P = self.frozen.U, self.frozen.P
        self.U = np.array(U[:, :N], dtype=float)           # the frozen model's inputs span a period at least
        self._warm: tuple[float, np.ndarray] | None = None

    def _names(self) -> tuple[str, ...]:
        L, law = self.layout, self.frozen.law
        names = []
        for name, sl in L.slices.items():
            if name in _BOOKKEEPING:
                continue
            n = sl.stop - sl.start
            if name == "law":
                names += list(law.states)
            else:
                names += [f"{name}[{j}]" if n > 1 else name for j in range(n)]
        return tuple(names)

    def _inputs(self, k_e: float) -> np.ndarray:
        from ..simulation.closedloop import INPUT

        U = self.U.copy()
        U[INPUT["k_e"]] = k_e
        U[INPUT["noise"]] = 0.0
        return U

    def _start(self, k_e: float) -> np.ndarray:
        """A first state on (near) the orbit: the previous orbit for a nearby
        stiffness, else the frozen loop's fixed point at path time 0 moving
        with the circle."""
        from .wholeloop import equilibrium_damping

        if self._warm is not None and abs(math.log(k_e / self._warm[0])) < 0.2:
            s = self._warm[1].copy()
            # a scheduled damping far from its fixed point is rate-limited: no derivative to follow
            s[self.layout["b_n"]] = equilibrium_damping(self.scenario, k_e)
            return s

        sc, L, loop = self.scenario, self.layout, self.frozen.loop
        s = self.frozen.at(k_e, 0.0).s_eq.copy()
        from ..simulation.geometry import surface_of

        X = np.r_[0.0, self.U[0:2, 0]]                    # the path's start, moving along it
        s[L["dq"]] = loop.joint_rates(s[L["q"]], *surface_of(sc).rates(X, np.r_[0.0, self.U[2:4, 0]]))
        return s

    def _period(self, s: np.ndarray, U: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, list]:
        """One period from ``s``: the end state, the monodromy (one tangent
        rollout per column; compiled rollouts two at a time in threads,
        ``processes.threads_for_side_by_side``), the contact force along
        the period (N) and the states along it (after each sample)."""
        from ..processes import threads_for_side_by_side

        ns, nd = self.layout.size, self.dynamic.size
        run = lambda j: self.rollout.run(np.r_[s, np.eye(1, nd, j).ravel()], U, self.P)
        with np.errstate(all="ignore"):
            first = run(0)                  # on the virtual machine until compiled (rollout's "auto")
            threads = threads_for_side_by_side() if self.rollout.how != "vm" else 1
            if threads > 1 and nd > 1:
                from concurrent.futures import ThreadPoolExecutor

                with ThreadPoolExecutor(threads) as pool:
                    rest = list(pool.map(run, range(1, nd)))
            else:
                rest = [run(j) for j in range(1, nd)]
        Phi = np.column_stack([S[ns:, -1] for S, _ in (first, *rest)])
        S, F = first
        return S[:ns, -1], Phi, F, S[:ns]

    def at(self, k_e: float, iters: int = 12, tol: float = 1e-10, growth: str = "always") -> PeriodicLoop:
        """The loop at constant stiffness ``k_e`` (N/m) linearised along its
        periodic orbit (Newton shooting to ``tol``, relative).

        Single shooting fails where the loop is locally unstable on part of
        the path (a curved part's largest normal mass above the frozen
        limit): a deviation grows there by orders of magnitude before the
        rest of the period damps it, so the period map is far from linear a
        short way off the orbit and Newton stalls although the orbit
        attracts. Then the orbit is found as the simulator finds it: up to
        :data:`RELAX_PERIODS` periods run from the start until they repeat,
        and Newton again from there.

        ``growth``: ``"always"`` computes the transient growth (one more period
        of tangent rollouts), ``"if stable"`` only where the spectral radius is
        below 1 (else NaN: the orbit is unstable whatever it is)."""
        if growth not in ("always", "if stable"):
            raise AnalysisError(f"growth: expected 'always' or 'if stable', got {growth!r}")
        if not (np.isfinite(k_e) and k_e > 0):
            raise AnalysisError(f"k_e: must be > 0, got {k_e!r}")
        if not (isinstance(iters, int) and iters >= 1):
            raise AnalysisError(f"iters: must be a whole number >= 1, got {iters!r}")
        if not (np.isfinite(tol) and tol > 0):
            raise AnalysisError(f"tol: must be finite and > 0, got {tol!r}")
        U = self._inputs(float(k_e))
        start = self._start(float(k_e))
        s, Phi, F, residual, it, states = self._shoot(start, U, iters, tol)
        if residual > 1e-5:
            relaxed = self._relax(start, U, tol)
            if relaxed is not None:
                s, Phi, F, residual, more, states = self._shoot(relaxed, U, iters, tol)
                it += more
        f = np.ravel(F)
        if residual == math.inf:
            raise AnalysisError(f"k_e = {k_e:.6g} N/m: no periodic orbit found (the shooting diverged)")
        if residual > 1e-5:
            raise AnalysisError(f"k_e = {k_e:.6g} N/m: the periodic orbit did not converge "
                                f"(residual {residual:.3g} after {it} Newton steps)")
        if not f.min() > 0.0:
            raise AnalysisError(f"k_e = {k_e:.6g} N/m: the periodic orbit leaves the surface (force "
                                f"{f.min():.3g} N); the linearisation in contact does not apply")
        self._warm = (float(k_e), s.copy())
        rho = float(np.max(np.abs(np.linalg.eigvals(Phi))))
        return PeriodicLoop(float(k_e), self.scenario.controller.Ts, self.samples, s, Phi, self.states, rho,
                            residual, (float(f.min()), float(f.max())), it,
                            self._growth(s, states, U) if growth == "always" or rho < 1.0 else math.nan)

    def _growth(self, s: np.ndarray, states: np.ndarray, U: np.ndarray) -> float:
        """:attr:`PeriodicLoop.transient_growth` of the orbit from ``s``
        (``states`` after each sample): the tangent step restarted from the
        identity at every :data:`GROWTH_CHUNK`-th sample gives each piece's
        transition matrices Phi(b + tau, b) (one more period of tangent
        rollouts, in pieces), and :func:`_window_growth` multiplies them out."""
        from ..processes import threads_for_side_by_side

        ns, nd, N = self.layout.size, self.dynamic.size, self.samples
        eye = np.eye(nd)

        def piece(b):
            x = s if b == 0 else states[:, b - 1]
            Ub = U[:, b:b + GROWTH_CHUNK]
            cols = [self.rollout.run(np.r_[x, eye[j]], Ub, self.P)[0][ns:] for j in range(nd)]
            return np.moveaxis(np.stack(cols, axis=1), 2, 0)          # (sample, state, column)

        with np.errstate(all="ignore"):
            starts = range(0, N, GROWTH_CHUNK)
            threads = threads_for_side_by_side() if self.rollout.how != "vm" else 1
            if threads > 1 and len(starts) > 1:
                from concurrent.futures import ThreadPoolExecutor

                with ThreadPoolExecutor(threads) as pool:
                    pieces = list(pool.map(piece, starts))
            else:
                pieces = [piece(b) for b in starts]
        return _window_growth(pieces)

    def _shoot(self, s: np.ndarray, U: np.ndarray, iters: int, tol: float):
        """Newton shooting on one period from ``s``: (the orbit's start, the
        monodromy, the force along the period, the residual, iterations, the
        states along the period), all of one iterate: the last one run, also
        when ``iters`` run out."""
        d, eye = self.dynamic, np.eye(self.dynamic.size)
        residual, it, previous = math.inf, 0, math.inf
        for it in range(1, iters + 1):
            end, Phi, F, states = self._period(s, U)
            if not (np.all(np.isfinite(end)) and np.all(np.isfinite(Phi))):
                return s, Phi, F, math.inf, it, states       # diverged
            r = (end - s)[d]
            residual = float(np.max(np.abs(r) / (1.0 + np.abs(s[d]))))
            # converged, or stalled at the rounding of one period's arithmetic (f = k_e x: ~1e-6 relative at 2.6e6 N/m)
            if residual < tol or (it > 2 and residual > 0.5 * previous) or it == iters:
                break                    # (out of steps: s is the iterate the residual and Phi belong to)
            previous = residual
            s = s.copy()
            s[d] += np.linalg.lstsq(Phi - eye, -r, rcond=None)[0]
        return s, Phi, F, residual, it, states

    def _relax(self, s: np.ndarray, U: np.ndarray, tol: float) -> np.ndarray | None:
        """The state at the start of the period after running periods of the
        nonlinear loop from ``s`` until two successive ones agree to 100
        ``tol`` (relative), within :data:`RELAX_PERIODS`; None if they do not,
        or if after 10 periods the difference has not shrunk a thousandfold
        (no attracting orbit: a limit cycle, a drift, a divergence)."""
        d, ns, zeros = self.dynamic, self.layout.size, np.zeros(self.dynamic.size)
        first = None
        for n in range(1, RELAX_PERIODS + 1):
            with np.errstate(all="ignore"):
                S, _ = self.rollout.run(np.r_[s, zeros], U, self.P)
            end = S[:ns, -1]
            if not np.all(np.isfinite(end)):
                return None
            residual = float(np.max(np.abs(end - s)[d] / (1.0 + np.abs(s[d]))))
            s = end
            first = residual if first is None else first
            if residual < 100 * tol:
                return s
            if n >= 10 and residual > 1e-3 * first:
                return None
        return None


GROWTH_CHUNK = 50
"""Samples between the window starts of :attr:`PeriodicLoop.transient_growth`
(and the tangent rollout's compiled chunk, so that a piece runs no more)."""


def _balancing(A: np.ndarray, rtol: float = 1e-10) -> np.ndarray:
    """The diagonal d that balances the nonnegative matrix ``A``: in D^-1 A D
    every state's off-diagonal row and column have equal 2-norms. That d
    minimises sum_(i != j) (A_ij d_j / d_i)^2, a convex function of log d
    (Osborne's condition is its gradient), found here by Newton steps on log d
    (its Hessian a weighted graph Laplacian; least squares for its null
    space, the common scale) with a backtracking line search, to ``rtol``
    relative between each row and column. Not ``scipy.linalg.matrix_balance``:
    LAPACK rounds the scales to powers of 2 and stops early, so a state's unit
    moved the balanced figure up to 11-fold (a made-up 6-state case); the
    minimiser is covariant (scaling state i by u multiplies d_i by u), so
    D^-1 A D does not depend on the units. It exists where every state reaches
    every other through A's nonzero entries (one strongly connected group:
    :func:`_window_growth` balances each group on its own)."""
    W = np.array(A, dtype=float)
    top = np.abs(W).max(initial=0.0)
    W = (W / top if np.isfinite(top) and top > 0 else W) ** 2   # d does not depend on A's scale; no overflow
    np.fill_diagonal(W, 0.0)
    x = np.zeros(W.shape[0])

    def parts(x):
        m = W * np.exp(2.0 * (x[None, :] - x[:, None]))          # squared entries of D^-1 A D
        return m, m.sum(axis=0), m.sum(axis=1)                   # columns, rows

    m, col, row = parts(x)
    for _ in range(200):
        scale = col + row
        coupled = scale > 0
        if not np.any(coupled) or np.max(np.abs(col - row)[coupled] / scale[coupled]) < rtol:
            break
        H = 4.0 * (np.diag(scale) - m - m.T)
        step = np.linalg.lstsq(H, -2.0 * (col - row), rcond=None)[0]
        f, t = m.sum(), 1.0
        while t > 1e-12:
            m_new, col_new, row_new = parts(x + t * step)
            if m_new.sum() <= f:
                break
            t *= 0.5
        x = x + t * step
        m, col, row = m_new, col_new, row_new
    return np.exp(x)


def _window_growth(pieces: list) -> float:
    """The transient growth from the transition matrices of consecutive pieces
    of one period (``pieces[j][tau - 1]`` = Phi(b_j + tau, b_j)): the largest
    ||Phi(t, b_j)||_2 over every start b_j and every t up to one period later
    (wrapping round the period), in balanced coordinates, divided by the
    largest one-step norm at the starts, for each strongly connected group of
    states (the largest figure over the groups, at least 1). The
    coordinates: D^-1 X D with D
    balancing the mean |one-step Jacobian| over the starts
    (:func:`_balancing`), so the figure does not depend on the states' units
    (N or kN, rad or mrad; review 38: 7,244 in SI, 11,345 with the filter in
    kN, unbalanced). Exact over those starts: the 2-norm is taken wherever
    the Frobenius norms (an upper bound) do not rule a window out; a start
    between two of them can see more, by at most the growth from it to the
    next start, and the groups come from the starts' Jacobians only (review
    39; docs/theory.md)."""
    from scipy.sparse.csgraph import connected_components

    if not all(np.all(np.isfinite(p)) for p in pieces):     # a NaN, or a piece's product overflowed
        return math.inf
    A = np.array([p[0] for p in pieces])
    mean = np.abs(A).mean(axis=0)
    # one-way couplings between groups of states have no unit-free size (balancing would shrink them without
    # end): each strongly connected group's own transition, Phi's diagonal block (the products' diagonal
    # blocks are the blocks' products, the groups ordered triangularly), balanced on its own
    count, group = connected_components(mean != 0, directed=True, connection="strong")
    growth = 1.0
    for g in range(count):
        keep = np.flatnonzero(group == g)
        block = np.ix_(keep, keep)
        growth = max(growth, _group_growth([p[(slice(None), *block)] for p in pieces], mean[block]))
    return growth


def _group_growth(pieces: list, mean: np.ndarray) -> float:
    """:func:`_window_growth` for one strongly connected group of states."""
    M, nd = len(pieces), pieces[0].shape[1]
    scale = _balancing(mean)
    ratio = scale[None, :] / scale[:, None]                         # D^-1 X D, elementwise
    pieces = [p * ratio for p in pieces]
    one = max(np.linalg.norm(p[0], 2) for p in pieces)
    if not one > 0:                 # a group the step overwrites (a held value): nothing of it carries on
        return 1.0
    ends = np.array([p[-1] for p in pieces])
    bound = np.array([np.sqrt(np.einsum("tij,tij->t", p, p)).max() for p in pieces])   # >= each ||Phi(., b_m)||_2
    best = one
    P = np.broadcast_to(np.eye(nd), (M, nd, nd)).copy()            # P[j] = Phi(b_(j+i), b_j)
    starts = np.arange(M)
    with np.errstate(all="ignore"):
        for i in range(M):
            m = (starts + i) % M
            reach = bound[m] * np.sqrt(np.einsum("jab,jab->j", P, P))  # ||C P||_2 <= ||C||_F ||P||_F
            for j in np.flatnonzero(~(reach <= best)):
                if reach[j] <= best:
                    continue
                W = pieces[m[j]] @ P[j]
                columns, rows = np.einsum("tij,tij->tj", W, W), np.einsum("tij,tij->ti", W, W)
                if not np.all(np.isfinite(columns)):
                    return math.inf
                # the largest column or row norm is at most the 2-norm: it raises the bar before any SVD
                best = max(best, float(np.sqrt(max(columns.max(), rows.max()))))
                left = W[np.sqrt(columns.sum(axis=1)) > best]      # the Frobenius norm rules out the rest
                if len(left):
                    best = max(best, float(np.linalg.norm(left, 2, axis=(1, 2)).max()))
            P = ends[m] @ P
    return float(best / one)


RELAX_PERIODS = 40
"""Periods the orbit's search runs the loop for when Newton shooting alone
fails (:meth:`PeriodicModel.at`)."""


def periodic_loop(scenario, k_e: float) -> PeriodicLoop:
    """:meth:`PeriodicModel.at` for one stiffness."""
    return PeriodicModel(scenario).at(k_e)


GROWTH_BOUND = 1e5
"""The largest transient growth (:attr:`PeriodicLoop.transient_growth`) the
periodic limit accepts. Where a perturbation grows this much within a period
the spectral radius says nothing useful: the orbit attracts only
perturbations too small to meet (a sensor's noise, a model's error, the
rounding of a run), and the simulated loop leaves it. Calibrated on measured
cases, not derived: at their limits the bundled scenarios' growth is at most
1.8e4 (the paper with the scheduled damping, an orbit-loss edge that a
simulated bisection confirms), the ``ur5-pipe``'s 3.4e3 and the rest below
50; on review 37's 4-joint arm, whose orbit keeps a spectral radius of 0.03
up to where it is lost (7.3e5-7.6e5 N/m), it is 1.5e3 at 4.5e5 N/m, 5.4e6 at
6e5 and 2.8e7 at 6.3e5, and constant-k_e runs hold the 10 mN tolerance up
to 6.2e5 N/m and miss it from 6.4e5 (review 38; the same arm along a line:
1.2e7 at 8.2e5 N/m, runs missing from 8.5e5-9e5). The bound puts that arm's
limits 15-25 % inside its simulated ones (docs/theory.md)."""


@dataclass(frozen=True)
class PeriodicLimit:
    """Where :func:`periodic_search` ends: ``k_e`` (N/m), ``set_by`` what
    ends it (``"spectral radius"``: the monodromy's crosses 1 (Floquet);
    ``"transient growth"``: a perturbation grows more than
    :data:`GROWTH_BOUND`-fold within a period above it; ``"orbit lost"``:
    no periodic orbit in contact above it), and the ``spectral_radius`` and
    ``transient_growth`` of the largest stable stiffness evaluated (within
    the search's ``xtol`` of ``k_e``)."""
    k_e: float
    set_by: str
    spectral_radius: float
    transient_growth: float


def periodic_search(scenario, model: PeriodicModel | None = None, bracket: tuple[float, float] | None = None,
                    xtol: float = 1e-5, growth_bound: float = GROWTH_BOUND) -> PeriodicLimit:
    """The largest constant k_e (N/m) for which the loop's periodic orbit is
    locally stable with a bounded transient: the sign change of ``log rho``
    where the growth is below ``growth_bound``, else of
    ``max(log rho, log(growth / growth_bound))`` (>= 0), in log k_e (rho the
    monodromy's spectral radius, growth :attr:`PeriodicLoop.transient_growth`;
    ``scipy.optimize.brentq``, ``xtol`` in log k_e, i.e. relative; a bracketing
    search, so the jump where the growth reaches the bound ends it as an
    orbit's loss does); ``growth_bound = inf`` is the Floquet limit alone (up
    to where the orbit is lost).

    ``bracket`` (N/m): a stable and an unstable stiffness; by default the
    frozen loop's smallest and largest limits over the path
    (``stability.wholeloop.whole_loop_limit``), widened until they bracket.
    A stiffness whose orbit cannot be found or leaves the surface counts as
    unstable."""
    from scipy.optimize import brentq

    if not growth_bound > 1.0:
        raise AnalysisError(f"growth_bound: must be > 1, got {growth_bound!r}")
    mdl = model or PeriodicModel(scenario)

    seen: dict = {}

    def g(log_k):       # remembered: brentq evaluates the bracket's ends again (the orbit's Newton is warm-started)
        if log_k not in seen:
            try:
                w = mdl.at(math.exp(log_k), growth="if stable")
                rho, growth = w.spectral_radius, w.transient_growth
                log_rho = math.log(rho) if rho > 0 else -math.inf
                # below the bound (or not computed: the radius >= 1) the radius alone (the Floquet search's own
                # path and root, to the last digit, wherever the growth never reaches the bound); at or above
                # it >= 0: unstable
                seen[log_k] = (max(log_rho, math.log(growth / growth_bound)) if growth >= growth_bound
                               else log_rho, rho, growth)
            except AnalysisError:
                seen[log_k] = (1.0, None, None)
        return seen[log_k][0]

    if bracket is None:
        from .onedim import scenario_parameters, scenario_stiffness_limit
        from .wholeloop import whole_loop_limit

        # the 1-D limit as the frozen search's guess (its log grid would start at 10 N/m, 1 m deep), and the
        # band that holds the scenario's smallest stiffness, as the deciding limit's (review 36: on the pipe
        # with a 2-sample delay the guess did not bracket and the grid's 10 N/m left the workspace)
        lo_lim, per_point = whole_loop_limit(mdl.scenario, points=8, rtol=1e-3, model=mdl.frozen,
                                             guess=scenario_stiffness_limit(mdl.scenario),
                                             within=scenario_parameters(mdl.scenario)["k_e_min"])
        hi_lim = max(l for _, l in per_point)
        if not (np.isfinite(lo_lim) and lo_lim > 0):
            raise AnalysisError("the frozen loop has no finite stiffness limit to start the periodic search from")
        bracket = (lo_lim / 1.02, hi_lim * 1.02)
    lo, hi = (math.log(float(v)) for v in bracket)
    g_lo, g_hi = g(lo), g(hi)
    for widened in range(9):         # widen (8 times at most) until the bracket holds
        if g_lo < 0 < g_hi:
            break
        if widened == 8:             # review 40: the eighth widening's bracket is tested too
            a, b = math.exp(lo), math.exp(hi)
            raise AnalysisError(f"no stability boundary found between {a:.4g} and {b:.4g} N/m (at {a:.4g} N/m "
                                f"{_state(seen[lo], growth_bound)}; at {b:.4g} N/m {_state(seen[hi], growth_bound)})")
        if g_lo >= 0:
            lo, g_lo = lo - 0.1, g(lo - 0.1)
        if g_hi <= 0:
            hi, g_hi = hi + 0.1, g(hi + 0.1)
    root = brentq(g, lo, hi, xtol=xtol)
    stable = max((k for k, v in seen.items() if v[0] < 0 and k <= root), default=lo)
    above = min((k for k, v in seen.items() if v[0] >= 0 and k >= root), default=hi)
    _, rho, growth = seen[stable]
    rho_above = seen[above][1]
    set_by = ("orbit lost" if rho_above is None else
              "spectral radius" if rho_above >= 1.0 else "transient growth")
    return PeriodicLimit(float(math.exp(root)), set_by, rho, growth)


def _state(value: tuple, growth_bound: float) -> str:
    """What :func:`periodic_search` found at one stiffness, in words (its
    failure message names both ends of the bracket: review 40)."""
    _, rho, growth = value
    if rho is None:
        return "no periodic orbit in contact was found"
    if rho >= 1.0:
        return f"the orbit is unstable (spectral radius {rho:.3g})"
    if growth >= growth_bound:
        return (f"the transient growth {growth:.3g} is at or above the bound {growth_bound:.3g} (spectral radius "
                f"{rho:.3g})")
    return f"the orbit is stable (spectral radius {rho:.3g}, transient growth {growth:.3g})"


def periodic_limit(scenario, model: PeriodicModel | None = None, bracket: tuple[float, float] | None = None,
                   xtol: float = 1e-5) -> float:
    """:func:`periodic_search`'s stiffness (N/m)."""
    return periodic_search(scenario, model, bracket, xtol).k_e
