"""Force- and position-tracking metrics of a simulation, per stiffness segment, and its verdicts.

A segment is a run of constant stiffness (a piecewise-constant profile, as in
Fig. 3), the span between two knots of a piecewise-linear or table profile
(a ramp or a hold; a knot pair closer than :data:`STEP_SAMPLES` samples is
one step), or, for a sinusoidal profile, one cycle of the path. Forces in N,
times in s, positions in m.

Verdicts (:data:`VERDICTS`, best first) judge each segment's force error
e = f_e - f_d against the scenario's tracking tolerance
(``controller.force_tolerance``, N) and its growth over whole periods of the
forcing (the path and a sinusoidal stiffness), never over fractions of one:

* ``converged``: stable (neither of the last two), |e| within the
  tolerance (plus 6 sensor-noise standard deviations, the ripple the noise
  itself drives) over the segment's last quarter, and the mean of e there
  within the tolerance alone (noise averages out of a mean, a bias does not:
  a large sensor noise cannot hide a bias), widened only by the mean's own
  sampling uncertainty under sensor noise (:data:`BIAS_BATCHES` batch means,
  a Student-t bound at :data:`BIAS_FALSE_ALARM`), so a noisy but unbiased
  run is not called off target by chance;
* ``off_target``: stable (not growing, contact kept), but not within the
  tolerance at its end: a bias (wrong x_e, wrong assumed k_e), a slow drift, a
  forced response to a varying stiffness, or a transient still decaying;
* ``limit_cycle``: the contact is lost in the last quarter, or an oscillation
  above the ripple band that does not decay and is not the periodic response
  to the forcing;
* ``diverged``: a force that is not finite, or an oscillation growing by more
  than 1.5x from one judging window to the next.
"""

from __future__ import annotations

import functools
import math
from dataclasses import asdict, dataclass

import numpy as np

from .scenario import read_stiffness_table
from .simulator import SimulationResult

__all__ = ["SegmentMetrics", "segments", "segment_metrics", "settling_time", "format_table", "segment_verdict",
           "judge_segment", "judging_periods", "bias_allowance", "VERDICTS", "FirstContact", "first_contact", "FIRST_CONTACT_WINDOW"]

VERDICTS = ("converged", "off_target", "limit_cycle", "diverged")
"""Per-segment verdicts, best first (see the module docstring)."""

STEADY_FRACTION = 0.25
"""The last quarter of a segment is its steady state."""

RIPPLE_BAND = 0.01
"""Peak-to-peak force oscillation, as a fraction of f_d, below which a
segment has no oscillation to judge (plus 6 sensor-noise standard
deviations)."""

NOISE_SIGMAS = 6.0
"""Sensor-noise standard deviations added to the ripple band and to the
tracking tolerance (a Gaussian sample exceeds 6 sigma once in 1e9)."""

GROWTH = 1.5
"""An oscillation growing by more than this factor from one judging window to
the next is ``diverged``."""

SUSTAINED = 0.95
"""An oscillation keeping at least this fraction of its amplitude from one
judging window to the next does not decay (``limit_cycle``, unless it is the
periodic response to the forcing)."""

FORCED = 0.2
"""An oscillation that repeats from one whole forcing period to the next
within this fraction of its amplitude is the forced response (stable)."""

REPEAT_GROWTH = 0.02
"""A window that repeats the previous one scaled by more than 1 + this (the
least-squares gain of e_B on e_A, means removed) grows: not the forced
response, whose windows repeat at gain 1 (an oscillation whose period
divides the window, e.g. the sampled loop's Nyquist mode, growing up to
1.67x per window passed the repeat test alone)."""

STEP_SAMPLES = 10
"""Knots of a piecewise-linear or table profile closer than this many samples
to the previous segment boundary make one step (the later knot starts the
segment)."""

MAX_KNOT_SEGMENTS = 50
"""A piecewise-linear or table profile with more knots than this in the run
is cut per path period instead (a densely sampled smooth profile)."""


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
    * ``stiffness``: the mean k_e over the segment (N/m);
    * ``contact_lost_steady``: f_e <= 0 somewhere in the last quarter;
    * ``contact_lost_time``: how long f_e <= 0 after the segment's first
      sample in contact (s; the whole segment if it never touches): the
      contact an upward stiffness switch loses, behind an overshoot of
      100 % (the force fell to zero);
    * ``tolerance``: the tracking tolerance the verdict used (N, the
      scenario's ``controller.force_tolerance`` plus 6 noise sigmas);
    * ``verdict``: :func:`judge_segment`; ``reason``: why, in words.
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
    tolerance: float = math.nan
    reason: str = ""

    def as_dict(self) -> dict:
        return {k: (None if isinstance(v, float) and not np.isfinite(v) else v)
                for k, v in asdict(self).items()}


def _knot_times(profile) -> np.ndarray | None:
    if profile.kind == "piecewise_linear":
        return np.asarray(profile.times, dtype=float)
    if profile.kind == "table":
        return np.asarray(read_stiffness_table(profile.file)[0], dtype=float)
    return None


def segments(result: SimulationResult) -> list[tuple[int, int]]:
    """Index ranges [i0, i1) of the segments: at the value changes of a
    piecewise-constant profile, at the knots of a piecewise-linear or table
    profile (a knot pair within :data:`STEP_SAMPLES` samples is one step, at
    the later knot), per path period otherwise."""
    k = result.stiffness
    n = k.size
    profile = result.scenario.environment.stiffness
    knots = _knot_times(profile)
    if knots is not None:
        idx = np.ceil(knots / result.Ts - 1e-9).astype(int)
        idx = idx[(idx > 0) & (idx < n)]
        if idx.size <= MAX_KNOT_SEGMENTS:
            kept = [0]
            for i in idx:
                if i - kept[-1] < STEP_SAMPLES and kept[-1] > 0:
                    kept[-1] = int(i)                  # a step: the later knot starts the segment
                elif i - kept[-1] >= STEP_SAMPLES:
                    kept.append(int(i))
            bounds = np.r_[kept, n]
            return [(int(a), int(b)) for a, b in zip(bounds[:-1], bounds[1:]) if b > a]
    edges = np.flatnonzero(np.diff(k) != 0) + 1
    if profile.kind == "piecewise_constant" or (knots is None and len(edges) <= 50):
        bounds = np.r_[0, edges, n]
    else:
        per = int(round(result.scenario.trajectory.period / result.Ts))
        bounds = np.r_[np.arange(0, n, per), n]
    return [(int(a), int(b)) for a, b in zip(bounds[:-1], bounds[1:]) if b > a]


def settling_time(err: np.ndarray, band: float, t: np.ndarray) -> float:
    """Time from ``t[0]`` after which ``|err| <= band`` for good: 0 if always
    inside, NaN if still outside at the last sample."""
    outside = np.flatnonzero(np.abs(err) > band)
    if outside.size == 0:
        return 0.0
    last = outside[-1]
    return float(t[last + 1] - t[0]) if last + 1 < t.size else float("nan")


def judging_periods(result: SimulationResult) -> tuple[int, ...]:
    """The periods of the forcing, in samples, in the order the verdict tries
    them: their common period (the path and a sinusoidal stiffness), the
    stiffness' period, the path's (a circle of radius > 0)."""
    sc = result.scenario
    per = []
    prof = sc.environment.stiffness
    if prof.kind == "sinusoidal":
        per.append(int(round(prof.period / result.Ts)))
    if sc.trajectory.radius > 0:
        per.append(int(round(sc.trajectory.period / result.Ts)))
    per = [p for p in per if p >= 2]
    if len(per) == 2:
        per.insert(0, math.lcm(*per))
    return tuple(dict.fromkeys(per))


def _amplitude(e: np.ndarray) -> float:
    """The oscillation of ``e``: the largest swing between two consecutive
    local extrema (N); 0 for a monotone signal or one with a single extremum
    (a drift or a lag is not an oscillation, however curved)."""
    d = np.diff(e)
    d = d[d != 0.0]
    turns = np.flatnonzero(d[:-1] * d[1:] < 0)
    if turns.size < 2:
        return 0.0
    # the extreme values: e at the turning points (cumulated differences from e[0])
    v = e[0] + np.cumsum(d)[turns]
    return float(np.max(np.abs(np.diff(v))))


def _gain(e_A: np.ndarray, e_B: np.ndarray) -> float:
    """The least-squares gain g of ``e_B ~ g e_A`` (means removed): 1 for a
    repeat, above 1 for growth, below for decay."""
    a, b = e_A - np.mean(e_A), e_B - np.mean(e_B)
    aa = float(a @ a)
    return float(a @ b) / aa if aa > 0.0 else 0.0


BIAS_BATCHES = 20
"""Batches of the last quarter whose means estimate the standard error of
the mean force error under sensor noise (the batch-means method: batches of
50 samples for a 4 s segment at 1 kHz, longer than the loop's correlation
time, so the batch means are nearly independent)."""
BIAS_FALSE_ALARM = 1e-3
"""Chance that an unbiased noisy segment is called off target by its mean:
the bias allowance is the two-sided Student-t quantile (BIAS_BATCHES - 1
degrees of freedom) times the batch-means standard error."""


def bias_allowance(e: np.ndarray) -> float:
    """The sampling uncertainty of ``mean(e)`` (N) allowed on top of the bias
    tolerance under sensor noise: t_(1 - BIAS_FALSE_ALARM/2, B-1) x
    std(batch means)/sqrt(B), B = :data:`BIAS_BATCHES`; 0 for fewer than
    2 B samples."""
    e = np.asarray(e, dtype=float)
    B = BIAS_BATCHES
    if e.size < 2 * B:
        return 0.0
    means = e[:e.size - e.size % B].reshape(B, -1).mean(axis=1)
    return float(_t_quantile(1.0 - BIAS_FALSE_ALARM / 2, B - 1) * np.std(means, ddof=1) / math.sqrt(B))


@functools.lru_cache(maxsize=4)
def _t_quantile(p: float, dof: int) -> float:
    from scipy.stats import t

    return float(t.ppf(p, dof))


def judge_segment(force: np.ndarray, f_d: float, band: float, tolerance: float,
                  periods: tuple[int, ...] = (), Ts: float = 1.0,
                  bias_tolerance: float | None = None, noisy: bool = False) -> tuple[str, str]:
    """``(verdict, reason)`` for one segment's force (N) against f_d (N).

    ``band`` (N): the oscillation (peak-to-peak) that counts as none;
    ``tolerance`` (N): the largest |f_e - f_d| over the last quarter for
    ``converged`` (the caller adds the sensor noise to both);
    ``bias_tolerance`` (N): the largest |mean(f_e - f_d)| over the last
    quarter for ``converged`` (default ``tolerance``; the caller passes the
    scenario's tolerance without the noise allowance), widened by
    :func:`bias_allowance` when ``noisy`` (the run has sensor noise);
    ``periods``: the forcing's periods in samples (:func:`judging_periods`);
    ``Ts`` (s) only for the words of the reason.

    Growth is judged between two consecutive windows A, B at the segment's
    end, each a whole number of periods of the first of ``periods`` that the
    segment holds twice (as many whole periods as fit in its last quarter,
    at least one); with no such period (no forcing, or a segment shorter than
    two periods), the two halves of the last quarter. With a_A, a_B the
    oscillation in each (the largest swing between consecutive extrema):
    ``diverged`` if a_B > band and a_B > 1.5 a_A; ``limit_cycle`` if the
    contact is lost in the last
    quarter, or a_B > band, a_B >= 0.95 a_A and B does not repeat A (whole
    periods only: max |e_B - e_A| > 0.2 a_B, or B is A grown by more
    than 2 % (:data:`REPEAT_GROWTH`); a repeat is the forced
    response); otherwise stable: ``converged`` if max |e| over the last
    quarter <= ``tolerance``, else ``off_target``. A segment of fewer than
    16 samples is judged by the tolerance alone.
    """
    force = np.asarray(force, dtype=float)
    if not np.all(np.isfinite(force)):
        return "diverged", "the force is not finite"
    n = force.size
    last = force[int(n * (1 - STEADY_FRACTION)):]
    e = force - f_d
    if last.size < 4:           # too short for two windows: the tolerance alone, over the whole segment
        worst = float(np.max(np.abs(e))) if n else 0.0
        return (("converged", f"|f_e - f_d| <= {worst:.3g} N (a segment of {n} samples)") if worst <= tolerance
                else ("off_target", f"|f_e - f_d| up to {worst:.3g} N (tolerance {tolerance:.3g} N, a segment of "
                                    f"{n} samples: too short to judge growth)"))
    if np.any(last <= 0.0):
        return "limit_cycle", "the contact is lost in the last quarter"
    P = next((p for p in periods if n >= 2 * p), None)
    W = P * max(1, (n // 4) // P) if P else max(2, last.size // 2)
    e_A, e_B = e[n - 2 * W:n - W], e[n - W:]
    a_A, a_B = _amplitude(e_A), _amplitude(e_B)
    over = f"{W * Ts:.3g} s" + (" (whole periods)" if P else "")
    if a_B > band and a_B > GROWTH * a_A:
        return "diverged", f"oscillation grows {a_B / max(a_A, 1e-300):.3g}x over {over}"
    forced = (P is not None and float(np.max(np.abs(e_B - e_A))) <= FORCED * a_B
              and _gain(e_A, e_B) <= 1.0 + REPEAT_GROWTH)
    if a_B > band and a_B >= SUSTAINED * a_A and not forced:
        return "limit_cycle", f"oscillation of {a_B:.3g} N peak-to-peak does not decay over {over}"
    worst = float(np.max(np.abs(e[n - last.size:])))
    bias = float(np.mean(e[n - last.size:]))
    if bias_tolerance is None:
        bias_tolerance = tolerance
    if noisy:
        bias_tolerance += bias_allowance(e[n - last.size:])
    if worst <= tolerance and abs(bias) <= bias_tolerance:
        return "converged", f"|f_e - f_d| <= {worst:.3g} N at the end"
    if worst <= tolerance:
        return "off_target", (f"a bias of {bias:+.3g} N over the last quarter (tolerance {bias_tolerance:.3g} N; "
                              f"|f_e - f_d| <= {worst:.3g} N is within the noise allowance)")
    if forced:
        why = f"a periodic forced response of {a_B:.3g} N peak-to-peak"
    elif a_B > band:
        why = f"still decaying ({a_B / max(a_A, 1e-300):.3g}x over {over})"
    else:
        drift = float(np.mean(e_B) - np.mean(e_A))
        why = f"a bias of {float(np.mean(e_B)):+.3g} N" + (f", drifting {drift:+.3g} N over {over}"
                                                          if abs(drift) > 0.1 * tolerance else "")
    return "off_target", f"|f_e - f_d| up to {worst:.3g} N at the end (tolerance {tolerance:.3g} N): {why}"


def segment_verdict(force: np.ndarray, f_d: float, band: float, tolerance: float = 0.01,
                    periods: tuple[int, ...] = ()) -> str:
    """The verdict of :func:`judge_segment` alone (``tolerance`` in N, the
    scenario key's default 0.01 N)."""
    return judge_segment(force, f_d, band, tolerance, periods)[0]


def segment_metrics(result: SimulationResult) -> list[SegmentMetrics]:
    """:class:`SegmentMetrics` for every segment of ``result``."""
    out = []
    sc = result.scenario
    f_d = sc.controller.f_d
    noise = NOISE_SIGMAS * sc.sensor.noise_std
    band = RIPPLE_BAND * f_d + noise
    tol = sc.controller.force_tolerance + noise
    periods = judging_periods(result)
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
        verdict, reason = judge_segment(f, f_d, band, tol, periods, result.Ts,
                                        bias_tolerance=sc.controller.force_tolerance, noisy=sc.sensor.noise_std > 0)
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
            verdict=verdict, tolerance=tol, reason=reason,
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
    """A plain-text table of the per-segment metrics, with the tracking
    tolerance each verdict used: one unit per column (in its header), every
    number of a column to the same significant digits, thousands separated
    (``fmt.column``)."""
    from .. import fmt

    def col(name, values, unit, sig=3, nan="never"):
        unit, cells = fmt.column(values, unit, sig)
        return (f"{name} ({unit})" if unit else name, [nan if c == "–" else c for c in cells])

    return fmt.text_table([
        ("segment", [str(i) for i in range(1, len(metrics) + 1)]),
        ("t (s)", [f"{fmt.num(m.start)}–{fmt.num(m.end)}" for m in metrics]),
        col("k_e", [m.stiffness for m in metrics], "N/m", 4),
        col("ss err", [m.steady_state_error for m in metrics], "N"),
        col("peak", [m.peak_force for m in metrics], "N"),
        col("jump", [m.switch_jump for m in metrics], "N"),
        col("overshoot", [m.overshoot_pct for m in metrics], "%"),
        col("settle 2 %", [m.settling_time for m in metrics], "s"),
        col("tang RMS", [m.tangential_rms for m in metrics], "m"),
        col("tol", [m.tolerance for m in metrics], "N"),
        ("verdict", [m.verdict for m in metrics])])
