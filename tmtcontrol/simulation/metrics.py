"""Force- and position-tracking metrics of a simulation, per stiffness segment.

A segment is a run of constant stiffness (a piecewise-constant profile, as in
Fig. 3) or, for continuously varying profiles, one cycle of the path. Forces
in N, times in s, positions in m.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from .simulator import SimulationResult

__all__ = ["SegmentMetrics", "segments", "segment_metrics", "settling_time", "format_table", "segment_verdict",
           "VERDICTS", "FirstContact", "first_contact", "FIRST_CONTACT_WINDOW"]

VERDICTS = ("converged", "limit_cycle", "diverged")
"""Per-segment verdicts, best first."""

STEADY_FRACTION = 0.25
"""The last quarter of a segment is its steady state."""

RIPPLE_BAND = 0.01
"""Peak-to-peak force ripple, as a fraction of f_d, below which a segment's
steady state counts as settled (plus 6 sensor-noise standard deviations)."""


@dataclass(frozen=True)
class SegmentMetrics:
    """Metrics of one segment (forces N, times s, positions m).

    * ``switch_jump``: the force step at the segment's first sample (the
      stiffness switch acting on the current penetration, which no
      controller can avoid; for the first segment, the force there);
    * ``overshoot_pct``: the controller's overshoot after it, relative to
      f_d: if the force starts above f_d, how far it then dips below f_d;
      otherwise how far it rises above f_d (0 if it never crosses);
    * ``settling_time`` / ``settling_time_10mN``: from the segment start
      until |f_e - f_d| stays within 2 % of f_d / within 0.01 N (NaN: never);
    * ``steady_state_error``: the largest |f_e - f_d| over the last quarter,
      ``steady_rms_error`` its RMS; ``max_steady_error`` = the former (kept
      for older summaries); ``tangential_rms``: RMS distance between X and
      X_r in the surface plane over the last quarter;
    * ``contact_lost_steady``: f_e <= 0 somewhere in the last quarter;
    * ``contact_lost_time``: how long f_e <= 0 after the segment's first
      sample in contact (s; the whole segment if it never touches): the
      contact an upward stiffness switch loses, behind an overshoot of
      100 % (the force fell to zero);
    * ``verdict``: :func:`segment_verdict`.
    """
    start: float
    end: float
    stiffness: float
    steady_state_error: float
    steady_rms_error: float
    peak_force: float
    min_force: float
    switch_jump: float
    overshoot_pct: float
    settling_time: float
    settling_time_10mN: float
    max_steady_error: float
    tangential_rms: float
    contact_lost_steady: bool
    contact_lost_time: float
    verdict: str

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


def segment_verdict(force: np.ndarray, f_d: float, band: float) -> str:
    """``converged``, ``limit_cycle`` or ``diverged`` for one segment's force.

    The last quarter is split in halves A and B; with the peak-to-peak
    amplitudes a_A, a_B of the force in each:

    * ``limit_cycle`` if the contact is lost (f_e <= 0) anywhere in the last
      quarter, or if a_B > ``band`` and a_B >= 0.8 a_A (a sustained
      oscillation);
    * ``diverged`` if a_B > ``band`` and a_B > 1.5 a_A (growing), or any
      force is not finite;
    * ``converged`` otherwise: settled (a_B <= band), or decaying (an
      oscillation near the stability limit may still be above the band; its
      ``steady_state_error`` says how far).

    ``band`` (N) is the ripple that counts as settled (the caller adds the
    sensor noise to it).
    """
    if not np.all(np.isfinite(force)):
        return "diverged"
    n = force.size
    last = force[int(n * (1 - STEADY_FRACTION)):]
    if last.size < 4:
        return "converged"
    if np.any(last <= 0.0):
        return "limit_cycle"
    h = last.size // 2
    a_A, a_B = float(np.ptp(last[:h])), float(np.ptp(last[h:]))
    if a_B > band and a_B > 1.5 * a_A:
        return "diverged"
    if a_B > band and a_B >= 0.8 * a_A:
        return "limit_cycle"
    return "converged"


def segment_metrics(result: SimulationResult) -> list[SegmentMetrics]:
    """:class:`SegmentMetrics` for every segment of ``result``."""
    out = []
    f_d = result.scenario.controller.f_d
    band = RIPPLE_BAND * f_d + 6.0 * result.scenario.sensor.noise_std
    for i0, i1 in segments(result):
        t = result.time[i0:i1]
        f = result.contact_force[i0:i1]
        err = result.force_error[i0:i1]
        ss = slice(int((i1 - i0) * (1 - STEADY_FRACTION)), i1 - i0)
        dt = result.position_task[1:, i0:i1] - result.reference_task[1:, i0:i1]
        tang = np.sqrt(np.mean(np.sum(dt[:, ss] ** 2, axis=0)))
        peak = float(f.max())
        jump = float(f[0] - (result.contact_force[i0 - 1] if i0 > 0 else 0.0))
        after = f[1:] if f.size > 1 else f
        overshoot = (max(0.0, f_d - float(after.min())) if f[0] > f_d else max(0.0, float(after.max()) - f_d))
        ss_err = float(np.abs(err[ss]).max())
        touching = np.flatnonzero(f > 0.0)
        lost = np.count_nonzero(f[touching[0]:] <= 0.0) if touching.size else f.size
        out.append(SegmentMetrics(
            start=float(t[0]), end=float(t[-1] + result.Ts),
            stiffness=float(np.mean(result.stiffness[i0:i1])),
            steady_state_error=ss_err, steady_rms_error=float(np.sqrt(np.mean(err[ss] ** 2))),
            peak_force=peak, min_force=float(f.min()),
            switch_jump=jump, overshoot_pct=overshoot / f_d * 100.0,
            settling_time=settling_time(err, 0.02 * f_d, t),
            settling_time_10mN=settling_time(err, 0.01, t),
            max_steady_error=ss_err,
            tangential_rms=float(tang),
            contact_lost_steady=bool(np.any(f[ss] <= 0.0)),
            contact_lost_time=float(lost * result.Ts),
            verdict=segment_verdict(f, f_d, band),
        ))
    return out


FIRST_CONTACT_WINDOW = 1.0
"""Seconds after the first contact over which its peak and bounces count."""


@dataclass(frozen=True)
class FirstContact:
    """The first contact with the surface (forces N, times s).

    ``time``: first sample with f_e > 0 (None if the run never touches);
    ``peak_force``: the largest f_e within :data:`FIRST_CONTACT_WINDOW` after
    it (and within the first segment), ``peak_ratio`` = peak / f_d;
    ``bounces``: how often the contact is lost again in that window."""
    time: float | None
    peak_force: float
    peak_ratio: float
    bounces: int

    def as_dict(self) -> dict:
        return asdict(self)


def first_contact(result: SimulationResult, window: float = FIRST_CONTACT_WINDOW) -> FirstContact:
    """:class:`FirstContact` of ``result``. A run that starts on the surface
    at zero force touches at its first positive force."""
    f = result.contact_force
    touching = f > 0.0
    if not touching.any():
        return FirstContact(None, 0.0, 0.0, 0)
    i0 = int(np.argmax(touching))
    end = min(segments(result)[0][1], i0 + int(round(window / result.Ts)) + 1)
    w = touching[i0:max(end, i0 + 1)]
    peak = float(f[i0:max(end, i0 + 1)].max())
    return FirstContact(float(result.time[i0]), peak, peak / result.scenario.controller.f_d,
                        int(np.count_nonzero(w[:-1] & ~w[1:])))


def format_table(metrics: list[SegmentMetrics]) -> str:
    """A plain-text table of the per-segment metrics."""
    head = (f"{'segment':>7} {'t (s)':>11} {'k_e (N/m)':>10} {'ss err (N)':>10} {'peak (N)':>9} "
            f"{'jump (N)':>9} {'overshoot':>9} {'settle 2% (s)':>13} {'tang RMS (mm)':>13}  verdict")
    rows = [head, "-" * len(head)]
    for i, m in enumerate(metrics, 1):
        settle = f"{m.settling_time:.3f}" if np.isfinite(m.settling_time) else "never"
        rows.append(f"{i:>7} {m.start:>5.1f}-{m.end:<5.1f} {m.stiffness:>10.4g} "
                    f"{m.steady_state_error:>10.2e} {m.peak_force:>9.2f} {m.switch_jump:>+9.2f} "
                    f"{m.overshoot_pct:>8.1f}% {settle:>13} {m.tangential_rms * 1e3:>13.4f}  {m.verdict}")
    return "\n".join(rows)
