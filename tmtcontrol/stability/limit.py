"""The stiffness limit that decides a scenario's verdict, computed by one function for every command.

``analyze --scenario``, ``report``, ``simulate`` (a segment beyond the limit,
a failing run's message) and ``sweep`` (each case's predicted limit) quote the
figure :func:`deciding_limit` returns, so one scenario has one limit wherever
it is printed (issue 43). It is the smaller of two limits of the loop as it is
simulated (beyond the paper, whose eqs. (22)/(25) are continuous):

* **along the path**: the stiffness where the monodromy of one path period
  crosses the unit circle (``stability.periodic``), searched between the
  smallest and the largest limit of the loop frozen at ``points`` path points
  (``stability.wholeloop``; the smallest, bracketed to :data:`WHOLE_LOOP_RTOL`,
  is the conservative bound and stands in where the loop is not periodic);
* **from first contact**: the largest stiffness from which the scenario's own
  start settles instead of locking into a contact limit cycle
  (``stability.first_contact``, searched up to the limit along the path).

The 1-D sampled loop (``stability.onedim``: the paper's normal axis, eq. (22),
sampled, with the arm's effective normal mass) is the *small-signal*
explanation: quoted beside the deciding limit and labelled so, it is not a
safe limit where the deciding one is lower (a surface-location error), and it
is the search's starting guess. :func:`with_stiffness_limit` attaches the
limit to a simulation, whose segment verdicts then call a segment above it
``beyond_limit``. Units are SI (N/m).
"""

from __future__ import annotations

import dataclasses
import json
from dataclasses import dataclass

import numpy as np

from .continuous import AnalysisError

__all__ = ["ScenarioLimit", "NoContact", "deciding_limit", "periodic_note", "with_stiffness_limit", "WHOLE_LOOP_RTOL",
           "UNREAD_KEYS", "CLIP_KEYS", "APPROACH_KEYS", "analysed_settings"]

WHOLE_LOOP_RTOL = 1e-6
"""Relative width of the whole-loop limit's final bracket (stable at its
lower end, unstable at its upper): the search starts at the 1-D limit, so a
coarser bracket would often return the 1-D value itself."""

UNREAD_KEYS = ("name", "robot.dq_max", "robot.limit_margin", "robot.tool_radius", "controller.force_tolerance",
               "controller.orientation_tolerance", "sensor.seed", "simulation.mujoco_contact",
               "simulation.mujoco_friction", "requirements")
"""Scenario keys (dotted; a section for all its keys) no limit reads: the
scenario's name, the joint rates and the reserve held below each limit (the
verdicts judge them along the run), the tool sphere and the contact and
friction of ``--plant mujoco`` (the analyses model the built-in loop), the
verdicts' tolerances, the noise's seed (the analyses and the first-contact
runs are noise-free) and the design requirements. They are left out of the
key the limits are kept under (:func:`analysed_settings`), so a run that
changes only these reads the limits computed before."""

CLIP_KEYS = ("robot.tau_max",)
"""Keys the analyses see only through the loop's torque clip
(``robot.saturate`` on; off, the clip is infinite whatever the limits:
``simulation.limits.ArmLimits.torque_clip``)."""

APPROACH_KEYS = ("sensor.noise_std",)
"""Keys the analyses see only through a guarded approach
(``trajectory.approach_gap`` and ``controller.approach_speed`` above 0): its
detection threshold adds 6 sigma of the filtered noise, which sets how deep
the approach finds the surface and so the surface-location error it leaves
(``simulation.environment.approach_depth``; review 49: 0.5 N of noise moved
an approach scenario's limits by 0.01-0.8 %)."""


def analysed_settings(scenario) -> dict:
    """The scenario's settings (``model_dump(mode="json")``) without
    :data:`UNREAD_KEYS`, nor :data:`CLIP_KEYS` unless the loop clips its
    torque, nor :data:`APPROACH_KEYS` unless it starts with a guarded
    approach: what the limits are computed from, as the key they are kept
    under."""
    from ..simulation.environment import has_approach

    d = scenario.model_dump(mode="json")
    for key in (UNREAD_KEYS + (() if scenario.robot.saturate else CLIP_KEYS)
                + (() if has_approach(scenario) else APPROACH_KEYS)):
        section, _, field = key.partition(".")
        if field:
            d[section].pop(field)
        else:
            d.pop(section)
    return d


class NoContact(AnalysisError):
    """The loop holds no contact at any stiffness (its equilibrium is off the
    part): there is no stiffness limit, and no segment is judged against one
    (review 68: a sweep's no-contact cases read ``beyond_limit`` above the 1-D
    figure the failed analysis fell back to, ``off_target`` below it)."""


@dataclass(frozen=True)
class ScenarioLimit:
    """A scenario's stiffness limits, N/m.

    ``limit`` decides the verdict (``limit_from`` says which: ``"periodic
    orbit"``, ``"first contact"``, ``"frozen-point minimum"`` where the loop is
    not periodic, or ``"unstable at the smallest stiffness"`` with limit 0, or
    with limit 0 the reason an axis without contact force is unstable at
    every stiffness, ``stability.onedim.unstable_free_axis``);
    ``small_signal`` is the 1-D sampled loop's (None with the mid-period hold,
    which the 1-D model lacks); ``whole_loop`` the frozen-point minimum with
    ``whole_loop_bracket`` (stable, unstable) and ``whole_loop_points``
    ((path time s, limit) per point); ``periodic`` the limit along the path
    (the frozen minimum when ``periodic_note`` says why there is no periodic
    analysis); ``periodic_set_by`` what ends the periodic search
    (``stability.periodic.PeriodicLimit.set_by``: "spectral radius",
    "transient growth" or "orbit lost") with the ``periodic_radius`` and
    ``periodic_growth`` just below it; ``first_contact`` the large-signal limit
    from the start. ``periodic`` and ``first_contact`` are None when only the
    frozen loop was asked for (``along_path=False``) or the loop is unstable at
    the smallest stiffness. ``whole_loop_clipped``: the joints (1-based) whose
    torque reaches the drive's clip (``robot.saturate``) at the frozen point
    that sets ``whole_loop`` (:func:`_clipped_at_the_minimum`): there the
    clip, not the loop, sets that minimum."""
    limit: float
    limit_from: str
    small_signal: float | None
    whole_loop: float
    whole_loop_bracket: tuple[float, float]
    whole_loop_points: tuple[tuple[float, float], ...]
    periodic: float | None = None
    periodic_note: str | None = None
    first_contact: float | None = None
    periodic_set_by: str | None = None
    periodic_radius: float | None = None
    periodic_growth: float | None = None
    whole_loop_clipped: tuple[int, ...] = ()

    @property
    def small_signal_is_safe(self) -> bool:
        """Whether the 1-D small-signal figure is at or below the deciding
        limit (else it must not be read as a safe limit)."""
        return self.small_signal is not None and self.small_signal <= self.limit

    def describe(self) -> str:
        """One clause for a message: the deciding limit and where it comes
        from, then the 1-D figure labelled as small-signal."""
        text = f"the loop's limit {self.limit:,.0f} N/m ({self.limit_from}; as tmtcontrol analyze --scenario)"
        if self.small_signal is not None:
            text += (f", 1-D small-signal {self.small_signal:,.0f} N/m"
                     + ("" if self.small_signal_is_safe else " (not a safe limit here)"))
        return text


def periodic_note(scenario) -> str | None:
    """Why the periodic analysis (``stability.periodic``) cannot run on the
    scenario, as one line, or None: it needs a path period that is a whole
    number of control periods (else the sampled loop is not periodic); the
    frozen-point minimum (conservative) is then quoted in its place."""
    Ts, period = scenario.controller.Ts, scenario.trajectory.period
    N = int(round(period / Ts))
    if N >= 1 and abs(N * Ts - period) <= 1e-9 * period:
        return None
    return (f"trajectory.period = {period:g} s is not a whole number of control periods ({Ts:g} s): the loop "
            "is not periodic, so the frozen-point minimum stands in for the limit along the path")


def _one_d(scenario) -> float | None:
    """The 1-D small-signal limit, and the search's guess: the mid-period
    hold's loop is guessed from the zero-order hold's 1-D figure. Kept in the
    results under the deciding limit's key (:func:`_result_key`): it costs
    milliseconds, but SciPy's import (0.15-0.2 s) on every warm ``simulate``;
    ``TMTCONTROL_RESULT_CACHE=0`` computes it every time."""
    from ..cache import kept_result, results_enabled

    key = _result_key(scenario, 0, False) if results_enabled() else None
    return kept_result("small_signal_limit", key, lambda: _computed_one_d(scenario),
                       lambda v: None if v is None else {"limit": float(v)}, lambda d: float(d["limit"]))


def _computed_one_d(scenario) -> float | None:
    from .onedim import scenario_stiffness_limit

    if scenario.controller.hold == "mid_period":
        return scenario_stiffness_limit(scenario.replace(controller=scenario.controller.model_copy(
            update={"hold": "zero_order"})))
    return scenario_stiffness_limit(scenario)


def deciding_limit(scenario, points: int = 8, along_path: bool = True, runner=None,
                   memo: dict | None = None) -> ScenarioLimit | None:
    """The stiffness limit that decides ``scenario``'s verdict (module
    docstring); None for a law without a linear verdict. ``points``: frozen
    path points; ``along_path=False`` stops after the frozen loop (the
    periodic and first-contact searches are the costly part: a compile of the
    tangent-linear step per loop structure, then seconds); ``runner``: a
    ``stability.first_contact.LoopRunner`` to reuse (a sweep's simulator);
    ``memo``: a dict the caller keeps, so that one command that attaches the
    limit to its run and then quotes it computes it once (an
    ``AnalysisError`` it raised is kept and raised again)."""
    if memo is None:
        return _deciding_limit(scenario, points, along_path, runner)
    key = (scenario.model_dump_json(), int(points), bool(along_path))
    if key not in memo:
        try:
            memo[key] = _deciding_limit(scenario, points, along_path, runner)
        except AnalysisError as exc:         # kept too: the caller's second use says the same, at once
            memo[key] = exc
    if isinstance(memo[key], AnalysisError):
        raise memo[key]
    return memo[key]


def _deciding_limit(scenario, points, along_path, runner):
    """:func:`_computed_limit`, kept in the compile cache's results
    (``tmtcontrol.cache.store_result``) under a key of everything that
    changes it: a second command on the same scenario reads it (a warm
    report, ``analyze`` after ``simulate``), and computed under a lock on
    that key (``tmtcontrol.cache.result_lock``): a process that needs it
    while another computes it (a report's two processes) waits and reads it.
    ``TMTCONTROL_RESULT_CACHE=0`` turns it off (always computed, nothing
    kept)."""
    from ..cache import kept_result, results_enabled
    from ..simulation.simulator import check_joint_settings, robot_of

    # the per-joint settings no limit reads are still checked (review 49: a kept limit skipped building the loop,
    # where a 2-value robot.dq_max for a 3-joint arm is refused, and a wrong one was accepted)
    check_joint_settings(robot_of(scenario), scenario)
    key = _result_key(scenario, points, along_path) if results_enabled() else None
    return kept_result("deciding_limit", key, lambda: _computed_limit(scenario, points, along_path, runner),
                       lambda lim: None if lim is None else dataclasses.asdict(lim), _from_json)


def _result_key(scenario, points, along_path) -> str | None:
    """What the deciding limit depends on: the compiled loop's structure key
    (the package's sources, the arm's and the controller model's content,
    the surface's, the law's declaration), every value of the scenario the
    limits read (:func:`analysed_settings`; issue 42: the key covers what
    changes the result and nothing else), its
    analysis parameters (a stiffness table's range), the numerical
    libraries' versions and the search's settings. None for a law that is not
    the package's own declaration (its code is not in the key: not kept)."""
    import casadi
    import scipy

    from ..control.laws import get_law
    from ..simulation.simulator import structure_key
    from .onedim import scenario_parameters

    structure = structure_key(scenario, get_law(scenario.controller.law.kind))
    if structure is None:
        return None
    params = sorted((k, repr(v)) for k, v in scenario_parameters(scenario).items())
    settings = json.dumps(analysed_settings(scenario), sort_keys=True)
    return repr((structure, settings, params, casadi.__version__, np.__version__, scipy.__version__, int(points),
                 bool(along_path)))


def _from_json(data: dict) -> ScenarioLimit:
    """A :class:`ScenarioLimit` from its stored form (``dataclasses.asdict``)."""
    fields = {f.name for f in dataclasses.fields(ScenarioLimit)}
    if set(data) != fields:
        raise KeyError("fields")
    return ScenarioLimit(**{**data, "whole_loop_bracket": tuple(data["whole_loop_bracket"]),
                            "whole_loop_points": tuple(tuple(p) for p in data["whole_loop_points"]),
                            "whole_loop_clipped": tuple(data["whole_loop_clipped"])})


def _clipped_at_the_minimum(scenario, model, whole, per_point, k_e_min) -> tuple[int, ...]:
    """The joints whose torque reaches the drive's clip at the path point whose frozen limit is the
    minimum ``whole``: on the clip at the equilibrium at either end of the bisection's bracket (its
    stable end as the bisection found it; the end above, or the smallest stiffness where the
    minimum is 0), or, where the end above has no equilibrium with the clip, beyond the clip in the
    loop without it, if that loop is stable there (review 50: the clip engaging just above the
    stable end ended the band, or left no equilibrium, with the stable end's torque free). () where
    the clip has no part in it, or the minimum is unbounded."""
    if not whole < np.inf or not np.any(np.isfinite(model.torque_clip)):
        return ()
    from .wholeloop import WholeLoopModel

    path_time = min(per_point, key=lambda p: p[1])[0]
    above = whole * (1 + WHOLE_LOOP_RTOL) if whole > 0 else k_e_min
    joints = set()
    if whole > 0:
        try:
            joints.update(model.clipped_at(whole, path_time))
        except AnalysisError:      # none from a fresh start where the bisection had warm ones
            pass
    try:
        joints.update(model.at(above, path_time).clipped)
    except AnalysisError:
        if not joints:
            free = WholeLoopModel(scenario.replace(robot={**scenario.robot.model_dump(), "saturate": False}))
            try:
                loop = free.at(above, path_time)
            except AnalysisError:
                return ()
            if loop.stable:
                joints.update(int(j) + 1 for j in np.flatnonzero(np.abs(loop.tau) > model.torque_clip))
    return tuple(sorted(joints))


def _computed_limit(scenario, points, along_path, runner):
    from ..control.laws import get_law
    from .onedim import scenario_parameters
    from .wholeloop import whole_loop_limit

    if not get_law(scenario.controller.law.kind).linear_analysis:
        return None
    guess = _one_d(scenario)
    small = None if scenario.controller.hold == "mid_period" else guess
    from .onedim import unstable_free_axis

    free = unstable_free_axis(scenario)
    if free is not None:
        # an axis without contact force unstable on its own: unstable at every stiffness, nothing to search; every
        # command quotes limit 0 and names it (review 55: analyze printed a periodic limit beside "free axes NO",
        # a sweep's row named neither, and the searches took minutes on a loop unstable everywhere)
        return ScenarioLimit(0.0, free, small_signal=small, whole_loop=0.0, whole_loop_bracket=(0.0, 0.0),
                             whole_loop_points=())
    p = scenario_parameters(scenario)
    note = periodic_note(scenario) if along_path else None
    frozen_model = model = None
    if along_path and note is None:
        from ..simulation.rollout import COMPILE_AFTER, compile_together
        from .first_contact import LoopRunner
        from .periodic import PeriodicModel
        from .wholeloop import WholeLoopModel

        model, runner = PeriodicModel(scenario), runner or LoopRunner(scenario)
        # both searches run their loops for far more than COMPILE_AFTER periods: the tangent step and the
        # scenario's step compile side by side (issue 42: the Panda's, 13 s and 6 s in turn), first, so that
        # the frozen points' Jacobians are the compiled tangent step's columns (a UR5's 17 in 0.5 ms, 8 ms on
        # CasADi's virtual machine)
        compile_together([model.rollout, runner.sim.rollout], COMPILE_AFTER + 1)
        # its own frozen model (not model.frozen, whose equilibria seed the periodic search's first orbits: the
        # bisection's would change them), sharing the tangent step
        frozen_model = WholeLoopModel(scenario)
        frozen_model.tangent = model.rollout
    if frozen_model is None:
        from .wholeloop import WholeLoopModel

        frozen_model = WholeLoopModel(scenario)
    # the band that contains the scenario's smallest stiffness (contact damping: unstable on soft surfaces)
    whole, per_point = whole_loop_limit(scenario, points=points, rtol=WHOLE_LOOP_RTOL, guess=guess,
                                        within=p["k_e_min"], model=frozen_model)
    # the bisection ends with a stable and an unstable stiffness at most WHOLE_LOOP_RTOL apart
    bracket = (whole, whole * (1 + WHOLE_LOOP_RTOL)) if 0 < whole < np.inf else (whole, whole)
    frozen = dict(small_signal=small, whole_loop=float(whole), whole_loop_bracket=tuple(map(float, bracket)),
                  whole_loop_points=tuple((float(t), float(l)) for t, l in per_point),
                  whole_loop_clipped=_clipped_at_the_minimum(scenario, frozen_model, whole, per_point,
                                                             p["k_e_min"]))
    if not ((small is None or small > 0) and whole > 0):
        # unstable at the scenario's smallest stiffness: no limit above it to search along the path
        return ScenarioLimit(0.0, "unstable at the smallest stiffness", **frozen)
    if whole == np.inf:
        _no_contact(scenario, frozen_model, p["k_e_min"])
    if not along_path:
        return ScenarioLimit(float(whole), "frozen-point minimum", **frozen)
    from .first_contact import LoopRunner, first_contact_limit
    from .periodic import periodic_search

    search = {}
    if note is None:
        hi = max(l for _, l in per_point)
        found = periodic_search(scenario, model=model, bracket=(whole / 1.02, hi * 1.02))
        periodic = found.k_e
        search = dict(periodic_set_by=found.set_by, periodic_radius=found.spectral_radius,
                      periodic_growth=found.transient_growth)
    else:       # no periodic loop to analyse: the frozen-point minimum (conservative) stands in
        periodic = float(whole)
    runner = runner or LoopRunner(scenario)
    first = first_contact_limit(scenario, periodic, runner=runner)
    own = _own_start_unsettled(scenario, runner, p["k_e_min"], min(periodic, first))
    if own is not None:
        return ScenarioLimit(0.0, own, periodic=float(periodic), periodic_note=note, first_contact=0.0, **search,
                             **frozen)
    return ScenarioLimit(min(periodic, first), "first contact" if first < periodic else (
        "periodic orbit" if note is None else "frozen-point minimum"), periodic=float(periodic),
        periodic_note=note, first_contact=float(first), **search, **frozen)


def _no_contact(scenario, model, k_min: float) -> None:
    """Raise :class:`AnalysisError`, naming the controller's belief, when the
    frozen loop holds no contact at the scenario's smallest stiffness
    ``k_min`` (its equilibrium off the part: no stiffness changes that, so
    there is no limit to search; review 57: x_e_error = -0.2 m with the
    command f_d/K = 0.1 m deep read "no stability boundary found between inf
    and inf N/m", naming no key). The force there decides: none, the
    command stops short of the part."""
    try:
        f_eq = model.at(k_min, 0.0).f_eq
    except AnalysisError:
        return
    if f_eq > 0.0:
        return
    ctl, imp = scenario.controller, scenario.impedance
    key = "controller.x_e_error" if ctl.x_e_error < 0 or not any(ctl.part_offset) else "controller.part_offset"
    raise NoContact(
        f"{key}: the loop holds no contact at any stiffness (at {k_min:,.0f} N/m its equilibrium is off the part, "
        f"force {f_eq:.3g} N): the position command, f_d/K = {ctl.f_d / imp.k[0]:.3g} m beyond the surface the "
        f"controller believes ({ctl.x_e_error:+.3g} m from the true one), stops short of the part; there is no "
        "stiffness limit to find")


def _own_start_unsettled(scenario, runner, k_min: float, limit: float) -> str | None:
    """Why the scenario's own start does not settle at its smallest
    stiffness ``k_min`` (N/m) below the ``limit`` the searches found, or
    None. The searches run the start at stiffnesses near their limits only
    (the first-contact one from the limit down), where the tool goes a
    fraction of a millimetre deep; at the softest surface the arm has to
    press f_d/k_e deep, which a large f_d takes out of its reach (review 57:
    the paper at f_d = 2,000 N, 0.4 m into 5,000 N/m, diverged in 31 ms
    while analyze said stable, exit 0). One run of the start
    (``first_contact.settles``, milliseconds compiled) tells."""
    from .first_contact import settles

    if not 0 < k_min < limit:
        return None
    run = settles(runner, k_min)
    if run.settled and run.min_force > 0.0:
        return None
    how = ("its force does not stay finite" if not np.isfinite(run.amplitude) else
           f"no contact force in the last second of {run.duration:g} s: the tool left the part"
           if run.min_force <= 0.0 else
           f"its force swings {run.amplitude:.3g} N in the last second of {run.duration:g} s")
    return (f"the scenario's own start does not settle at its smallest stiffness {k_min:,.0f} N/m: {how} (the "
            f"steady depth f_d/k_e is {scenario.controller.f_d / k_min:.3g} m there)")


def _has_surface_error(scenario) -> bool:
    """Whether the controller believes the surface nearer than it is
    (``controller.x_e_error`` < 0) or the part displaced
    (``controller.part_offset``, whose error along the normal changes sign
    on a curved part): the start may then be bistable and the first-contact
    limit lie below the 1-D figure (``stability.first_contact``). A positive
    x_e error pushes harder from the start and is not bistable (the paper at
    +5 and +10 mm: deciding limit 167,249 N/m, the periodic orbit's, above
    the 1-D 163,402). On a plane an offset is exactly an x_e error of its
    normal part and a path moved by the rest (docs/surfaces.md), so there
    the rule is the x_e error's with ``part_offset . n`` added (review 56: a
    1e-12 m sideways offset, or +2 mm along the normal, quoted the periodic
    limit where the identical run without it quoted the 1-D figure)."""
    from ..simulation.geometry import surface_of

    ctl = scenario.controller
    offset = np.asarray(ctl.part_offset, dtype=float)
    if not offset.any():
        return ctl.x_e_error < 0.0
    surface = surface_of(scenario)
    if surface.turns:
        return True
    return ctl.x_e_error + float(offset @ surface.normal()) < 0.0


def with_stiffness_limit(result, limit: ScenarioLimit | AnalysisError | None = None, memo: dict | None = None,
                         quote: bool = False):
    """``result`` (a simulation) with the scenario's limit attached as
    ``info["stiffness_limit"]`` (N/m) and ``info["stiffness_limit_from"]``:
    its segment verdicts (``simulation.metrics.segment_metrics``) then call a
    segment whose stiffness exceeds it ``beyond_limit``, even when the run
    ended before an instability grew (a ramp or a short hold above it).

    The limit attached is :func:`deciding_limit`'s, the one ``analyze
    --scenario`` prints (``limit`` when the caller has it: a sweep's, per
    case family, or the :class:`AnalysisError` its computation raised;
    ``memo`` as :func:`deciding_limit`'s). It is computed (a compile per
    loop structure, then seconds) only where it can change a verdict: when
    some segment whose own verdict is below ``limit_cycle`` reaches above the
    1-D small-signal figure or, with the surface believed nearer than it is
    or the part displaced (whose start may be bistable, its first-contact
    limit below the 1-D figure), reaches any stiffness. Otherwise the 1-D figure is attached (no segment is beyond
    it; milliseconds), or nothing with the mid-period hold, which the 1-D
    model lacks (the hold's lead raises the limit; the zero-order hold's 1-D
    figure is only the gate). Where the deciding limit fails, the 1-D figure
    is attached and its source says why. A loop unstable at its smallest
    stiffness gets limit 0 (every segment is beyond it). Unchanged for a law
    without a linear verdict. ``quote``: the caller quotes the deciding
    limit for a failing segment (``simulate``'s line), so it is computed
    wherever a segment fails, even one whose verdict it cannot change, and
    the result carries the figure the line quotes (review 10: summary.json
    held the 1-D figure beside a line quoting the periodic limit)."""
    if isinstance(limit, ScenarioLimit):
        return _attached(result, float(limit.limit), limit.limit_from)
    from ..control.laws import get_law
    from .onedim import unstable_free_axis

    sc = result.scenario
    free = unstable_free_axis(sc)      # review 54: a free axis unstable on its own (b_rot = 0) was "converged"
    if free is not None:
        return _attached(result, 0.0, free)
    if not get_law(sc.controller.law.kind).linear_analysis:
        return result
    guess, error = _one_d(sc), _has_surface_error(sc)
    if guess is None or np.isnan(guess) or (guess == np.inf and not error):
        return result
    small = None if sc.controller.hold == "mid_period" else guess
    if guess <= 0:          # as deciding_limit: unstable at the scenario's smallest stiffness
        return _attached(result, 0.0, "unstable at the smallest stiffness")
    if limit is None:
        gate = 0.0 if error else guess
        if not (np.max(result.stiffness) > gate and _limit_can_matter(result, gate)) \
                and not (quote and _fails(result)):
            return result if small is None else _attached(result, small, "1-D small-signal")
        try:
            limit = deciding_limit(sc, memo=memo)
        except AnalysisError as exc:
            limit = exc
        if limit is None:
            return result
        if isinstance(limit, ScenarioLimit):
            return _attached(result, float(limit.limit), limit.limit_from)
    if small is None or isinstance(limit, NoContact):
        # the deciding limit failed: the 1-D figure stands, and says why; a loop without contact has no limit
        return result
    return _attached(result, small, "1-D small-signal; the loop's own limit failed: "
                     + (str(limit).splitlines() or [type(limit).__name__])[0])


def _fails(result) -> bool:
    """Some segment ends worse than ``over_limit`` (a verdict whose line quotes the loop's limit)."""
    from ..simulation.metrics import segment_metrics

    return any(m.verdict not in ("converged", "over_limit") for m in segment_metrics(result))


def _attached(result, value: float, source: str):
    return dataclasses.replace(result, info={**(result.info or {}), "stiffness_limit": value,
                                             "stiffness_limit_from": source})


def _limit_can_matter(result, gate: float) -> bool:
    """Whether some segment reaching above ``gate`` (N/m) would take the
    limit's verdict: its own is below ``limit_cycle`` (a segment that locked
    into a limit cycle or diverged keeps that verdict whatever the limit)."""
    from ..simulation.metrics import VERDICTS, segment_metrics, segments

    own = segment_metrics(result)
    return any(np.max(result.stiffness[i0:i1]) > gate and VERDICTS.index(m.verdict) < VERDICTS.index("limit_cycle")
               for (i0, i1), m in zip(segments(result), own))
