"""Stability, damping and sampled-data analysis of the TMT loop (eqs. 19-25).

Continuous time (section IV). With the TMT reference the normal axis obeys
eq. (22), ``m e'' + b e' + (k + k_e) e = -f_d (k + k_e)/k_e``; the force
``f_e = k_e (x - x_e) = -k_e e`` then responds to f_d through

    G(s) = (k + k_e) / (m s^2 + b s + k + k_e)                          (22)

whose DC gain is 1: f_e = f_d at steady state (eqs. 23-24). Critical damping
is ``b = 2 sqrt(m (k + k_e))`` (eq. 25).

Sampled data (beyond the paper). The controller runs at Ts with zero-order
hold. In the ideal case (exact model, no friction) the normal axis of the
implemented loop is, between samples,

    x'' = U_k + (f_k - k_e x - d_e x')/m_p,     x_a'' = (f_k - b x_a' - k x_a)/m

with ``f_k`` the force measured at t_k (through the optional first-order
filter), ``U_k`` eq. (6) with the eq. (4) command and the TMT reference
linearised about its equilibrium (``dx_r = dx - df_m/k_e``), and ``m_p`` the
robot's effective Cartesian mass along the normal, ``1/(n^T D*^-1 n)``. Its
exact ZOH discretisation gives the discrete closed loop whose spectral radius
decides stability at Ts. Every public function returns python-control
objects or plain numbers; units are SI.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import control as ct
import numpy as np
from scipy.linalg import expm

__all__ = [
    "AnalysisError", "ContinuousAnalysis", "minimal_realization", "bibo_stable",
    "internally_stable", "tmt_error_tf", "tmt_error_ss", "analyze_continuous",
    "critical_damping", "damping_ratio", "damping_for_range", "RangeAnalysis", "analyze_range",
    "stiffness_sweep", "x_e_error_force", "SampledModel", "sampled_closed_loop",
    "spectral_radius", "max_stable_stiffness", "stability_region", "switch_response",
    "effective_mass", "scenario_parameters", "paper_effective_mass", "analyze", "analysis_kwargs",
    "format_analysis",
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
    _check(m, b, k, k_e)
    return ct.tf([k + k_e], [m, b, k + k_e], inputs="f_d", outputs="f_e")


def tmt_error_ss(m, b, k, k_e) -> ct.StateSpace:
    """Eq. (22) in state space: state (e, e'), input f_d, output f_e = -k_e e."""
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


@dataclass(frozen=True)
class ContinuousAnalysis:
    """Eq. (22) at one stiffness: systems, poles and verdicts."""
    m: float
    b: float
    k: float
    k_e: float
    f_d: float
    tf: ct.TransferFunction
    ss: ct.StateSpace
    poles: np.ndarray
    natural_frequency: float      # rad/s
    damping_ratio: float
    bibo_stable: bool
    steady_state_force: float     # N, f_d * DC gain (eqs. 23-24)
    critical_damping: float       # N s/m, eq. (25)
    overshoot_pct: float
    settling_time: float          # s, 2 %

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


def _stable_eigs(eig, discrete) -> bool:
    return bool(np.all(np.abs(eig) < 1.0)) if discrete else bool(np.all(eig.real < 0.0))


def bibo_stable(sys: ct.LTI) -> bool:
    """BIBO stability: every eigenvalue of the state matrix of a minimal
    realisation strictly in the open left half plane (continuous) or inside
    the unit circle (discrete).

    Deciding on state-space eigenvalues after an exact (subspace) minimal
    realisation, rather than on transfer-function poles after numerical
    pole-zero cancellation, means a near-cancellation cannot hide an unstable
    mode that the input reaches and the output sees. Modes that are exactly
    uncontrollable or unobservable do not affect BIBO stability; see
    :func:`internally_stable` for those."""
    red = minimal_realization(sys)
    return _stable_eigs(np.linalg.eigvals(red.A), ct.ss(sys).isdtime()) if red.nstates else True


def internally_stable(sys: ct.LTI) -> bool:
    """Every eigenvalue of the (non-reduced) state matrix is stable."""
    S = ct.ss(sys)
    return _stable_eigs(np.linalg.eigvals(S.A), S.isdtime()) if S.nstates else True


def analyze_continuous(m, b, k, k_e, f_d=10.0) -> ContinuousAnalysis:
    """Poles, natural frequency, damping, BIBO verdict, steady state and step
    metrics of eq. (22) at one stiffness."""
    _check(m, b, k, k_e, f_d)
    G = tmt_error_tf(m, b, k, k_e)
    S = tmt_error_ss(m, b, k, k_e)
    poles = np.sort_complex(np.linalg.eigvals(S.A))
    wn = math.sqrt((k + k_e) / m)
    stable = bibo_stable(S)
    if stable:
        info = ct.step_info(G)
        overshoot, settling = float(info["Overshoot"]), float(info["SettlingTime"])
        ss_force = f_d * float(np.real(ct.dcgain(S)))
    else:
        overshoot = settling = float("nan")
        ss_force = float("nan")
    return ContinuousAnalysis(m, b, k, k_e, f_d, G, S, poles, wn, damping_ratio(m, b, k, k_e),
                              stable, ss_force, critical_damping(m, k, k_e), overshoot, settling)


def damping_for_range(m, k, k_e_min, k_e_max, zeta=1.0) -> float:
    """The smallest b with damping ratio >= ``zeta`` for every k_e in
    [k_e_min, k_e_max]: the ratio falls with k_e, so it is set at k_e_max."""
    _check(m, 0.0, k, k_e_min)
    _pos("k_e_max", k_e_max)
    _pos("zeta", zeta)
    if k_e_min > k_e_max:
        raise AnalysisError(f"k_e_min: must be <= k_e_max ({k_e_max:g}), got {k_e_min:g}")
    return zeta * critical_damping(m, k, k_e_max)


@dataclass(frozen=True)
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
    _check(m, b, k)
    k_e = np.asarray(k_e, dtype=float)
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
    reference.py) and ``f_e = k_eff (delta + f_d/k)``. The linearised loop
    stiffness is ``k + k_e/(1 - delta k_e/f_d)``: an error towards the
    surface stiffens the loop (check sampled stability!).

    Known law (eqs. 11-12): ``f_e = f_d k_eff(k_e)/k_eff(k_e^) + k_eff(k_e) delta``.
    """
    keff = k * k_e / (k + k_e)
    if law == "tmt":
        return f_d if delta < f_d / k_e else keff * (delta + f_d / k)
    if assumed_stiffness is None:
        raise AnalysisError("assumed_stiffness: required for law = 'known'")
    keff_hat = k * assumed_stiffness / (k + assumed_stiffness)
    return f_d * keff / keff_hat + keff * delta


# -- sampled data ----------------------------------------------------------------

def effective_mass(D: np.ndarray, n: np.ndarray) -> float:
    """Effective Cartesian mass along unit vector n: ``1/(n^T D*^-1 n)``, kg."""
    return float(1.0 / (n @ np.linalg.solve(D, n)))


@dataclass(frozen=True)
class SampledModel:
    """Discrete-time closed loop of the normal axis at Ts.

    State ``(x, x', x_a, x_a', f_m)`` as deviations from the equilibrium
    (m, m/s, m, m/s, N); ``sys`` is a python-control discrete StateSpace with
    input f_d (N) and output the contact force f_e (N)."""
    Ts: float
    k_e: float
    sys: ct.StateSpace
    spectral_radius: float
    params: dict = field(default_factory=dict)

    @property
    def stable(self) -> bool:
        return self.spectral_radius < 1.0


def _zoh(A, B, Ts):
    n, mi = A.shape[0], B.shape[1]
    M = np.zeros((n + mi, n + mi))
    M[:n, :n], M[:n, n:] = A, B
    E = expm(M * Ts)
    return E[:n, :n], E[:n, n:]


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
    _check(m, b, k, k_e)
    _pos("Ts", Ts)
    _pos("m_p", m_p)
    kd = b / m if kd is None else kd
    kp = k / m if kp is None else kp
    # continuous part within a period: z = (x, v, xa, va), held inputs (U, f)
    A = np.array([[0, 1, 0, 0], [-k_e / m_p, -d_e / m_p, 0, 0], [0, 0, 0, 1], [0, 0, -k / m, -b / m]],
                 dtype=float)
    B = np.array([[0, 0], [1, 1 / m_p], [0, 0], [0, 1 / m]], dtype=float)
    Phi, Gam = _zoh(A, B, Ts)
    # sample: f_m = alpha f_prev + (1 - alpha)(k_e x + d_e v)  -> row over (x, v, xa, va, f_prev)
    fm = np.array([(1 - alpha) * k_e, (1 - alpha) * d_e, 0, 0, alpha])
    # reference deviation: TMT dx_r = dx - df_m/k_e ; known: 0 ; plus f_d input
    e_x = np.array([1.0, 0, 0, 0, 0])
    xr = (e_x - fm / k_e) if law == "tmt" else np.zeros(5)
    # x_r sensitivity to f_d at the equilibrium: d/df_d [f_d/k + f_d x/f_m] = 1/k + 1/k_e
    xr_fd = 1 / k + 1 / k_e
    aa = (fm - b * np.array([0, 0, 0, 1.0, 0]) - k * np.array([0, 0, 1.0, 0, 0])) / m  # x_a''
    xc = xr - np.array([0, 0, 1.0, 0, 0])
    dxc = -np.array([0, 0, 0, 1.0, 0])
    U = -aa + kd * (dxc - np.array([0, 1.0, 0, 0, 0])) + kp * (xc - e_x)
    U_fd = kp * xr_fd
    Ad = np.zeros((5, 5))
    Bd = np.zeros((5, 1))
    Ad[:4] = Phi @ np.vstack([np.eye(5)[:4]]) + Gam @ np.vstack([U, fm])
    Bd[:4, 0] = Gam @ np.array([U_fd, 0.0])
    Ad[4] = fm
    C = np.array([[k_e, d_e, 0, 0, 0]])
    sys = ct.ss(Ad, Bd, C, [[0.0]], Ts, inputs="f_d", outputs="f_e",
                states=["x", "dx", "xa", "dxa", "f_m"])
    rho = float(np.max(np.abs(np.linalg.eigvals(Ad))))
    return SampledModel(Ts, k_e, sys, rho, {"m": m, "b": b, "k": k, "m_p": m_p, "kd": kd, "kp": kp,
                                             "law": law, "alpha": alpha, "d_e": d_e})


def spectral_radius(m, b, k, k_e, Ts, m_p, **kw) -> float:
    """Largest eigenvalue magnitude of the sampled closed loop (< 1: stable)."""
    return sampled_closed_loop(m, b, k, k_e, Ts, m_p, **kw).spectral_radius


def max_stable_stiffness(m, b, k, Ts, m_p, k_lo=1.0, k_hi=1e10, **kw) -> float:
    """Largest k_e for which the sampled loop is stable at Ts (N/m).

    Scans a log grid from ``k_lo`` for the first unstable stiffness, then
    bisects (relative precision 1e-6). Returns ``inf`` if stable up to
    ``k_hi`` and 0 if unstable already at ``k_lo``."""
    grid = np.geomspace(k_lo, k_hi, 121)
    rho = [spectral_radius(m, b, k, ke, Ts, m_p, **kw) for ke in grid]
    unstable = [i for i, r in enumerate(rho) if r >= 1.0]
    if not unstable:
        return float("inf")
    i = unstable[0]
    if i == 0:
        return 0.0
    lo, hi = grid[i - 1], grid[i]
    while hi / lo > 1 + 1e-6:
        mid = math.sqrt(lo * hi)
        if spectral_radius(m, b, k, mid, Ts, m_p, **kw) < 1.0:
            lo = mid
        else:
            hi = mid
    return float(lo)


def stability_region(m, b, k, m_p, Ts_grid, k_e_grid, **kw) -> np.ndarray:
    """Spectral radius on a grid: array (len(k_e_grid), len(Ts_grid))."""
    return np.array([[spectral_radius(m, b, k, ke, Ts, m_p, **kw) for Ts in Ts_grid]
                     for ke in k_e_grid])


def switch_response(m, b, k, k_old, k_new, Ts, m_p, f_d=10.0, duration=4.0, **kw) -> dict:
    """Predicted force after a stiffness switch k_old -> k_new at a sample.

    Starts from the equilibrium for k_old (x = f_d/k_old, x_a = f_d/k, at
    rest) and runs the linear sampled model for k_new. Returns time, force,
    overshoot % (peak over f_d), 2 % settling time and ``contact_lost`` (the
    linear prediction went below zero force, where the unilateral contact
    makes it invalid)."""
    model = sampled_closed_loop(m, b, k, k_new, Ts, m_p, **kw)
    A, C = model.sys.A, model.sys.C
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
    from .metrics import settling_time

    t = np.arange(n) * Ts
    return {"time": t, "force": f, "overshoot_pct": max(0.0, (f.max() - f_d) / f_d * 100),
            "settling_time": settling_time(f - f_d, 0.02 * f_d, t), "contact_lost": bool(f.min() < 0),
            "model": model}


# -- one call for the CLI and the report ----------------------------------------

def scenario_parameters(scenario) -> dict:
    """Normal-axis parameters of a scenario for the analysis: m, b, k, f_d, the
    stiffness range of its profile, Ts, the inner-loop gains, the force filter
    pole, and the robot's effective normal mass along the path (min and max)."""
    from .environment import stiffness_samples, task_frame
    from .robot import Puma560
    from .simulate import check_path

    sc = scenario
    robot = Puma560(armature=sc.robot.armature, friction=False)
    path = check_path(robot, sc, n=73)
    n = task_frame(sc.environment.tilt_deg)[:, 0]
    masses = [effective_mass(np.asarray(robot.cartesian_inertia(q)), n) for q in path.q.T]
    t = np.arange(0.0, sc.duration, sc.controller.Ts)
    k_e = stiffness_samples(sc.environment.stiffness, t, sc.trajectory.period)
    kd, kp = sc.impedance.gains
    fc = sc.sensor.filter_cutoff
    return {"m": sc.impedance.m[0], "b": sc.impedance.b[0], "k": sc.impedance.k[0],
            "f_d": sc.controller.f_d, "k_e_min": float(k_e.min()), "k_e_max": float(k_e.max()),
            "k_e_values": sorted({float(v) for v in k_e}) if len(set(k_e)) <= 20 else [],
            "Ts": sc.controller.Ts, "kd": kd[0], "kp": kp[0],
            "alpha": float(np.exp(-2 * np.pi * fc * sc.controller.Ts)) if fc > 0 else 0.0,
            "d_e": sc.environment.damping, "m_p_min": min(masses), "m_p_max": max(masses),
            "law": sc.controller.law}


def paper_effective_mass() -> float:
    """Smallest effective normal mass along the paper scenario's path, kg
    (the default ``m_p`` of the sampled-data analysis)."""
    from .scenario import paper_scenario

    return scenario_parameters(paper_scenario())["m_p_min"]


def analyze(m, b, k, f_d=10.0, k_e=None, k_e_min=None, k_e_max=None, Ts=None, m_p=None,
            kd=None, kp=None, alpha=0.0, d_e=0.0, law="tmt") -> dict:
    """Everything ``tmtcontrol analyze`` reports, as a dict of plain values
    (the python-control objects under ``"systems"``).

    Give either ``k_e`` or ``k_e_min`` and ``k_e_max`` (N/m). With ``Ts`` (s)
    the sampled-data analysis is added; ``m_p`` (kg) is the robot's effective
    normal mass, a number or a (min, max) pair (default: the paper path's
    minimum)."""
    _check(m, b, k, None, f_d)
    if (k_e is None) == (k_e_min is None and k_e_max is None):
        raise AnalysisError("k_e: give either k_e or both k_e_min and k_e_max")
    if k_e is not None:
        cont = analyze_continuous(m, b, k, k_e, f_d)
        out = cont.as_dict()
        out["systems"] = {"tf": cont.tf, "ss": cont.ss}
        lo = hi = k_e
    else:
        if k_e_min is None or k_e_max is None:
            raise AnalysisError("k_e_min/k_e_max: give both ends of the stiffness range")
        rng = analyze_range(m, b, k, k_e_min, k_e_max, f_d)
        out = rng.as_dict()
        out["systems"] = {"tf": rng.at_max.tf, "ss": rng.at_max.ss, "tf_min": rng.at_min.tf}
        lo, hi = k_e_min, k_e_max
    if Ts is not None:
        _pos("Ts", Ts)
        if m_p is None:
            m_p = paper_effective_mass()
        masses = tuple(m_p) if isinstance(m_p, (tuple, list)) else (m_p,)
        for v in masses:
            _pos("m_p", v)
        kw = {"kd": kd, "kp": kp, "alpha": alpha, "d_e": d_e, "law": law}
        limit = min(max_stable_stiffness(m, b, k, Ts, mp, **kw) for mp in masses)
        grid = np.geomspace(lo, hi, 25) if hi > lo else np.array([lo])   # ends included exactly
        rho = max(spectral_radius(m, b, k, ke, Ts, mp, **kw) for ke in grid for mp in masses)
        out.update({"Ts": Ts, "m_p": list(masses), "max_stable_stiffness": limit,
                    "spectral_radius": rho, "sampled_stable": bool(rho < 1.0 and hi < limit)})
        out["systems"]["sampled"] = sampled_closed_loop(m, b, k, hi, Ts, min(masses), **kw).sys
    return out


def analysis_kwargs(p: dict) -> dict:
    """:func:`analyze` keywords for a scenario's :func:`scenario_parameters`:
    its normal axis, stiffness range (a single k_e if constant), Ts, gains,
    force filter and the path's effective masses."""
    kw = dict(m=p["m"], b=p["b"], k=p["k"], f_d=p["f_d"], Ts=p["Ts"], kd=p["kd"], kp=p["kp"],
              alpha=p["alpha"], d_e=p["d_e"], law=p["law"], m_p=(p["m_p_min"], p["m_p_max"]))
    if p["k_e_min"] == p["k_e_max"]:
        kw["k_e"] = p["k_e_min"]
    else:
        kw.update(k_e_min=p["k_e_min"], k_e_max=p["k_e_max"])
    return kw


def format_analysis(d: dict) -> str:
    """The analysis as a readable table."""
    yes = lambda v: "yes" if v else "NO"
    rows = []
    if "k_e_min" in d:
        rows.append(f"stiffness range      {d['k_e_min']:.6g} .. {d['k_e_max']:.6g} N/m "
                    "(scalars below at k_e_max)")
    else:
        rows.append(f"stiffness            {d['k_e']:.6g} N/m")
    rows += [
        f"impedance            m = {d['m']:g} kg, b = {d['b']:g} N s/m, k = {d['k']:g} N/m, f_d = {d['f_d']:g} N",
        "poles (eq. 22)       " + ", ".join(f"{re:.4g}{im:+.4g}j" for re, im in d["poles"]),
        f"natural frequency    {d['natural_frequency']:.4g} rad/s",
        f"damping ratio        {d['damping_ratio']:.4g}",
        f"BIBO stable          {yes(d['bibo_stable'])}",
        f"steady-state force   {d['steady_state_force']:.6g} N (eqs. 23-24: f_e = f_d)",
        f"critical damping     b >= {d['critical_damping']:.4g} N s/m (eq. 25)",
        f"step: overshoot      {d['overshoot_pct']:.3g} %, settling (2 %) {d['settling_time']:.4g} s",
    ]
    if "worst_damping_ratio" in d:
        rows += [f"worst damping ratio  {d['worst_damping_ratio']:.4g} (at k_e_max)",
                 f"stable for all k_e   {yes(d['stable_for_all'])}",
                 f"b for zeta >= 1      {d['b_for_critical_damping_over_range']:.4g} N s/m over the range; "
                 f"then settling at k_e_min {d['slowest_settling_with_that_b']:.4g} s"]
    if "Ts" in d:
        rows += [f"sampled at Ts        {d['Ts']:g} s, m_p = {', '.join(f'{v:.4g}' for v in d['m_p'])} kg",
                 f"max stable k_e       {d['max_stable_stiffness']:.6g} N/m",
                 f"spectral radius      {d['spectral_radius']:.6f}",
                 f"sampled stable       {yes(d['sampled_stable'])}"]
    return "\n".join(rows)
