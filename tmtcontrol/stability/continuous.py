"""Continuous-time stability and damping of the TMT error dynamics (eqs. 19-25).

With the TMT reference the normal axis obeys eq. (22),
``m e'' + b e' + (k + k_e) e = -f_d (k + k_e)/k_e``; the force
``f_e = k_e (x - x_e) = -k_e e`` then responds to f_d through

    G(s) = (k + k_e) / (m s^2 + b s + k + k_e)                          (22)

whose DC gain is 1: f_e = f_d at steady state (eqs. 23-24). Critical damping
is ``b = 2 sqrt(m (k + k_e))`` (eq. 25). Every public function returns
python-control objects or plain numbers; units are SI.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:  # python-control takes 1.4 s to import: functions import it when called
    import control as ct

__all__ = [
    "AnalysisError", "ContinuousAnalysis", "minimal_realization", "bibo_stable",
    "internally_stable", "tmt_error_tf", "tmt_error_ss", "analyze_continuous",
    "critical_damping", "damping_ratio", "damping_for_range", "RangeAnalysis", "analyze_range",
    "stiffness_sweep", "x_e_error_force",
]


class AnalysisError(ValueError):
    """Invalid analysis input; the message names the parameter."""


def _pos(name, v, strict=True):
    if isinstance(v, bool) or not isinstance(v, (int, float, np.floating, np.integer)):
        raise AnalysisError(f"{name}: expected a number, got {v!r}")
    if not math.isfinite(v):
        raise AnalysisError(f"{name}: must be finite, got {v!r}")
    if (v <= 0) if strict else (v < 0):
        raise AnalysisError(f"{name}: must be {'>' if strict else '>='} 0, got {v!r}")


def _check(m, b, k, k_e=None, f_d=None):
    _pos("m", m)
    _pos("b", b, strict=False)
    _pos("k", k)   # the TMT law divides by k
    if k_e is not None:
        _pos("k_e", k_e)
    if f_d is not None:
        _pos("f_d", f_d)


# -- continuous time -------------------------------------------------------------

def tmt_error_tf(m, b, k, k_e) -> ct.TransferFunction:
    """Eq. (22) as the transfer function f_d -> f_e, ``(k+k_e)/(m s^2 + b s + k + k_e)``."""
    import control as ct
    _check(m, b, k, k_e)
    return ct.tf([k + k_e], [m, b, k + k_e], inputs="f_d", outputs="f_e")


def tmt_error_ss(m, b, k, k_e) -> ct.StateSpace:
    """Eq. (22) in state space: state (e, e'), input f_d, output f_e = -k_e e."""
    import control as ct
    _check(m, b, k, k_e)
    A = [[0.0, 1.0], [-(k + k_e) / m, -b / m]]
    B = [[0.0], [-(k + k_e) / (k_e * m)]]
    C = [[-k_e, 0.0]]
    return ct.ss(A, B, C, [[0.0]], inputs="f_d", outputs="f_e", states=["e", "de"])


def critical_damping(m, k, k_e) -> float:
    """Eq. (25): the smallest b giving a critically damped (or overdamped) loop."""
    _check(m, 0.0, k, k_e)
    return 2.0 * math.sqrt(m * (k + k_e))


def damping_ratio(m, b, k, k_e) -> float:
    """zeta = b / (2 sqrt(m (k + k_e)))."""
    return b / critical_damping(m, k, k_e)


@dataclass(frozen=True, eq=False)
class ContinuousAnalysis:
    """Eq. (22) at one stiffness: systems, poles and verdicts. The systems
    are built from (m, b, k, k_e) when asked for, so the analysis holds only
    numbers (python-control's state-space objects cannot be pickled: an
    analysis can be sent to another process)."""
    m: float
    b: float
    k: float
    k_e: float
    f_d: float
    poles: np.ndarray
    natural_frequency: float      # rad/s
    damping_ratio: float
    bibo_stable: bool
    steady_state_force: float     # N, f_d * DC gain (eqs. 23-24)
    critical_damping: float       # N s/m, eq. (25)
    overshoot_pct: float
    settling_time: float          # s, 2 %

    @property
    def tf(self) -> ct.TransferFunction:
        """Eq. (22) as a transfer function (:func:`tmt_error_tf`)."""
        return tmt_error_tf(self.m, self.b, self.k, self.k_e)

    @property
    def ss(self) -> ct.StateSpace:
        """Eq. (22) in state space (:func:`tmt_error_ss`)."""
        return tmt_error_ss(self.m, self.b, self.k, self.k_e)

    def as_dict(self) -> dict:
        return {"m": self.m, "b": self.b, "k": self.k, "k_e": self.k_e, "f_d": self.f_d,
                "poles": [[float(p.real), float(p.imag)] for p in self.poles],
                "natural_frequency": self.natural_frequency, "damping_ratio": self.damping_ratio,
                "bibo_stable": self.bibo_stable, "steady_state_force": self.steady_state_force,
                "critical_damping": self.critical_damping, "overshoot_pct": self.overshoot_pct,
                "settling_time": self.settling_time}


def minimal_realization(sys: ct.LTI, tol: float = 1e-9) -> ct.StateSpace:
    """Controllable and observable part of ``sys`` (Kalman decomposition).

    python-control's ``minreal`` for state space needs slycot (a Fortran
    build); this does the same with orthonormal bases from SVD rank tests
    (singular values below ``tol`` times the largest count as zero): project
    on the controllable subspace, then on the orthogonal complement of the
    unobservable subspace (both are A-invariant, so the projections are
    exact)."""
    import control as ct
    S = ct.ss(sys)
    A, B, C, D = (np.asarray(M, dtype=float) for M in (S.A, S.B, S.C, S.D))
    n = A.shape[0]

    def basis(M):
        if M.size == 0:
            return np.zeros((n, 0))
        U, sv, _ = np.linalg.svd(M)
        r = int(np.sum(sv > tol * max(sv.max(), 1e-300))) if sv.size else 0
        return U[:, :r]

    T = basis(np.hstack([np.linalg.matrix_power(A, i) @ B for i in range(n)]))
    A1, B1, C1 = T.T @ A @ T, T.T @ B, C @ T
    r1 = A1.shape[0]
    O = np.vstack([C1 @ np.linalg.matrix_power(A1, i) for i in range(r1)]) if r1 else np.zeros((0, 0))
    W = basis(O.T) if r1 else np.zeros((0, 0))
    A2, B2, C2 = W.T @ A1 @ W, W.T @ B1, C1 @ W
    return ct.ss(A2, B2, C2, D, S.dt)


MARGINAL = 1e-9
"""An eigenvalue within this relative distance of the stability boundary
(|Re| <= MARGINAL |lambda| in continuous time, |lambda| >= 1 - MARGINAL in
discrete time) is not counted stable: a verdict does not rest on rounding
(an undamped loop's poles on the imaginary axis come out of LAPACK with a
real part of order 1e-16 |lambda| of either sign)."""


def _stable_eigs(eig, discrete) -> bool:
    eig = np.asarray(eig)
    if discrete:
        return bool(np.all(np.abs(eig) < 1.0 - MARGINAL))
    return bool(np.all(eig.real < -MARGINAL * np.abs(eig)))


def _balanced(sys: ct.LTI):
    """``(A, B, C, discrete)`` of ``sys`` after a diagonal similarity that
    balances A (powers of 2, LAPACK's gebal: exact in floating point) and
    with B and C scaled to unit norm (the input's and output's units do not
    change stability): eq. (22)'s state space at k_e = 1e8 N/m and m = 1 g
    has entries from 1e-8 to 1e11, where an unscaled rank test drops a
    state."""
    import control as ct
    from scipy.linalg import matrix_balance

    S = ct.ss(sys)
    A, B, C = (np.asarray(M, dtype=float) for M in (S.A, S.B, S.C))
    if A.size:
        _, (scale, _) = matrix_balance(A, permute=False, separate=True)
        A, B, C = A * scale[None, :] / scale[:, None], B / scale[:, None], C * scale[None, :]
    nb, nc = np.linalg.norm(B), np.linalg.norm(C)
    return A, B / (nb if nb > 0 else 1.0), C / (nc if nc > 0 else 1.0), S.isdtime()


def bibo_stable(sys: ct.LTI, tol: float = 1e-9) -> bool:
    """BIBO stability: every eigenvalue of the state matrix that the input
    reaches and the output sees strictly inside the stability region (the
    open left half plane, continuous; the open unit disc, discrete), by
    more than :data:`MARGINAL` (a pole on the boundary is not stable).

    Each eigenvalue is tested on its own (the Popov-Belevitch-Hautus test,
    on a balanced realisation: the mode is reached when its left
    eigenvector is not orthogonal to B, seen when C does not annihilate its
    right eigenvector, both to ``tol`` relative), rather than on
    transfer-function poles after numerical pole-zero cancellation, so a
    near-cancellation cannot hide an unstable mode that the input reaches
    and the output sees. Modes that are exactly uncontrollable or
    unobservable do not affect BIBO stability; see
    :func:`internally_stable` for those."""
    from scipy.linalg import eig as _eig

    A, B, C, discrete = _balanced(sys)
    if not A.size:
        return True
    lam, left, right = _eig(A, left=True, right=True)
    for i, li in enumerate(lam):
        if _stable_eigs([li], discrete):
            continue
        w, v = left[:, i], right[:, i]
        reached = np.linalg.norm(w.conj() @ B) > tol * np.linalg.norm(w)
        seen = np.linalg.norm(C @ v) > tol * np.linalg.norm(v)
        if reached and seen:
            return False
    return True


def internally_stable(sys: ct.LTI) -> bool:
    """Every eigenvalue of the (non-reduced) state matrix is stable."""
    import control as ct
    S = ct.ss(sys)
    return _stable_eigs(np.linalg.eigvals(S.A), S.isdtime()) if S.nstates else True


def analyze_continuous(m, b, k, k_e, f_d=10.0) -> ContinuousAnalysis:
    """Poles, natural frequency, damping, BIBO verdict, steady state and step
    metrics of eq. (22) at one stiffness."""
    _check(m, b, k, k_e, f_d)       # before importing python-control (~1 s): bad input is refused at once
    import control as ct

    S = tmt_error_ss(m, b, k, k_e)
    poles = np.sort_complex(np.linalg.eigvals(S.A))
    wn = math.sqrt((k + k_e) / m)
    stable = bibo_stable(S)
    if stable:
        zeta = damping_ratio(m, b, k, k_e)
        # eq. (22) is w_n^2 / (s^2 + 2 zeta w_n s + w_n^2): its step overshoot and 2 % settling time in closed
        # form (python-control's step_info reads them off a time grid, too coarse near the peaks: 72.5 % for
        # the exact 72.9 % at zeta = 0.1)
        overshoot = 100.0 * math.exp(-math.pi * zeta / math.sqrt(1.0 - zeta * zeta)) if zeta < 1.0 else 0.0
        settling = settling_time_2nd_order(zeta, wn)
        ss_force = f_d * float(np.real(ct.dcgain(S)))
    else:
        overshoot = settling = float("nan")
        ss_force = float("nan")
    return ContinuousAnalysis(m, b, k, k_e, f_d, poles, wn, damping_ratio(m, b, k, k_e),
                              stable, ss_force, critical_damping(m, k, k_e), overshoot, settling)


def settling_time_2nd_order(zeta: float, w_n: float, band: float = 0.02) -> float:
    """The last time (s) the unit step response of w_n^2 / (s^2 + 2 zeta w_n
    s + w_n^2) is ``band`` away from 1, exactly: its error is e(t) =
    e^(-zeta w_n t) (cos w_d t + zeta/sqrt(1 - zeta^2) sin w_d t) below
    critical damping, whose extrema at k pi / w_d are e^(-zeta w_n k pi /
    w_d), so the last crossing lies between the last extremum above the
    band and the next zero (root-found there); above it the error falls
    monotonically and is root-found on its own. Undamped or negatively
    damped (zeta <= 0), the error never stays within the band: inf (review
    45: zeta = 0 gave 0.155 s at w_n = 10 rad/s for an error of cos w_n t)."""
    from scipy.optimize import brentq

    for name, v in (("zeta", zeta), ("w_n", w_n), ("band", band)):
        if isinstance(v, bool) or not isinstance(v, (int, float, np.floating, np.integer)) or not math.isfinite(v):
            raise AnalysisError(f"{name}: expected a finite number, got {v!r}")
    _pos("w_n", w_n)
    if not 0.0 < band < 1.0:
        raise AnalysisError(f"band: must lie in (0, 1) (a fraction of the unit step), got {band!r}")
    if zeta <= 0.0:
        return math.inf
    if zeta < 1.0:
        w_d, r = w_n * math.sqrt(1.0 - zeta * zeta), zeta / math.sqrt(1.0 - zeta * zeta)
        sigma = zeta * w_n
        err = lambda t: math.exp(-sigma * t) * (math.cos(w_d * t) + r * math.sin(w_d * t))
        # the last extremum k pi / w_d whose size e^(-sigma k pi / w_d) exceeds the band (k = 0: the start)
        k = max(0, math.ceil(math.log(1.0 / band) * w_d / (sigma * math.pi)) - 1) if sigma > 0 else 0
        t0 = k * math.pi / w_d
        zero = (math.pi - math.atan2(1.0, r)) / w_d          # the first zero of e after 0; one every pi / w_d
        t1 = zero + k * math.pi / w_d
        return float(brentq(lambda t: abs(err(t)) - band, t0, t1, xtol=1e-14 * t1, rtol=1e-12))
    if zeta == 1.0:
        err = lambda t: math.exp(-w_n * t) * (1.0 + w_n * t)
    else:
        q = math.sqrt(zeta * zeta - 1.0)
        p1, p2 = w_n * (zeta - q), w_n * (zeta + q)          # the slow and the fast pole's magnitudes
        err = lambda t: (p2 * math.exp(-p1 * t) - p1 * math.exp(-p2 * t)) / (p2 - p1)
    hi = 1.0 / w_n
    while err(hi) > band:
        hi *= 2.0
    return float(brentq(lambda t: err(t) - band, 0.0, hi, xtol=1e-14 * hi, rtol=1e-12))


def damping_for_range(m, k, k_e_min, k_e_max, zeta=1.0) -> float:
    """The smallest b with damping ratio >= ``zeta`` for every k_e in
    [k_e_min, k_e_max]: the ratio falls with k_e, so it is set at k_e_max."""
    _check(m, 0.0, k, k_e_min)
    _pos("k_e_max", k_e_max)
    _pos("zeta", zeta)
    if k_e_min > k_e_max:
        raise AnalysisError(f"k_e_min: must be <= k_e_max ({k_e_max:g}), got {k_e_min:g}")
    return zeta * critical_damping(m, k, k_e_max)


@dataclass(frozen=True, eq=False)
class RangeAnalysis:
    """Eq. (22) over an interval of stiffness."""
    k_e_min: float
    k_e_max: float
    at_min: ContinuousAnalysis
    at_max: ContinuousAnalysis
    worst_damping_ratio: float
    stable_for_all: bool
    b_for_critical: float           # b giving zeta >= 1 over the whole interval (eq. 25 at k_e_max)
    slowest_settling_critical: float   # s, 2 % settling at k_e_min with that b: the cost

    def as_dict(self) -> dict:
        d = self.at_max.as_dict()
        d.update({"k_e_min": self.k_e_min, "k_e_max": self.k_e_max,
                  "worst_damping_ratio": self.worst_damping_ratio,
                  "stable_for_all": self.stable_for_all,
                  "b_for_critical_damping_over_range": self.b_for_critical,
                  "slowest_settling_with_that_b": self.slowest_settling_critical,
                  "at_k_e_min": self.at_min.as_dict()})
        return d


def analyze_range(m, b, k, k_e_min, k_e_max, f_d=10.0) -> RangeAnalysis:
    """Worst case of eq. (22) over [k_e_min, k_e_max]. Poles of
    ``m s^2 + b s + (k + k_e)`` have negative real part for every k_e > 0 iff
    b > 0 (the coefficients are positive), so ``stable_for_all`` is decided at
    both ends and on a log grid in between."""
    _check(m, b, k, k_e_min, f_d)
    _pos("k_e_max", k_e_max)
    if k_e_min > k_e_max:
        raise AnalysisError(f"k_e_min: must be <= k_e_max ({k_e_max:g}), got {k_e_min:g}")
    lo, hi = analyze_continuous(m, b, k, k_e_min, f_d), analyze_continuous(m, b, k, k_e_max, f_d)
    grid = np.geomspace(k_e_min, k_e_max, 25)
    stable = all(bibo_stable(tmt_error_ss(m, b, k, ke)) for ke in grid)
    b_crit = damping_for_range(m, k, k_e_min, k_e_max, 1.0)
    slow = analyze_continuous(m, b_crit, k, k_e_min, f_d).settling_time
    return RangeAnalysis(k_e_min, k_e_max, lo, hi, min(lo.damping_ratio, hi.damping_ratio),
                         stable, b_crit, slow)


def stiffness_sweep(m, b, k, k_e: np.ndarray) -> dict:
    """Root locus in k_e and damping ratio / natural frequency versus k_e.

    The characteristic polynomial ``m s^2 + b s + k + k_e`` is
    ``1 + k_e L(s)`` with ``L = 1/(m s^2 + b s + k)``, so python-control's
    :func:`control.root_locus_map` of L gives the locus."""
    import control as ct
    _check(m, b, k)
    k_e = np.asarray(k_e, dtype=float)
    if not k_e.size or not np.all(np.isfinite(k_e)) or np.any(k_e <= 0):    # review 58: [] failed inside NumPy
        raise AnalysisError(f"k_e: expected one or more finite stiffnesses > 0 (N/m), got {k_e.tolist()!r}")
    L = ct.tf([1.0], [m, b, k])
    rl = ct.root_locus_map(L, gains=k_e)
    return {"k_e": k_e, "root_locus": rl, "loci": rl.loci,
            "damping_ratio": b / (2 * np.sqrt(m * (k + k_e))),
            "natural_frequency": np.sqrt((k + k_e) / m)}


def x_e_error_force(f_d, k, k_e, delta, law="tmt", assumed_stiffness=None) -> float:
    """Steady-state force when the controller's surface location is off by
    ``delta`` (m, positive: believed deeper than it is).

    TMT: at f_e = f_d the reference ``x_e^ + f_d/k + f_d (x - x_e^)/f_e`` no
    longer depends on x_e^, so f_e = f_d is an equilibrium for any delta. It
    is the one reached while the compliance estimate stays non-negative,
    i.e. ``delta < f_d/k_e``; beyond, the estimate is clipped at 0 (see
    ``control.laws.tmt.tmt_reference``) and ``f_e = k_eff (delta + f_d/k)``.
    The linearised loop is ``m(1-c) s^2 + b(1-c) s + k_e + k(1-c)`` with
    ``c = delta k_e/f_d`` (``tmt_polynomial``): the stiffness changes by at
    most k. Its sampled limit falls for delta < 0 (surface believed closer:
    about -12 % at -10 mm, paper gains, 1 kHz); see docs/theory.md.

    Known law (eqs. 11-12): ``f_e = f_d k_eff(k_e)/k_eff(k_e^) + k_eff(k_e) delta``.
    """
    _pos("f_d", f_d)
    _pos("k", k)
    _pos("k_e", k_e)
    if isinstance(delta, bool) or not isinstance(delta, (int, float, np.floating, np.integer)) \
            or not math.isfinite(delta):
        raise AnalysisError(f"delta: expected a finite number (m), got {delta!r}")
    if law not in ("tmt", "known"):
        raise AnalysisError(f"law: expected 'tmt' or 'known', got {law!r}")
    keff = k * k_e / (k + k_e)
    if law == "tmt":
        return f_d if delta < f_d / k_e else keff * (delta + f_d / k)
    if assumed_stiffness is None:
        raise AnalysisError("assumed_stiffness: required for law = 'known'")
    _pos("assumed_stiffness", assumed_stiffness)
    keff_hat = k * assumed_stiffness / (k + assumed_stiffness)
    return f_d * keff / keff_hat + keff * delta


