"""Sampled-data model of the implemented normal-axis loop (beyond the paper).

The controller runs at Ts with zero-order hold. In the ideal case (exact
model, no friction) the normal axis of the implemented loop is, between
samples,

    x'' = U_k + (f_k - k_e x - d_e x')/m_p,     x_a'' = (f_k - b x_a' - k x_a)/m

with ``f_k`` the force measured at t_k (through the optional first-order
filter), ``U_k`` eq. (6) with the eq. (4) command and the TMT reference
linearised about its equilibrium (``dx_r = dx - df_m/k_e``), and ``m_p`` the
robot's effective Cartesian mass along the normal, ``1/(n^T D*^-1 n)``. Its
exact ZOH discretisation gives the discrete closed loop whose spectral radius
decides stability at Ts. :func:`stable_band` is the package's one search for
the band of k_e in which a loop is stable (with a stiff contact damper the
loop is also unstable on soft surfaces, below the band); the limit is the
band's upper edge. Units are SI.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from ..simulation.scenario import MAX_STIFFNESS
from .continuous import AnalysisError, _check, _pos

if TYPE_CHECKING:  # python-control takes 1.4 s to import: built on first use of SampledModel.sys
    import control as ct

__all__ = ["largest_stable", "stable_band", "StiffnessBand", "stiffness_band", "effective_mass", "SampledModel", "sampled_closed_loop", "spectral_radius",
           "spectral_radii", "free_axis_radius", "max_stable_stiffness", "stability_region", "stiffness_margin", "switch_response"]



def effective_mass(D: np.ndarray, n: np.ndarray) -> float:
    """Effective Cartesian mass along unit vector n: ``1/(n^T D*^-1 n)``, kg."""
    return float(1.0 / (n @ np.linalg.solve(D, n)))


@dataclass(frozen=True, eq=False)
class SampledModel:
    """Discrete-time closed loop of the normal axis at Ts.

    State ``(x, x', x_a, x_a', f_m)`` as deviations from the equilibrium
    (m, m/s, m, m/s, N); ``sys`` is a python-control discrete StateSpace with
    input f_d (N) and output the contact force f_e (N)."""
    Ts: float
    k_e: float
    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    spectral_radius: float
    params: dict = field(default_factory=dict)

    @property
    def sys(self) -> ct.StateSpace:
        import control as ct

        return ct.ss(self.A, self.B, self.C, [[0.0]], self.Ts, inputs="f_d", outputs="f_e",
                     states=["x", "dx", "xa", "dxa", "f_m"])

    @property
    def stable(self) -> bool:
        return self.spectral_radius < 1.0


def _zoh(A, B, Ts):
    """Exact zero-order-hold discretisation of ``(A, B)`` over Ts; stacks of
    matrices (leading axes) are discretised each on its own."""
    n, mi = A.shape[-1], B.shape[-1]
    M = np.zeros(A.shape[:-2] + (n + mi, n + mi))
    M[..., :n, :n], M[..., :n, n:] = A, B
    from scipy.linalg import expm   # here: SciPy's import (0.15 s) is not on a warm `simulate`'s path

    E = expm(M * Ts)
    return E[..., :n, :n], E[..., :n, n:]


def _discrete_loop(m, b, k, k_e: np.ndarray, Ts, m_p, kd, kp, law, alpha, d_e):
    """``(Ad, Bd, C)`` of the sampled normal-axis loop for each stiffness of
    the 1-D array ``k_e``: shapes (n, 5, 5), (n, 5, 1), (n, 1, 5)."""
    n = k_e.size
    one, zero = np.ones(n), np.zeros(n)
    # continuous part within a period: z = (x, v, xa, va), held inputs (U, f)
    A = np.zeros((n, 4, 4))
    A[:, 0, 1], A[:, 1, 0], A[:, 1, 1] = 1.0, -k_e / m_p, -d_e / m_p
    A[:, 2, 3], A[:, 3, 2], A[:, 3, 3] = 1.0, -k / m, -b / m
    B = np.broadcast_to(np.array([[0, 0], [1, 1 / m_p], [0, 0], [0, 1 / m]], dtype=float), (n, 4, 2))
    Phi, Gam = _zoh(A, B, Ts)
    # sample: f_m = alpha f_prev + (1 - alpha)(k_e x + d_e v)  -> row over (x, v, xa, va, f_prev)
    fm = np.stack([(1 - alpha) * k_e, (1 - alpha) * d_e * one, zero, zero, alpha * one], axis=1)
    # reference deviation: TMT dx_r = dx - df_m/k_e ; known: 0 ; plus f_d input
    e = np.eye(5)
    xr = (e[0] - fm / k_e[:, None]) if law == "tmt" else np.zeros((n, 5))
    # x_r sensitivity to f_d at the equilibrium: d/df_d [f_d/k + f_d x/f_m] = 1/k + 1/k_e
    xr_fd = 1 / k + 1 / k_e
    aa = (fm - b * e[3] - k * e[2]) / m                                  # x_a''
    xc, dxc = xr - e[2], -e[3]
    U = -aa + kd * (dxc - e[1]) + kp * (xc - e[0])
    Ad = np.zeros((n, 5, 5))
    Bd = np.zeros((n, 5, 1))
    Ad[:, :4] = Phi @ e[:4] + Gam @ np.stack([U, fm], axis=1)
    Bd[:, :4, 0] = Gam[:, :, 0] * (kp * xr_fd)[:, None]
    Ad[:, 4] = fm
    C = np.stack([k_e, d_e * one, zero, zero, zero], axis=1)[:, None, :]
    return Ad, Bd, C


def check_loop_settings(alpha, d_e, kd=None, kp=None) -> None:
    """:class:`AnalysisError` naming the first of the force filter's pole
    ``alpha`` (0 <= alpha < 1), the contact damping ``d_e`` (N s/m, >= 0) and
    the inner-loop gains ``kd``, ``kp`` (>= 0 when given) out of range
    (review 58: alpha = 2, d_e = -5 and kd = -1 were analysed silently,
    alpha = NaN failed in LAPACK)."""
    _pos("alpha", alpha, strict=False)
    if alpha >= 1.0:
        raise AnalysisError(f"alpha: the force filter's pole must be < 1, got {alpha!r}")
    _pos("d_e", d_e, strict=False)
    for name, v in (("kd", kd), ("kp", kp)):
        if v is not None:
            _pos(name, v, strict=False)


def _loop_args(m, b, k, k_e, Ts, m_p, kd, kp, law, alpha=0.0, d_e=0.0, k_e_max=None):
    _check(m, b, k, k_e)
    _pos("Ts", Ts)
    _pos("m_p", m_p)
    check_loop_settings(alpha, d_e, kd, kp)
    top = k_e if k_e_max is None else k_e_max
    if top > MAX_STIFFNESS:     # review 58: 1e300 N/m failed in LAPACK
        raise AnalysisError(f"k_e: at most {MAX_STIFFNESS:g} N/m (the stiffest surface analysed), got {top!r}")
    if law not in ("tmt", "known"):
        raise AnalysisError(f"law: the 1-D sampled model covers 'tmt' and 'known', got {law!r}")
    return (b / m if kd is None else kd), (k / m if kp is None else kp)


def sampled_closed_loop(m, b, k, k_e, Ts, m_p, kd=None, kp=None, law="tmt", alpha=0.0,
                        d_e=0.0) -> SampledModel:
    """The normal axis of the implemented sampled loop (see module docstring).

    Parameters
    ----------
    m, b, k : float
        Impedance (eq. 2), kg, N s/m, N/m.
    k_e : float
        Environment stiffness, N/m.
    Ts : float
        Control period, s.
    m_p : float
        Robot's effective Cartesian mass along the normal, kg.
    kd, kp : float, optional
        Inner-loop gains of eq. (6); default b/m, k/m (eq. 9).
    law : {"tmt", "known"}
        TMT (linearised: dx_r = dx - df_m/k_e) or a fixed reference.
    alpha : float
        Force-filter pole (0 = no filter), as in the simulator.
    d_e : float
        Contact damping, N s/m.
    """
    kd, kp = _loop_args(m, b, k, k_e, Ts, m_p, kd, kp, law, alpha, d_e)
    Ad, Bd, C = (x[0] for x in _discrete_loop(m, b, k, np.array([float(k_e)]), Ts, m_p, kd, kp, law, alpha, d_e))
    rho = float(np.max(np.abs(np.linalg.eigvals(Ad))))
    return SampledModel(Ts, k_e, Ad, Bd, C, rho, {"m": m, "b": b, "k": k, "m_p": m_p, "kd": kd, "kp": kp,
                                             "law": law, "alpha": alpha, "d_e": d_e})


def spectral_radii(m, b, k, k_e, Ts, m_p, kd=None, kp=None, law="tmt", alpha=0.0, d_e=0.0) -> np.ndarray:
    """:func:`spectral_radius` for every stiffness of the array ``k_e`` at
    once (the same matrices, discretised and solved as one stack)."""
    k_e = np.asarray(k_e, dtype=float).ravel()
    if not k_e.size:
        raise AnalysisError("k_e: expected at least one stiffness")
    kd, kp = _loop_args(m, b, k, float(k_e.min()), Ts, m_p, kd, kp, law, alpha, d_e, float(k_e.max()))
    Ad = _discrete_loop(m, b, k, k_e, Ts, m_p, kd, kp, law, alpha, d_e)[0]
    return np.abs(np.linalg.eigvals(Ad)).max(axis=1)


def spectral_radius(m, b, k, k_e, Ts, m_p, **kw) -> float:
    """Largest eigenvalue magnitude of the sampled closed loop (< 1: stable)."""
    return sampled_closed_loop(m, b, k, k_e, Ts, m_p, **kw).spectral_radius


def free_axis_radius(kd: float, kp: float, Ts: float, delay: int = 0, lead: float = 0.0) -> float:
    """Spectral radius (< 1: stable) of a sampled axis that meets no contact
    force: a tangential or rotational task axis, or the null-space posture,
    under the ideal inner loop. Its deviation from the reference is a double
    integrator ``x'' = a`` whose acceleration is held over each period: the
    PD command of eq. (6) ``c_k = -kp x_k - kd x'_k`` (1/s^2, 1/s; the
    reference's deviation is 0), with the mid-period hold's ``lead``
    (``c_k + lead (c_k - c_{k-1})``, ``closedloop.MID_PERIOD``), applied from
    t_{k+delay}. Without delay and lead its characteristic polynomial is
    ``z^2 + (Ts^2 kp/2 + Ts kd - 2) z + 1 - Ts kd + Ts^2 kp/2``, stable
    (Jury) iff ``kp > 0`` and ``Ts kp/2 < kd < 2/Ts``: the hold costs the
    axis the damping ``Ts kp/2``, so ``kd = 0`` (``impedance.b_rot = 0``)
    is unstable at every rate, growing about ``(Ts kp/2 - kd)/2`` per
    second. With ``kp = 0`` (a posture held in velocity only: review 55)
    the position does not feed back: its pole at exactly 1 is a drift that
    stops, not a growth, and the radius is the velocity loop's alone."""
    _pos("Ts", Ts)
    if not isinstance(delay, (int, np.integer)) or delay < 0:
        raise AnalysisError(f"delay: expected an integer >= 0 samples, got {delay!r}")
    h = int(lead != 0.0)
    n = 2 + h + delay
    c = np.zeros(n)
    c[0], c[1] = -kp, -kd                              # the command computed at t_k
    held = (1.0 + lead) * c - (lead * np.eye(n)[2] if h else 0.0)
    applied = np.eye(n)[2 + h] if delay else held      # the oldest queued command, or this one
    A = np.zeros((n, n))
    A[0] = np.eye(n)[0] + Ts * np.eye(n)[1] + Ts * Ts / 2 * applied
    A[1] = np.eye(n)[1] + Ts * applied
    if h:
        A[2] = c
    if delay:
        A[2 + h:n - 1] = np.eye(n)[3 + h:]             # the queue moves up, this period's command last
        A[n - 1] = held
    if kp == 0.0:                                       # nothing reads x: its row is the pole at 1 alone
        A = A[1:, 1:]
    return float(np.max(np.abs(np.linalg.eigvals(A))))


@dataclass(frozen=True)
class StiffnessBand:
    """The band of environment stiffness (N/m) in which a loop is stable,
    as :func:`stable_band` finds it on its log scan from ``scan_from``.

    ``lower``, ``upper``: the band's edges; ``lower`` is ``scan_from`` when
    the loop is stable there (nothing below the scan is searched), ``upper``
    is ``inf`` when it is stable up to the scan's end; both NaN when no
    scanned stiffness is stable. The band is the one containing ``within``
    (the scenario's smallest stiffness), else the nearest band below it,
    else the nearest above; without ``within``, the lowest band of the scan.
    ``limit``: the largest stable stiffness for ``within``, the number a
    verdict compares with the scenario's largest stiffness: ``upper`` when
    the band starts at or below ``within``, 0 when the loop is unstable at
    ``within`` and at every scanned stiffness below it (the limit is then
    below the scenario, so a verdict on it fails)."""
    lower: float
    upper: float
    limit: float
    scan_from: float
    within: float | None = None

    @property
    def unstable_below(self) -> bool:
        """The loop is unstable from the scan's start up to ``lower``: an
        unstable band of softer surfaces lies below this one."""
        return bool(self.lower > self.scan_from)


def _bisect_edge(stable, good: float, bad: float, rtol: float) -> float:
    """The stability edge between a stable ``good`` and an unstable ``bad``
    stiffness (either order), by bisection in log k_e to ``rtol``: the
    last stable stiffness found."""
    lo, hi = (good, bad) if good < bad else (bad, good)
    lo, hi = float(lo), float(hi)
    while hi / lo > 1 + rtol:
        mid = math.sqrt(lo * hi)
        if stable(mid) == (good < bad):
            lo = mid
        else:
            hi = mid
    return lo if good < bad else hi


RESONANCE_OFFSETS = np.array([1e-8, 1e-7, 1e-6, 1e-5, 1e-4, 1e-3])
"""Where a sampling resonance's window is probed: k_n (1 - offset). Where
the contact mode sqrt(k_e / m_p) turns n pi per period (k_n = m_p (n pi /
Ts)^2) the zero-order hold cannot see it; the loop is unstable in a window
just below k_n (2.4 % wide for n = 1 with the paper's gains, narrowing as
1/n^2, always reaching k_n (1 - 1e-9): measured), narrower than any log
grid's step, so each window is probed at k_n itself (review 9: a
121-point grid stepped over the window at 2.9e6 N/m with m_p = 0.3 kg)."""


def resonances(m_p: float, Ts: float, k_lo: float, k_hi: float, most: int = 2000) -> np.ndarray:
    """The probe points (N/m, ascending) of the sampling resonances k_n =
    m_p (n pi / Ts)^2 in (k_lo, k_hi) (:data:`RESONANCE_OFFSETS`; at most
    ``most`` resonances)."""
    n0 = max(1, math.ceil(Ts / math.pi * math.sqrt(max(k_lo, 0.0) / m_p)))
    top = Ts / math.pi * math.sqrt(k_hi / m_p) if math.isfinite(k_hi) else math.inf
    n1 = int(min(n0 + most, math.floor(top) + 1))
    if n1 < n0:
        return np.zeros(0)
    k_n = m_p * (np.arange(n0, n1 + 1) * math.pi / Ts) ** 2
    pts = np.sort((k_n[:, None] * (1.0 - RESONANCE_OFFSETS[::-1][None, :])).ravel())
    return pts[(pts > k_lo) & (pts < k_hi)]


def stable_band(stable, k_lo: float = 10.0, k_hi: float = 1e9, rtol: float = 1e-6, points: int = 49,
                within: float | None = None, scan=None, resonance: tuple[float, float] | None = None
                ) -> StiffnessBand:
    """The band of k_e (N/m) in which ``stable(k_e)`` holds: a ``points``-
    point log grid from ``k_lo`` (or ``within`` if smaller) to ``k_hi``, then
    bisection of each edge in log k_e to ``rtol``.

    With ``within`` (N/m, the scenario's smallest stiffness) the band is the
    one that contains it, else the nearest below, else the nearest above
    (see :class:`StiffnessBand`; its ``limit`` is the scenario's limit);
    without, the lowest stable band of the grid. For a loop stable from the
    scan's start up to its first unstable grid point this is exactly a plain
    upward scan (bisection between that point and the stable grid point
    before it); a loop unstable at the scan's start (a stiff contact damper
    on a soft surface: the TMT reference's ``d_e x'/k_e`` term is then a
    sampled velocity feedback too strong for Ts) gets its lower edge
    searched and the band above it. Grid points are evaluated lazily
    (downward from ``within`` and upward to the band's end), unless ``scan``,
    a vectorised ``stable`` (array in, boolean array out), gives the whole
    grid at once. ``resonance = (m_p, Ts)`` (kg, s): between the seed and
    each edge the sampling resonances are probed too (:func:`resonances`),
    and the nearest unstable one ends the band. The package's one grid-and-bisection stiffness search:
    :func:`largest_stable`, :func:`max_stable_stiffness`,
    ``stability.lawloop.law_stiffness_limit`` and ``stability.analysis``
    call it."""
    for name, v in (("k_lo", k_lo), ("k_hi", k_hi)) + ((("within", within),) if within is not None else ()):
        _pos(name, v)             # review 58: within = -5 read "k_e: must be finite, got nan"
    if not k_lo < k_hi:
        raise AnalysisError(f"k_hi: must be above k_lo ({k_lo!r} N/m), got {k_hi!r}")
    start = float(k_lo if within is None else min(k_lo, within))
    grid = np.geomspace(start, k_hi, points)
    known = {} if scan is None else dict(enumerate(np.asarray(scan(grid), dtype=bool).tolist()))
    nan = float("nan")

    def ok(i):
        if i not in known:
            known[i] = bool(stable(grid[i]))
        return known[i]

    def window(seed, bound):
        # the unstable resonance probe in (seed, bound) nearest the seed (bound above or below it) and the stable
        # point nearest to that probe on the seed's side (review 71: below the seed too, where a seed just above a
        # resonance's unstable sliver took the band down through the sliver)
        if resonance is None:
            return None
        probes = resonances(*resonance, min(seed, bound), max(seed, bound))
        if not probes.size:
            return None
        flags = np.asarray(scan(probes), dtype=bool) if scan is not None else None
        near = seed
        for j in (range(probes.size) if bound > seed else range(probes.size - 1, -1, -1)):
            kr = probes[j]
            if not (flags[j] if flags is not None else stable(kr)):
                lo, hi = min(near, kr), max(near, kr)
                return kr, min([near, *(g for g in grid if lo < g < hi)], key=lambda g: abs(g - kr))
            near = kr
        return None

    def upper_edge(i0, seed):
        # the first unstable grid point from index i0 (the first above the stable seed)
        i = next((i for i in range(i0, points) if not ok(i)), None)
        hit = window(seed, grid[i] if i is not None else k_hi)
        if hit is not None:                 # a sampling resonance's window before it
            return _bisect_edge(stable, hit[1], hit[0], rtol)
        if i is None:
            return float("inf")
        # bracket from the stable grid point before it (a plain upward scan's), else from the seed
        edge = _bisect_edge(stable, grid[i - 1] if i > 0 and ok(i - 1) else seed, grid[i], rtol)
        return edge if edge >= seed else _bisect_edge(stable, seed, grid[i], rtol)

    def lower_edge(i0, seed):
        # the first unstable grid point downward from index i0 (the last below the stable seed), unless an
        # unstable resonance lies between it and the seed
        i = next((i for i in range(i0, -1, -1) if not ok(i)), None)
        hit = window(seed, grid[i] if i is not None else start)
        if hit is not None:
            return _bisect_edge(stable, hit[1], hit[0], rtol)
        if i is None:
            return start
        return _bisect_edge(stable, grid[i + 1] if i < i0 else seed, grid[i], rtol)

    if within is None:
        j = next((i for i in range(points) if ok(i)), None)
        if j is None:
            return StiffnessBand(nan, nan, 0.0, start)
        upper = upper_edge(j + 1, grid[j])
        return StiffnessBand(lower_edge(j - 1, grid[j]), upper, upper, start)
    w = float(within)
    above = int(np.searchsorted(grid, w, side="right"))        # the first grid index above w
    below = int(np.searchsorted(grid, w, side="left")) - 1     # the last grid index below w
    if stable(w):
        upper = upper_edge(above, w)
        return StiffnessBand(lower_edge(below, w), upper, upper, start, w)
    j = next((i for i in range(below, -1, -1) if ok(i)), None)
    if j is not None:           # the nearest band below the scenario: its upper edge (< w) is the limit
        bad = grid[j + 1] if j < below or (j + 1 < points and not ok(j + 1)) else w
        upper = _bisect_edge(stable, grid[j], bad, rtol)
        if upper >= w:          # the grid's bracket straddled w: the edge is below w
            upper = _bisect_edge(stable, grid[j], w, rtol)
        return StiffnessBand(lower_edge(j - 1, grid[j]), upper, upper, start, w)
    j = next((i for i in range(above, points) if ok(i)), None)
    if j is None:
        return StiffnessBand(nan, nan, 0.0, start, w)
    lower = _bisect_edge(stable, grid[j], grid[j - 1] if j > above else w, rtol)
    return StiffnessBand(lower, upper_edge(j + 1, grid[j]), 0.0, start, w)


def largest_stable(stable, k_lo: float = 10.0, k_hi: float = 1e9, rtol: float = 1e-6, points: int = 49,
                   within: float | None = None, resonance: tuple[float, float] | None = None) -> float:
    """Largest k_e (N/m) with ``stable(k_e)``: :func:`stable_band`'s
    ``limit`` (``inf`` if stable up to ``k_hi``; the upper edge of the band
    that contains ``within``, or without it of the lowest stable band of the
    scan; 0 if no band starts at or below ``within``). For a stability
    test without a vectorised form (the law loops, the scenario's 1-D
    loops)."""
    return stable_band(stable, k_lo, k_hi, rtol, points, within, resonance=resonance).limit


def stiffness_band(m, b, k, Ts, m_p, k_lo=10.0, k_hi=1e10, within=None, **kw) -> StiffnessBand:
    """The band of k_e (N/m) in which the sampled loop is stable at Ts:
    :func:`stable_band` on the spectral radius, a 121-point log grid from
    ``k_lo`` to ``k_hi`` (evaluated as one stack) and bisection to 1e-6
    relative. ``within``: the scenario's smallest stiffness (N/m), whose
    band is wanted. ``k_lo`` = 10 N/m as in ``stability.lawloop``: a
    surface that would need 1 m of penetration for 10 N is not the limit
    sought."""
    return stable_band(lambda ke: spectral_radius(m, b, k, ke, Ts, m_p, **kw) < 1.0, k_lo, k_hi, 1e-6, 121,
                       within, scan=lambda g: spectral_radii(m, b, k, g, Ts, m_p, **kw) < 1.0, resonance=(m_p, Ts))


def max_stable_stiffness(m, b, k, Ts, m_p, k_lo=10.0, k_hi=1e10, within=None, **kw) -> float:
    """Largest k_e for which the sampled loop is stable at Ts (N/m): the
    ``limit`` of :func:`stiffness_band`, the upper edge of the stable band
    that contains ``within`` (default: of the lowest stable band from
    ``k_lo``). ``inf`` if stable up to ``k_hi``; 0 if the loop is unstable at
    ``within`` and at every stiffness scanned below it. A contact damper
    ``d_e`` makes the TMT loop unstable on soft surfaces (with the paper's
    gains at 1 kHz, below about 11 N/m at d_e = 200 N s/m and 380 N/m at
    2000 N s/m; this closed form has no compliance clip, see
    ``stability.analysis.closed_form_applies``): the band then starts
    above ``k_lo`` and its upper edge is still the limit."""
    return stiffness_band(m, b, k, Ts, m_p, k_lo, k_hi, within, **kw).limit


def stability_region(m, b, k, m_p, Ts_grid, k_e_grid, **kw) -> np.ndarray:
    """Spectral radius on a grid: array (len(k_e_grid), len(Ts_grid))."""
    return np.array([spectral_radii(m, b, k, k_e_grid, Ts, m_p, **kw) for Ts in Ts_grid]).T


def stiffness_margin(m, b, k, m_p, Ts_grid, k_e_grid, **kw) -> tuple[np.ndarray, np.ndarray]:
    """The distance to the stability boundary on a grid: ``(limits, margin)``
    with ``limits[j]`` the largest stable stiffness at ``Ts_grid[j]``
    (:func:`max_stable_stiffness`, N/m) and ``margin[i, j] =
    log10(limits[j] / k_e_grid[i])`` in decades (> 0 stable; +inf where the
    loop is stable at any stiffness, -inf where at none). Below a band that
    starts above the scan (:func:`stiffness_band`: an unstable band of soft
    surfaces, from contact damping) the margin is ``log10(k_e_grid[i] /
    lower)`` instead, negative: the decades up to the band. Unlike the spectral
    radius, which on the stable side is often the impedance filter's slow pole
    whatever k_e, the margin says how far k_e may grow."""
    bands = [stiffness_band(m, b, k, Ts, m_p, **kw) for Ts in Ts_grid]
    limits = np.array([bd.limit for bd in bands])
    lower = np.array([bd.lower if bd.unstable_below else 0.0 for bd in bands])[None, :]   # NaN: no band
    k_e = np.asarray(k_e_grid, float)[:, None]
    with np.errstate(divide="ignore", invalid="ignore"):
        margin = np.log10(limits[None, :] / k_e)
        margin = np.where(k_e < lower, np.log10(k_e / lower), margin)
    return limits, margin


def switch_response(m, b, k, k_old, k_new, Ts, m_p, f_d=10.0, duration=4.0, **kw) -> dict:
    """Predicted force after a stiffness switch k_old -> k_new at a sample.

    Starts from the equilibrium for k_old (x = f_d/k_old, x_a = f_d/k, at
    rest) and runs the linear sampled model for k_new. Returns time, force,
    the controller's overshoot % after the switch jump (as
    ``segment_metrics``), 2 % settling time and ``contact_lost`` (the
    linear prediction went below zero force, where the unilateral contact
    makes it invalid)."""
    model = sampled_closed_loop(m, b, k, k_new, Ts, m_p, **kw)
    A, C = model.A, model.C
    # equilibrium for k_new (deviation origin) and the old state
    x_new, x_old = f_d / k_new, f_d / k_old
    # deviations from the new equilibrium; the force filter had converged to
    # the old force f_d, so its deviation is 0
    z = np.array([x_old - x_new, 0.0, 0.0, 0.0, 0.0])
    n = int(round(duration / Ts))
    f = np.empty(n)
    for i in range(n):
        f[i] = f_d + float((C @ z)[0])
        z = A @ z
    from ..simulation.metrics import settling_time

    t = np.arange(n) * Ts
    # the controller's overshoot after the jump, as segment_metrics measures it:
    # a dip below f_d when the force starts above it, a rise above f_d otherwise;
    # a dip is at most f_d (the unilateral contact clips the force at zero)
    after = f[1:]
    over = (f_d - max(float(after.min()), 0.0)) if f[0] > f_d else float(after.max()) - f_d
    return {"time": t, "force": f, "overshoot_pct": max(0.0, over) / f_d * 100,
            "settling_time": settling_time(f - f_d, 0.02 * f_d, t), "contact_lost": bool(f.min() < 0),
            "model": model}


