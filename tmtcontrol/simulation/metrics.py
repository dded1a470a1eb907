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
  tolerance over the segment's last quarter, and the mean of e there within
  the tolerance too;
* ``off_target``: stable (not growing, contact kept), but not within the
  tolerance at its end: a bias (wrong x_e, wrong assumed k_e), a slow drift, a
  forced response to a varying stiffness, or a transient still decaying; on
  a 6-D task also a tool orientation error above
  ``controller.orientation_tolerance`` over the last quarter, or the tool's
  axis that far off the true part's normal at the tool point
  (``normal_tilt``: a part displaced by ``controller.part_offset``, or the
  tool point off the commanded one on a curved part); on a surface
  whose chart is approximate (a measured height map:
  ``Surface.chart_error``), also an error that is within the tolerance only
  in the chart, not once the chart's own error (k_e times its depth error;
  its normal's) is added;
* ``over_limit``: a joint torque, joint rate or joint position beyond the
  arm's limit somewhere in the segment (:mod:`.limits`: the robot's own or
  ``robot.tau_max``/``robot.dq_max``, less ``robot.limit_margin``), a
  segment that would otherwise be ``converged`` or ``off_target``: a drive
  faults or clips there, so the run's force says nothing about the robot's;
  the reason names the joint, the value, the limit, when and for how long;
* ``beyond_limit``: when the caller has attached the scenario's stiffness
  limit (``result.info["stiffness_limit"]``, N/m, and where it comes from,
  ``"stiffness_limit_from"``: ``stability.limit.with_stiffness_limit``, the
  limit every command quotes), a segment whose stiffness exceeds it and
  whose force did not show an instability itself (it would be ``converged``
  or ``off_target``): not proven stable there; the run may have ended before
  the growth showed (the reason says what the run itself did);
* ``limit_cycle``: the contact is lost in the last quarter, or an oscillation
  above the ripple band that does not decay and is not the periodic response
  to the forcing, or one that repeats with the forcing but swings by at
  least f_d down to within :data:`NEAR_LOSS` f_d of losing the contact (the
  contact limit cycle of eq. (18) locked to the path, not a forced
  response); an oscillation that shrinks over three judging windows is
  still decaying (``off_target``), not a limit cycle;
* ``diverged``: a force that is not finite, or an oscillation growing by more
  than 1.5x from one judging window to the next.

Sensor noise (``sensor.noise_std`` > 0). The verdict judges the true
contact force, which the noise moves much less than the sensor itself (the
loop filters it). The run's noise-free twin (the same scenario with
``sensor.noise_std = 0``, :func:`noise_free_twin`) separates the two parts:
d = f_e - f_e(no noise) is what the noise did. The segment is judged
twice, and the worse verdict stands, so noise can never make a verdict
better than the noise-free run's:

* the twin against the plain tolerance (a bias, a forced response or a
  decaying transient stays visible however large the noise);
* the noisy run for contact loss, and against the tolerance widened by 6
  standard deviations of d over the last quarter, with the mean of e within
  the tolerance plus :func:`bias_allowance` of d (the mean's own sampling
  uncertainty: batch means, as many batches as the correlation time of d
  allows, a Student-t bound at :data:`BIAS_FALSE_ALARM`), so an unbiased
  noisy run is not called off target by chance, while a mean shift the
  noise itself causes (eq. (18) divides by the noisy force) is judged.
  Growth and sustained oscillation are judged on the twin only: on a noisy
  force the swing between consecutive extrema measures the noise.
"""

from __future__ import annotations

import functools
import math
from dataclasses import asdict, dataclass

import numpy as np

from .limits import limit_use
from .scenario import read_stiffness_table
from .simulator import SimulationResult

__all__ = ["SegmentMetrics", "segments", "segment_metrics", "settling_time", "format_table", "orientation_transient",
           "segment_verdict", "judge_segment", "judging_periods", "bias_allowance", "VERDICTS", "FirstContact",
           "first_contact", "FIRST_CONTACT_WINDOW", "CONTACT_FLOOR", "touching"]

VERDICTS = ("converged", "off_target", "over_limit", "beyond_limit", "limit_cycle", "diverged")
"""Per-segment verdicts, best first (see the module docstring)."""

STEADY_FRACTION = 0.25
"""The last quarter of a segment is its steady state."""

CONTACT_FLOOR = 1e-9
"""A contact force at or below ``f_d`` times this (10 nN at the paper's 10 N)
is rounding, not a touch, for every contact test here (:func:`touching`): a
height map's spline leaves 1e-13 N at a path start that lies on the part
(review 47: "first contact at 0.000 s" where the same analytic sphere read
0.001 s), the UR5 off its part 9.8e-14 N at its start (review 70: "the
contact is lost"); the paper's first step presses 25 mN."""


def touching(force, f_d: float) -> np.ndarray:
    """Where the contact force ``force`` (N) is a touch: above
    :data:`CONTACT_FLOOR` times ``f_d``, the one definition of contact the
    verdicts, the first contact and the contact-lost figures share."""
    return np.asarray(force) > CONTACT_FLOOR * f_d

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

NEAR_LOSS = 0.1
"""A repeating oscillation of at least f_d peak to peak whose force falls
below this fraction of f_d is a contact limit cycle locked to the path, not
a forced response (measured: the UR5 at -10 mm x_e error swings 0.75 <->
20.7 N)."""

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
      f_d is the desired force, 0 during a guarded approach until the first
      contact, but the scenario's f_d in a segment that never touches;
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
      scenario's ``controller.force_tolerance``, plus 6 standard deviations
      of what the sensor noise did to the force under noise);
    * ``verdict``: :func:`judge_segment`, then the limits and the
      orientation (module docstring); ``reason``: why, in words;
    * ``torque_margin`` / ``rate_margin``: the least fraction of a joint's
      torque / rate limit left over the segment (1 - peak/limit; negative:
      over; inf: no limit); ``position_margin``: the least distance of a
      joint to either end of its range (rad; inf: no limits);
      ``orientation_error``: the largest angle between the tool and its
      command over the last quarter (rad; None on a position task: not judged).
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
    torque_margin: float = math.inf
    rate_margin: float = math.inf
    position_margin: float = math.inf
    orientation_error: float | None = None
    tracking_verdict: str = ""
    """The verdict without the arm's limits (the force and the tool's
    orientation alone): what an ``over_limit`` segment's tracking did."""
    chart_force_error: float = 0.0
    """k_e times the surface chart's depth error (N), its largest over the
    last quarter: how far the force against the part's closest point may be
    from the simulated one (0 on an exact chart: ``Surface.chart_error``)."""
    chart_normal_error: float = 0.0
    """The chart's normal error (rad), its largest over the last quarter."""
    normal_tilt: float | None = None
    """The largest angle (rad) over the last quarter between the tool's axis
    and the true part's inward normal at the tool point (None on a position
    task, as ``orientation_error``: not judged): what the orientation error,
    measured against the command on the controller's part, leaves out (a displaced part, the tool point off the
    commanded one on a curved part; review 54)."""
    peak_orientation_error: float | None = None
    """The largest angle (rad) between the tool and its command over the
    whole segment, its transients included (None on a position task):
    shown, not judged (the verdict judges the last quarter); review 62, a
    tool 4.93 mrad off mid-segment with every segment converged at 1 mrad
    (:func:`orientation_transient`)."""

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
"""The most batches of the last quarter whose means estimate the standard
error of the mean under sensor noise (batch-means method). Fewer, longer
batches when the noise-driven force is correlated: each batch spans at
least :data:`BATCH_CORRELATION_TIMES` integrated correlation times (never
fewer than 4 batches), so the batch means are nearly independent."""
BATCH_CORRELATION_TIMES = 4.0
BIAS_FALSE_ALARM = 1e-3
"""Chance that an unbiased noisy segment is called off target by its mean:
the allowance is the two-sided Student-t quantile (batches - 1 degrees of
freedom) times the batch-means standard error."""


def correlation_time(x: np.ndarray, window: float = 5.0) -> float:
    """Integrated autocorrelation time of ``x`` in samples, tau = 1 + 2 sum
    rho_k, summed up to the first lag M >= ``window`` tau(M) (Sokal's
    automatic window); 1 for white noise, at least 1."""
    x = np.asarray(x, dtype=float) - np.mean(x)
    n = x.size
    if n < 4 or not np.any(x):
        return 1.0
    f = np.fft.rfft(x, 2 * n)
    acf = np.fft.irfft(f * np.conj(f))[:n]
    acf = acf / acf[0]
    taus = 2.0 * np.cumsum(acf) - 1.0
    lags = np.arange(n)
    stop = np.flatnonzero(lags >= window * taus)
    return float(max(taus[stop[0]] if stop.size else taus[-1], 1.0))


def bias_allowance(d: np.ndarray) -> float:
    """The sampling uncertainty of ``mean(d)`` (N) allowed on top of the bias
    tolerance under sensor noise, ``d`` the noise-driven part of the force
    error over the last quarter: t_(1 - BIAS_FALSE_ALARM/2, B-1) x
    std(batch means)/sqrt(B), with B = :data:`BIAS_BATCHES` batches, fewer
    (down to 4) when d's :func:`correlation_time` needs longer ones; 0 for
    fewer than 8 samples."""
    d = np.asarray(d, dtype=float)
    if d.size < 8:
        return 0.0
    B = int(np.clip(d.size // (BATCH_CORRELATION_TIMES * correlation_time(d)), 4, BIAS_BATCHES))
    means = d[:d.size - d.size % B].reshape(B, -1).mean(axis=1)
    return float(_t_quantile(1.0 - BIAS_FALSE_ALARM / 2, B - 1) * np.std(means, ddof=1) / math.sqrt(B))


@functools.lru_cache(maxsize=4)
def _t_quantile(p: float, dof: int) -> float:
    from scipy.stats import t

    return float(t.ppf(p, dof))


def judge_segment(force: np.ndarray, f_d: float, band: float, tolerance: float,
                  periods: tuple[int, ...] = (), Ts: float = 1.0,
                  bias_tolerance: float | None = None) -> tuple[str, str]:
    """``(verdict, reason)`` for one segment's force (N) against f_d (N).

    ``band`` (N): the oscillation (peak-to-peak) that counts as none;
    ``tolerance`` (N): the largest |f_e - f_d| over the last quarter for
    ``converged`` (the caller adds the sensor noise to both);
    ``bias_tolerance`` (N): the largest |mean(f_e - f_d)| over the last
    quarter for ``converged`` (default ``tolerance``; the caller passes the
    scenario's tolerance, plus :func:`bias_allowance` under sensor noise);
    ``periods``: the forcing's periods in samples (:func:`judging_periods`);
    ``Ts`` (s) only for the words of the reason.

    Growth is judged between two consecutive windows A, B at the segment's
    end, each a whole number of periods of the first of ``periods`` that the
    segment holds twice (as many whole periods as fit in its last quarter,
    at least one); with no such period (no forcing, or a segment shorter than
    two periods), the two halves of the last quarter. With a_A, a_B the
    oscillation in each (the largest swing between consecutive extrema):
    ``off_target`` if the segment has no contact at all (the tool never
    reached the surface: nothing to judge as an oscillation);
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
        return (("converged", f"|f_e - f_d| <= {_N(worst)} (a segment of {n} samples)") if worst <= tolerance
                else ("off_target", f"|f_e - f_d| up to {_N(worst)} (tolerance {_N(tolerance)}, a segment of "
                                    f"{n} samples: too short to judge growth)"))
    # never in contact: nothing oscillates, the tool is off the surface (review 23)
    if not np.any(touching(force, f_d)):
        return "off_target", "no contact in the segment (the tool never reached the surface)"
    if not np.all(touching(last, f_d)):
        return "limit_cycle", "the contact is lost in the last quarter"
    P = next((p for p in periods if n >= 2 * p), None)
    W = P * max(1, (n // 4) // P) if P else max(2, last.size // 2)
    e_A, e_B = e[n - 2 * W:n - W], e[n - W:]
    a_A, a_B = _amplitude(e_A), _amplitude(e_B)
    over = f"{W * Ts:.3g} s" + (" (whole periods)" if P else "")
    if a_B > band and a_B > GROWTH * a_A:
        return "diverged", f"oscillation grows {_x(a_B / max(a_A, 1e-300))}x over {over}"
    forced = (P is not None and float(np.max(np.abs(e_B - e_A))) <= FORCED * a_B
              and _gain(e_A, e_B) <= 1.0 + REPEAT_GROWTH)
    low = float(np.min(force[n - W:]))
    if forced and a_B > band and a_B >= f_d and low < NEAR_LOSS * f_d:
        return "limit_cycle", (f"oscillation of {_N(a_B)} peak-to-peak down to {_N(low)}, repeating with the "
                               f"forcing over {over}: a contact limit cycle locked to the path")
    if a_B > band and a_B >= SUSTAINED * a_A and not forced:
        a_0 = _amplitude(e[n - 3 * W:n - 2 * W]) if n >= 3 * W else 0.0
        if not (a_0 > a_A > a_B and a_B < SUSTAINED * a_0):     # shrinking over three windows: still decaying
            # the ratio said (review 56: "does not decay" of an amplitude that fell 1.5 % read as no decay at all)
            return "limit_cycle", (f"oscillation of {_N(a_B)} peak-to-peak does not decay over {over} (it keeps "
                                   f"{_x(100 * a_B / max(a_A, 1e-300))} % of its amplitude; {100 * SUSTAINED:g} % "
                                   "or more is sustained)")
    worst = float(np.max(np.abs(e[n - last.size:])))
    bias = float(np.mean(e[n - last.size:]))
    if bias_tolerance is None:
        bias_tolerance = tolerance
    if worst <= tolerance and abs(bias) <= bias_tolerance:
        return "converged", f"|f_e - f_d| <= {_N(worst)} at the end"
    if worst <= tolerance:
        return "off_target", (f"a bias of {_N(bias, sign=True)} over the last quarter "
                              f"(tolerance {_N(bias_tolerance)}; |f_e - f_d| <= {_N(worst)} is within the noise "
                              "allowance)")
    if forced:
        why = f"a periodic forced response of {_N(a_B)} peak-to-peak"
    elif a_B > band:
        why = f"still decaying ({_x(a_B / max(a_A, 1e-300))}x over {over})"
    elif (at := n - last.size + int(np.argmax(np.abs(e[n - last.size:])))) < n - W \
            and 2.0 * float(np.max(np.abs(e_B))) < min(worst, 2.0 * tolerance):
        # review 43: the worst sample before the last window (a step in a measured part met once), which is
        # within the tolerance and less than half of it: no bias of the last window explains it (under sensor
        # noise a bias's worst sample falls anywhere in the last quarter, at most a few noise widths above the
        # last window's)
        why = (f"an excursion to {_N(float(e[at]), sign=True)} {at * Ts:.3g} s into the segment, the last {over} "
               f"within {_N(float(np.max(np.abs(e_B))))} (a segment of fewer than two periods of the forcing "
               "cannot tell a transient from a forced response)" if P is None else
               f"an excursion to {_N(float(e[at]), sign=True)} {at * Ts:.3g} s into the segment, the last {over} "
               f"within {_N(float(np.max(np.abs(e_B))))}")
    else:
        drift = float(np.mean(e_B) - np.mean(e_A))
        why = f"a bias of {_N(float(np.mean(e_B)), sign=True)}" + (f", drifting {_N(drift, sign=True)} over {over}"
                                                          if abs(drift) > 0.1 * tolerance else "")
    return "off_target", f"|f_e - f_d| up to {_N(worst)} at the end (tolerance {_N(tolerance)}): {why}"


def segment_verdict(force: np.ndarray, f_d: float, band: float, tolerance: float = 0.01,
                    periods: tuple[int, ...] = ()) -> str:
    """The verdict of :func:`judge_segment` alone (``tolerance`` in N, the
    scenario key's default 0.01 N)."""
    return judge_segment(force, f_d, band, tolerance, periods)[0]


_TWINS: dict = {}


def noise_free_twin(result: SimulationResult) -> SimulationResult:
    """``result``'s scenario run again with ``sensor.noise_std = 0`` (same
    arm, path, stiffness and law) on the same plant (the built-in loop, or
    MuJoCo's for a run on MuJoCo: a twin on another plant would count the
    plants' difference as noise); kept for the last few scenarios, so
    judging one run several times simulates its twin once."""
    from .scenario import apply_overrides
    from .simulator import simulator_for

    sc0 = apply_overrides(result.scenario, ["sensor.noise_std=0"])
    on_mujoco = str(getattr(result, "info", {}).get("plant", "")).startswith("mujoco")
    key = (on_mujoco, sc0.model_dump_json())
    if key not in _TWINS:
        if len(_TWINS) >= 4:
            _TWINS.pop(next(iter(_TWINS)))
        # as long as the run itself (its own --max-steps was checked before it ran)
        if on_mujoco:
            from .mujoco_plant import simulate_on_mujoco

            _TWINS[key] = simulate_on_mujoco(sc0, max_steps=len(result.time) + 1)
        else:
            _TWINS[key] = simulator_for(sc0).run(max_steps=len(result.time) + 1)
    return _TWINS[key]


_RANK = {v: i for i, v in enumerate(VERDICTS)}

LOOP_LIMITS = ("periodic orbit", "first contact", "frozen-point minimum")
"""The sources of an attached stiffness limit that are the loop's own analysis
(``stability.limit``), not the 1-D small-signal figure."""


def _N(v: float, sign: bool = False) -> str:
    """A force in a verdict's reason, as the tables print it (``fmt.qty``: 439 µN, 11 mN, 2.5 N)."""
    from .. import fmt

    return ("+" if sign and v >= 0 else "") + fmt.qty(float(v), "N").replace(fmt.NBSP, " ")


def _x(v: float) -> str:
    """A ratio or a percentage in a verdict's reason, as the tables print numbers (``fmt.num``: 1,240, not
    1.24e+03; review 60)."""
    from .. import fmt

    return fmt.num(float(v)).replace(fmt.NBSP, " ")


def _judge(result: SimulationResult, twin: SimulationResult | None, i0: int, i1: int,
           periods: tuple[int, ...]) -> tuple[str, str, float]:
    """``(verdict, reason, tolerance used)`` of one segment (module docstring)."""
    sc = result.scenario
    f_d, tol0 = sc.controller.f_d, sc.controller.force_tolerance
    f = result.contact_force[i0:i1]
    if twin is None:
        return (*judge_segment(f, f_d, RIPPLE_BAND * f_d, tol0, periods, result.Ts), tol0)
    f0 = twin.contact_force[i0:i1]
    d = (f - f0)[int((i1 - i0) * (1 - STEADY_FRACTION)):]
    spread = NOISE_SIGMAS * float(np.std(d)) if np.all(np.isfinite(d)) else 0.0
    tol = tol0 + spread
    # growth and sustained oscillation are the twin's to show (the swing between consecutive extrema of a
    # noisy force measures the noise, not the oscillation); the noisy run adds contact loss, the
    # tolerance and the bias
    noisy = judge_segment(f, f_d, math.inf, tol, periods, result.Ts,
                          bias_tolerance=tol0 + bias_allowance(d) if np.all(np.isfinite(d)) else tol0)
    clean = judge_segment(f0, f_d, RIPPLE_BAND * f_d, tol0, periods, result.Ts)
    if _RANK[clean[0]] > _RANK[noisy[0]]:
        return clean[0], f"without the sensor noise: {clean[1]}", tol
    return (*noisy, tol)


def segment_metrics(result: SimulationResult) -> list[SegmentMetrics]:
    """:class:`SegmentMetrics` for every segment of ``result`` (with sensor
    noise, judged against its :func:`noise_free_twin` as well; with
    ``result.info["stiffness_limit"]``, a segment beyond it is ``beyond_limit``)."""
    out = []
    sc = result.scenario
    f_d = sc.controller.f_d
    periods = judging_periods(result)
    twin, twin_error = None, None
    if sc.sensor.noise_std > 0:
        from .simulator import SimulationError

        try:
            twin = noise_free_twin(result)
        except SimulationError as exc:       # the loop diverges without the noise: no segment is stable
            twin_error = str(exc)
    info = getattr(result, "info", None) or {}
    limit, source = info.get("stiffness_limit"), info.get("stiffness_limit_from", "1-D small-signal")
    limits, e_rot = getattr(result, "limits", None), getattr(result, "orientation_error", None)
    from .geometry import surface_of

    part = surface = surface_of(sc)
    if surface.exact_chart:                                 # nothing to add
        surface = None
    if e_rot is not None:
        from .simulator import robot_of

        fk = robot_of(sc).functions.fk
    touch = first_contact(result).time
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
        touched = np.flatnonzero(touching(f, f_d))
        if not touched.size:
            # no touch in the segment: the desired force is still the approach's 0, but the task's is f_d (review
            # 72: compare, simulate and the report read |f_e - f_d| = 0 N, settled at 0 s, beside "no contact")
            err = f - f_d
        ss_err = float(np.abs(err[ss]).max())
        lost = np.count_nonzero(~touching(f[touched[0]:], f_d)) if touched.size else f.size
        if twin_error is None:
            verdict, reason, tol = _judge(result, twin, i0, i1, periods)
        else:
            verdict, reason, tol = ("diverged", f"without the sensor noise the run diverges: {twin_error}",
                                    sc.controller.force_tolerance)
        verdict, reason = _first_contact_rules(verdict, reason, result.contact_force, i0, i1, result.Ts, f_d)
        k_max = float(np.max(result.stiffness[i0:i1]))
        if (((verdict == "limit_cycle" and "does not decay over" in reason)
             or (verdict == "diverged" and reason.startswith("oscillation grows"))) and periods
                and not any(i1 - i0 >= 2 * p for p in periods) and source in LOOP_LIMITS
                and limit is not None and k_max < limit):
            # review 17: a segment of one path period is judged on the two halves of its last quarter, where the
            # loop's damping changes with the path's phase: a growth there is no sustained oscillation when the
            # loop's own limit says stable (the paper at 165,000 N/m in a 4 s segment decays over 40 s to 0.1 mN;
            # review 22: a growth of 1.89x there, judged diverged, decays 0.21x per period in a longer run)
            verdict, reason = "off_target", (
                f"{reason}, yet k_e is below the loop's limit ({source}): a segment of fewer than two path "
                "periods cannot tell growth from the path's phase; not settled within the segment")
        if limit is not None and np.isfinite(limit) and k_max > limit and _RANK[verdict] < _RANK["limit_cycle"]:
            verdict, reason = "beyond_limit", (f"k_e reaches {k_max:,.0f} N/m, above the loop's predicted limit "
                                               f"{limit:,.0f} N/m ({source}): not proven stable there; this "
                                               f"run itself: {verdict}: {reason}")
        use = None if limits is None else limit_use(limits, t, result.q[:, i0:i1], result.dq[:, i0:i1],
                                                     result.tau[:, i0:i1], result.Ts)
        angle = None if e_rot is None else np.linalg.norm(e_rot[:, i0:i1], axis=0)    # tool vs command, rad
        e_o = 0.0 if angle is None else float(np.max(angle[ss]))
        chart = (0.0, 0.0) if surface is None else _chart_error(surface, result, i0 + ss.start, i1)
        verdict, reason = _chart_rule(verdict, reason, ss_err, chart, tol, None if e_rot is None else e_o,
                                      sc.controller.orientation_tolerance)
        verdict, reason = _limits_and_orientation(verdict, reason, None, e_o, sc.controller.orientation_tolerance)
        tilt = 0.0 if e_rot is None else _normal_tilt(part, fk, result, i0 + ss.start, i1)
        verdict, reason = _tilt_rule(verdict, reason, tilt, chart[1], sc.controller.orientation_tolerance,
                                     bool(np.any(np.asarray(sc.controller.part_offset) != 0.0)))
        reason = _setting_hints(verdict, reason, sc, float(np.min(result.stiffness[i0:i1])), float(t[ss.start]),
                                touch)
        tracking = verdict
        verdict, reason = _limits_and_orientation(verdict, reason, use, e_o, sc.controller.orientation_tolerance)
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
            contact_lost_steady=bool(not np.all(touching(f[ss], f_d))),
            contact_lost_time=float(lost * result.Ts),
            verdict=verdict, tolerance=tol, reason=reason,
            torque_margin=float(np.min(use.torque_margin)) if use else math.inf,
            rate_margin=float(np.min(use.rate_margin)) if use else math.inf,
            position_margin=float(np.min(use.position_margin)) if use else math.inf,
            # None on a position task: no orientation judged (review 62: 0.0 in summary.json read as a tool
            # perfectly normal to the part, where a 4-joint UR5's is 9-26 degrees off it, as it may be)
            orientation_error=None if e_rot is None else e_o, tracking_verdict=tracking,
            chart_force_error=chart[0], chart_normal_error=chart[1], normal_tilt=None if e_rot is None else tilt,
            peak_orientation_error=None if angle is None else float(np.max(angle)),
        ))
    return out


def _chart_error(surface, result: SimulationResult, i0: int, i1: int) -> tuple[float, float]:
    """The largest ``(k_e depth error (N), normal error (rad))`` of the
    surface's chart (:meth:`~tmtcontrol.surface.Surface.chart_error`) at the
    tool points of samples ``i0:i1``, at most :data:`CHART_SAMPLES` of them
    evenly spread (the error follows the path smoothly; each sample's closest
    point is a search)."""
    pick = np.unique(np.linspace(i0, i1 - 1, min(i1 - i0, CHART_SAMPLES)).round().astype(int))
    depth, normal = surface.chart_error(surface.from_base(result.position[:, pick]))
    return float(np.max(result.stiffness[pick] * depth)), float(np.max(normal))


CHART_SAMPLES = 250
"""Samples of a segment's last quarter at which :func:`_chart_error` asks the surface."""


def _chart_rule(verdict: str, reason: str, worst: float, chart: tuple[float, float], tolerance: float,
                e_o: float | None, orientation_tolerance: float) -> tuple[str, str]:
    """A ``converged`` segment whose force error ``worst`` (N) plus the
    chart's force error, or (on a 6-D task, ``e_o`` not None) whose
    orientation error plus the chart's normal error, exceeds its tolerance
    is ``off_target``: within the tolerance in the approximate chart only
    (review 43: on a sphere's height map the tool held 2.6 urad against the
    chart's normal, 2.1 mrad off the one at the closest point)."""
    if verdict != "converged":
        return verdict, reason
    f_c, n_c = chart
    if worst + f_c > tolerance:
        return "off_target", (f"|f_e - f_d| <= {_N(worst)} in the surface's chart, whose depth is first order: "
                              f"against the distance to the part's closest point the force is up to {_N(f_c)} "
                              f"further off (docs/surfaces.md), beyond the tolerance {_N(tolerance)}")
    if e_o is not None and n_c > 0.0 and e_o + n_c > orientation_tolerance:
        (e_t, n_t), tol_t = _angles((e_o, n_c), orientation_tolerance, e_o + n_c)
        return "off_target", (f"tool orientation error {e_t} against the chart's normal, which is up to {n_t} off "
                              f"the normal at the part's closest point (docs/surfaces.md): beyond "
                              f"controller.orientation_tolerance = {tol_t}")
    return verdict, reason


def _angles(values, bound: float, total: float | None = None) -> tuple[list[str], str]:
    """Angles (rad) for a verdict's reason in the unit of ``bound`` (rad, mrad,
    µrad or nrad: review 53, "3.09e-05 mrad" for 30.9 nrad), each with the
    digits that tell ``total`` (default the first value) from the bound
    (``fmt.against``: review 54, "0.000262 mrad ... = 0.000262 mrad")."""
    from .. import fmt

    scale, unit = next(((s, u) for s, u in ((1.0, "rad"), (1e-3, "mrad"), (1e-6, "µrad"))
                        if abs(bound) >= s * 0.9995), (1e-9, "nrad"))
    total = values[0] if total is None else total
    digits = fmt.digits_apart(total / scale, bound / scale)
    show = lambda v: fmt.num(v / scale, digits).replace(fmt.NBSP, " ") + f" {unit}"
    return [show(v) for v in values], fmt.num(bound / scale, digits).replace(fmt.NBSP, " ") + f" {unit}"


def _normal_tilt(part, fk, result: SimulationResult, i0: int, i1: int) -> float:
    """The largest angle (rad) between the tool's axis (its frame's z, which
    eq. (6)'s rotational task holds on the inward normal:
    ``geometry.tool_orientation``; ``fk`` the arm's pose Function) and the
    inward normal of the true part (``part``, the plant's) at the tool point,
    at the samples ``i0:i1``, at most :data:`CHART_SAMPLES` of them evenly
    spread."""
    pick = np.unique(np.linspace(i0, i1 - 1, min(i1 - i0, CHART_SAMPLES)).round().astype(int))
    axes = np.asarray(fk.map(pick.size)(result.q[:, pick]))[:3, 2::4]     # 4 x 4k: the poses side by side
    worst = 0.0
    for z, k in zip(axes.T, pick):
        n = part.normal(result.position[:, k])
        worst = max(worst, math.atan2(float(np.linalg.norm(np.cross(z, n))), float(z @ n)))
    return worst


def _tilt_rule(verdict: str, reason: str, tilt: float, n_c: float, tolerance: float,
               displaced: bool) -> tuple[str, str]:
    """A ``converged`` segment whose tool axis is more than ``tolerance``
    (controller.orientation_tolerance, rad) off the true part's normal at the
    tool point (``tilt``, plus the chart's normal error ``n_c`` on a measured
    part) is ``off_target``: the orientation error is measured against the
    command on the controller's part, which a part displaced by
    ``controller.part_offset`` (``displaced``), or a tool point off the
    commanded one on a curved part, moves off the true normal (review 54: a
    0.3 mm offset on the pipe tilted the tool 2.8 mrad, the error read
    0.017 mrad)."""
    if verdict != "converged" or tilt + n_c <= tolerance:
        return verdict, reason
    (t, n), tol = _angles((tilt, n_c), tolerance, tilt + n_c)
    why = ("the controller's part is displaced by controller.part_offset" if displaced else
           "the tool point is off the commanded one on a curved part")
    chart = f", and the chart's normal up to {n} further (docs/surfaces.md)" if n_c > 0.0 else ""
    return "off_target", (f"the tool's axis is up to {t} off the part's normal at the tool point ({why}){chart}: "
                          f"beyond controller.orientation_tolerance = {tol}")


def _setting_hints(verdict: str, reason: str, sc, k_min: float, judged_from: float, touch: float | None) -> str:
    """``reason`` with the settings that explain a segment's miss named
    (review 57's lows: "a bias of -8.3 N" said nothing of a force ramp still
    rising, nor a bias of -98 mN of a part softer than the law's clip):
    a stiffness below the law's ``min_stiffness`` (the clip of its stiffness
    or compliance estimate), and, after a guarded approach, f_d still ramping
    up (``controller.force_ramp`` from about the first contact ``touch``) when
    the segment's judged last quarter starts at ``judged_from`` s."""
    from .. import fmt
    from .environment import has_approach

    if verdict == "converged":
        return reason
    hints = []
    floor = getattr(sc.controller.law, "min_stiffness", None)
    if floor is not None and k_min < floor:
        hints.append(f"k_e = {fmt.num(k_min, 4)} N/m is below controller.law.min_stiffness = {fmt.num(floor, 4)} "
                     "N/m, the clip of the law's stiffness estimate")
    ramp = sc.controller.force_ramp
    if touch is not None and has_approach(sc) and touch + ramp > judged_from:
        hints.append(f"f_d was still ramping up where the last quarter is judged, from {judged_from:.3g} s "
                     f"(controller.force_ramp = {ramp:g} s from the contact at about {touch:.3g} s)")
    return reason + "".join(f"; {h}" for h in hints)


def _first_contact_rules(verdict: str, reason: str, force: np.ndarray, i0: int, i1: int, Ts: float,
                         f_d: float):
    """A segment's verdict with the run's first contact in view: a segment the
    run's first contact falls in at or after the start of its last quarter
    (a guarded approach arriving late) has too little left to judge, its
    impact's bounces included (review 25: held, review 27: bouncing, both
    read "the contact is lost", a limit cycle): off_target, provided the
    contact holds over the last quarter of what is left after it (a contact
    bouncing to the end is lost, review 29). A segment without
    contact after the run had some has lost it: limit_cycle. Contact is
    :func:`touching` (``f_d`` in N)."""
    touched = np.flatnonzero(touching(force, f_d))
    first = int(touched[0]) if touched.size else None
    if first is not None and first < i0 and reason.startswith("no contact in the segment"):
        return "limit_cycle", "the contact is lost for the whole segment"
    late = i0 + int((i1 - i0) * (1 - STEADY_FRACTION))
    # the impact's bounces only: the contact held over the last quarter of what is left after it (review 29: a
    # stiffness 12x over the limit bouncing to the end, 875 of 949 samples off the surface, was excused)
    settled_on = first is not None and np.all(touching(force[first + 3 * (i1 - first) // 4:i1], f_d))
    if (first is not None and late <= first < i1 and settled_on and verdict in ("limit_cycle", "diverged")
            and reason.startswith("the contact is lost")):
        return "off_target", (f"first contact made only {(i1 - first) * Ts:.3g} s before the segment's end (its "
                              "impact included), too late to judge its settling")
    return verdict, reason


def _limits_and_orientation(verdict: str, reason: str, use, e_o: float, tolerance: float) -> tuple[str, str]:
    """A segment that tracks its force (``converged`` or ``off_target``) but
    crosses a limit is ``over_limit`` (a worse verdict stays, its reason
    naming the excursions too); one ``converged`` whose tool orientation
    error ``e_o`` (rad) exceeds ``tolerance`` is ``off_target``. A segment's
    reason, whatever its verdict, says how long the torque sat on its clip
    (``robot.saturate``)."""
    if verdict == "converged" and e_o > tolerance:
        (e_t,), tol = _angles((e_o,), tolerance)
        verdict, reason = "off_target", (f"tool orientation error {e_t} against its command over the last quarter, "
                                         f"above controller.orientation_tolerance = {tol}")
    if use is not None and np.any(use.saturated > 0):
        # the drive's clip (robot.saturate) shapes the force: say so beside what the verdict blames, and beside a
        # converged one too (review 62: a sweep's or summary.json's converged reason hid 1.08 s on a 20 N m clip,
        # the first contact's overshoot 83 % against 24 % without it)
        reason = f"{reason}; the torque sat on its clip (robot.saturate): {use.on_clip()}"
    if use is not None and use.excursions:
        shown = "; ".join(e.text for e in use.ranked()[:3])          # the three furthest past their bounds
        more = f" (and {len(use.excursions) - 3} more)" if len(use.excursions) > 3 else ""
        if _RANK[verdict] < _RANK["over_limit"]:
            # review 54: an orientation beyond its tolerance read "the force tracking alone: off_target"
            return "over_limit", (f"{shown}{more}; the force tracking alone: converged" if verdict == "converged"
                                  else f"{shown}{more}; the tracking alone: {verdict}: {reason}")
        return verdict, f"{reason}; also beyond the arm's limits: {shown}{more}"     # the worse verdict stays
    return verdict, reason


FIRST_CONTACT_WINDOW = 1.0
"""Seconds after the first contact over which its peak and bounces count."""


@dataclass(frozen=True)
class FirstContact:
    """The first contact with the surface (forces N, times s).

    ``time``: first sample with f_e above :data:`CONTACT_FLOOR` f_d (None if the run never touches);
    ``peak_force``: the largest f_e within :data:`FIRST_CONTACT_WINDOW` after
    it (and within the first segment), ``peak_ratio`` = peak / f_d;
    ``bounces``: how often the contact is lost again in that window;
    ``window``: the seconds after the contact that the peak and bounces cover,
    :data:`FIRST_CONTACT_WINDOW` or less where the contact's segment or the run
    ends sooner (0 when the run never touches)."""
    time: float | None
    peak_force: float
    peak_ratio: float
    bounces: int
    window: float = 0.0

    @property
    def whole_window(self) -> bool:
        """Whether the peak and bounces cover all of :data:`FIRST_CONTACT_WINDOW`
        (True when the run never touches: nothing was cut short)."""
        return self.time is None or self.window >= FIRST_CONTACT_WINDOW - 1e-9

    def as_dict(self) -> dict:
        return asdict(self)


def first_contact(result: SimulationResult, window: float = FIRST_CONTACT_WINDOW) -> FirstContact:
    """:class:`FirstContact` of ``result``. A run that starts on the surface
    at zero force touches at its first force above :data:`CONTACT_FLOOR`
    times f_d; the window's losses of contact are its falls below it."""
    f = result.contact_force
    touch = touching(f, result.scenario.controller.f_d)
    if not touch.any():
        return FirstContact(None, 0.0, 0.0, 0)
    i0 = int(np.argmax(touch))
    # the window ends at the end of the segment the contact is made in (a later switch's transient is not the
    # contact's; review 25: the first segment's end, before a late contact, left one sample: 0.04 N for 10.2 N)
    seg_end = next((e for s, e in segments(result) if s <= i0 < e), f.size)
    end = min(seg_end, i0 + int(round(window / result.Ts)) + 1)
    w = touch[i0:max(end, i0 + 1)]
    peak = float(f[i0:max(end, i0 + 1)].max())
    last = max(end, i0 + 1) - 1
    # the samples cover the window up to the step that starts at the last one (a 10 ms run: 10 ms, not 1 s)
    span = min(window, float(result.time[last] - result.time[i0]) + result.Ts)
    return FirstContact(float(result.time[i0]), peak, peak / result.scenario.controller.f_d,
                        int(np.count_nonzero(w[:-1] & ~w[1:])), span)


def orientation_transient(metrics: list[SegmentMetrics], tolerance: float) -> str:
    """Where a 6-D task's tool left ``controller.orientation_tolerance``
    (``tolerance``, rad) against its command within a segment, outside the
    last quarter the verdict judges, in words ("" when it never did, or on a
    position task): the segment, its largest angle over the whole segment
    and over the last quarter (review 62: a 20 N m clip tilted a UR5's tool
    4.93 mrad at 12.14 s, five times the tolerance, while every segment read
    converged). A hardware user's tool does tilt that far there."""
    from .. import fmt

    over = [(i, m) for i, m in enumerate(metrics, 1) if m.peak_orientation_error is not None
            and m.peak_orientation_error > tolerance >= (m.orientation_error or 0.0)]
    if not over:
        return ""
    words = []
    for i, m in over:
        (peak, settled), tol = _angles((m.peak_orientation_error, m.orientation_error), tolerance)
        words.append(f"segment {i} ({fmt.num(m.start)}–{fmt.num(m.end)} s) up to {peak}, {settled} over its last "
                     "quarter")
    return "; ".join(words) + (f", against controller.orientation_tolerance = {tol}: a transient (a switch, a "
                               "clip); each segment's orientation is judged over its last quarter")


def format_table(metrics: list[SegmentMetrics]) -> str:
    """A plain-text table of the per-segment metrics, with the tracking
    tolerance each verdict used: one unit per column (in its header), every
    number of a column to the same significant digits, thousands separated
    (``fmt.column``)."""
    from .. import fmt

    def col(name, values, unit, sig=3, nan="never", reference=0.0):
        unit, cells = fmt.column(values, unit, sig, reference=reference)
        return (f"{name} ({unit})" if unit else name, [nan if c == "–" else c for c in cells])

    return fmt.text_table([
        ("segment", [str(i) for i in range(1, len(metrics) + 1)]),
        ("t (s)", [f"{fmt.num(m.start)}–{fmt.num(m.end)}" for m in metrics]),
        col("k_e", [m.stiffness for m in metrics], "N/m", 4),
        col("ss err", [m.steady_state_error for m in metrics], "N"),
        col("peak", [m.peak_force for m in metrics], "N"),
        # a first segment's jump is the force at its first sample: rounding residue when the tool starts on the
        # surface (review 43: 9.81e-14 N printed as "9.81 x 10^-5 nN" alone in its column)
        col("jump", [m.switch_jump for m in metrics], "N",
            reference=max((m.peak_force for m in metrics if math.isfinite(m.peak_force)), default=0.0)),
        col("overshoot", [m.overshoot_pct for m in metrics], "%"),
        col("settle 2 %", [m.settling_time for m in metrics], "s"),
        col("tang RMS", [m.tangential_rms for m in metrics], "m"),
        col("tol", [m.tolerance for m in metrics], "N"),
        ("verdict", [m.verdict for m in metrics])])
