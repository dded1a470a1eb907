"""Force- and position-tracking metrics of a simulation, per stiffness segment.

A segment is a run of constant stiffness (a piecewise-constant profile, as in
Fig. 3) or, for continuously varying profiles, one cycle of the path. Forces
in N, times in s, positions in m.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from .simulator import SimulationResult

__all__ = ["SegmentMetrics", "segments", "segment_metrics", "settling_time", "format_table"]

STEADY_FRACTION = 0.25
"""The last quarter of a segment is its steady state."""


@dataclass(frozen=True)
class SegmentMetrics:
    """Metrics of one segment.

    ``overshoot_pct`` is ``(peak - f_d)/f_d * 100`` (0 if the force never
    exceeds f_d); ``settling_time`` is measured from the segment start until
    |f_e - f_d| stays within 2 % of f_d (NaN if it never does);
    ``settling_time_10mN`` the same for the 0.01 N band; the steady-state
    error is the mean of f_e - f_d and the tangential RMS the RMS distance
    between X and X_r in the plane, both over the last quarter.
    """
    start: float
    end: float
    stiffness: float
    steady_state_error: float
    peak_force: float
    min_force: float
    overshoot_pct: float
    settling_time: float
    settling_time_10mN: float
    max_steady_error: float
    tangential_rms: float
    contact_lost_steady: bool

    def as_dict(self) -> dict:
        return {k: (None if isinstance(v, float) and not np.isfinite(v) else v)
                for k, v in asdict(self).items()}


def segments(result: SimulationResult) -> list[tuple[int, int]]:
    """Index ranges [i0, i1) of the segments."""
    k = result.stiffness
    edges = np.flatnonzero(np.diff(k) != 0) + 1
    if result.scenario.environment.stiffness.kind == "piecewise_constant" or len(edges) <= 50:
        bounds = np.r_[0, edges, k.size]
    else:
        per = int(round(result.scenario.trajectory.period / result.Ts))
        bounds = np.r_[np.arange(0, k.size, per), k.size]
    return [(int(a), int(b)) for a, b in zip(bounds[:-1], bounds[1:]) if b > a]


def settling_time(err: np.ndarray, band: float, t: np.ndarray) -> float:
    """Time from ``t[0]`` after which ``|err| <= band`` for good: 0 if always
    inside, NaN if still outside at the last sample."""
    outside = np.flatnonzero(np.abs(err) > band)
    if outside.size == 0:
        return 0.0
    last = outside[-1]
    return float(t[last + 1] - t[0]) if last + 1 < t.size else float("nan")


def segment_metrics(result: SimulationResult) -> list[SegmentMetrics]:
    """:class:`SegmentMetrics` for every segment of ``result``."""
    out = []
    f_d = float(result.desired_force[0])
    for i0, i1 in segments(result):
        t = result.time[i0:i1]
        f = result.contact_force[i0:i1]
        err = result.force_error[i0:i1]
        ss = slice(int((i1 - i0) * (1 - STEADY_FRACTION)), i1 - i0)
        dt = result.position_task[1:, i0:i1] - result.reference_task[1:, i0:i1]
        tang = np.sqrt(np.mean(np.sum(dt[:, ss] ** 2, axis=0)))
        peak = float(f.max())
        out.append(SegmentMetrics(
            start=float(t[0]), end=float(t[-1] + result.Ts),
            stiffness=float(np.mean(result.stiffness[i0:i1])),
            steady_state_error=float(np.mean(err[ss])),
            peak_force=peak, min_force=float(f.min()),
            overshoot_pct=max(0.0, (peak - f_d) / f_d * 100.0),
            settling_time=settling_time(err, 0.02 * f_d, t),
            settling_time_10mN=settling_time(err, 0.01, t),
            max_steady_error=float(np.abs(err[ss]).max()),
            tangential_rms=float(tang),
            contact_lost_steady=bool(np.any(f[ss] <= 0.0)),
        ))
    return out


def format_table(metrics: list[SegmentMetrics]) -> str:
    """A plain-text table of the per-segment metrics."""
    head = (f"{'segment':>7} {'t (s)':>11} {'k_e (N/m)':>10} {'ss err (N)':>11} {'peak (N)':>9} "
            f"{'overshoot':>9} {'settle 2% (s)':>13} {'tang RMS (mm)':>13}")
    rows = [head, "-" * len(head)]
    for i, m in enumerate(metrics, 1):
        settle = f"{m.settling_time:.3f}" if np.isfinite(m.settling_time) else "never"
        rows.append(f"{i:>7} {m.start:>5.1f}-{m.end:<5.1f} {m.stiffness:>10.4g} "
                    f"{m.steady_state_error:>11.2e} {m.peak_force:>9.2f} {m.overshoot_pct:>8.1f}% "
                    f"{settle:>13} {m.tangential_rms * 1e3:>13.4f}")
    return "\n".join(rows)
