"""Sweep files: a base scenario plus axes over dotted scenario keys, and the cases they span.

A sweep file (TOML)::

    scenario = "paper"                 # or a scenario file, relative to the sweep file
    [grid]                             # every combination of these values
    "environment.stiffness.values" = [[2000.0], [20000.0], [200000.0]]
    "controller.x_e_error" = { linspace = [-0.005, 0.005, 3] }
    [random]                           # `samples` draws, each combined with every grid point
    samples = 100
    seed = 1
    "sensor.noise_std" = { uniform = [0.0, 0.2] }

A grid value is what ``--set`` takes for that key (a list value for a list
key, e.g. one stiffness ``[2000.0]``; a number for a list key is a
one-element list); ``{ linspace = [a, b, n] }`` and ``{ geomspace = [a, b,
n] }`` generate numbers. A random axis is
``{ uniform = [a, b] }``, ``{ loguniform = [a, b] }`` or ``{ normal = [mean,
std], bounds = [lo, hi] }`` (a truncated normal; without ``bounds``,
truncated at mean +- 10 std). The draws depend only on the seed, so identical
files give identical cases.

Size: a sweep of more than ``max_cases`` cases (default 100,000, ``--max-cases``)
is refused from the axes' lengths alone, before any value is generated. The
cases are never listed: :class:`Cases` computes case ``i`` from its index
(grid index arithmetic and a block of seeded draws), so memory does not grow
with the number of cases.

Validation: before anything runs, every case is known to pass the scenario
schema, checked per axis rather than per case: each grid value once, each
random axis at both ends of its range and just inside them (a valid 0 beside
a least positive value is isolated); axes the schema checks together (the
same section's cross-field check, a tagged union, or the checks across
sections of ``sampling_problem``) only together, in every combination of
their grid values with the corners of their random ranges and the corners
just inside. An error names the axis key, or the values of the combination.
A file a grid value names is found beside the sweep file. One exception, checked case by case: a random axis of the path
or the part on a curved part whose checks are not intervals in it (the
scenario's ``NOT_INTERVALS`` by shape: the path's reach within a sphere's
or cylinder's domain is not monotone in its direction, a turned raster
reaching furthest at 45 deg; a height map's concave curvature along the
path changes with the path's size, direction and lanes and the grid's
spacing), so a value between two valid ends can be invalid; an error names
the case.
"""

from __future__ import annotations

import copy
import hashlib
import itertools
import json
import math
import pathlib
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..simulation.scenario import (BUILTIN_ARMS, NOT_INTERVALS, SAMPLED_KEYS, Scenario, ScenarioError, applicable_settings,
                                   load_scenario, read_toml, replace_plane, resolve_files, scenario_from_dict,
                                   scenario_to_dict, set_key, takes_a_number)

__all__ = ["SweepError", "Sweep", "Case", "Cases", "load_sweep", "sweep_from_dict", "EXAMPLE", "DEFAULT_MAX_CASES",
           "check_sweep_size", "check_sweep_robots"]

EXAMPLE = '''# tmtcontrol sweep file: a base scenario, then axes over dotted scenario keys.
# Cases = every grid combination x every random sample. SI units, as in scenarios.
scenario = "paper"            # "paper" or a scenario TOML file (relative to this file)

[grid]
# a grid value is what --set takes for that key: one stiffness profile per entry
"environment.stiffness.values" = [[2000.0], [20000.0], [200000.0]]
# or generated: { linspace = [start, stop, n] } / { geomspace = [start, stop, n] }
"controller.x_e_error" = [0.0, 0.005]

[random]
samples = 100                 # draws, each combined with every grid point
seed = 1                      # same seed, same draws
"sensor.noise_std" = { uniform = [0.0, 0.2] }
# also: { loguniform = [a, b] } and { normal = [mean, std], bounds = [lo, hi] }
'''


DEFAULT_MAX_CASES = 100_000
"""Sweeps of more cases are refused before anything is generated (``--max-cases``)."""

DRAW_BLOCK = 1024
"""Random draws come in blocks: sample ``i`` is entry ``i % 1024`` of block
``i // 1024``, drawn by PCG64 seeded with ``[seed, block]`` (so any case is
generated from its index alone)."""

NORMAL_SPAN = 10.0
"""A normal axis without ``bounds`` is truncated at mean +- 10 std (a
probability of 2e-23 per draw): the range its validation covers."""

SECONDS_PER_STEP = 0.7e-6
SECONDS_PER_CASE = 4e-3
"""The estimate printed before a sweep runs: per control step of a 3-joint
arm's loop (the PUMA's compiled rollout: 0.47-0.73 µs a step on the 2-core
machines measured) and per case (metrics, the row); a step of an arm of n
joints costs :meth:`Sweep.arm_cost` times as much (the UR5's 2.3 µs, the
Panda's 3.9 µs, docs/robots.md)."""

SECONDS_PER_LIMIT = 2.5
"""The estimate's cost of one case family's deciding limit
(``sweep.run.case_limits``) on a 3-joint arm (the paper loop's periodic and
first-contact searches, its compiled steps cached), times
:meth:`Sweep.arm_cost` (review 31: the UR5's took about 11 s). Every worker
computes each family it meets (the limit is memoised per worker), so the
workers do not share this cost: it is counted once per family, not divided
among them."""

ARM_COST_CASES = 64
"""Cases :meth:`Sweep.arm_cost` averages over when an axis changes the arm."""

SECONDS_TO_START = 0.5
"""The estimate's fixed part: the workers' start-up, loading the compiled
step and each family's noise-free twin (review 31: a 32-case sweep of 1 s
was estimated at 0.2 s)."""

ANALYSIS_FREE_PREFIXES = ("environment.stiffness", "trajectory.cycles")
"""Axes under these keys leave a case's analysis as it was (the limit does
not depend on k_e or the run length), so the memoised limit is reused across
their values and draws; so do the keys no limit reads at all
(``stability.limit.UNREAD_KEYS``: the joint rates, the reserve held below
each limit, the verdicts' tolerances, the MuJoCo plant's settings)."""


def changes_analysis(axis: str, saturates: bool = True, approaches: bool = True) -> bool:
    """Whether a sweep axis changes a case's limit analysis: not under
    :data:`ANALYSIS_FREE_PREFIXES` nor ``stability.limit.UNREAD_KEYS``, nor
    under ``stability.limit.CLIP_KEYS`` when no case clips its torque
    (``saturates`` False), nor under ``stability.limit.APPROACH_KEYS`` (the
    sensor noise) when no case starts with a guarded approach (``approaches``
    False)."""
    from ..stability.limit import APPROACH_KEYS, CLIP_KEYS, UNREAD_KEYS

    return not (axis.startswith(ANALYSIS_FREE_PREFIXES + UNREAD_KEYS)
                or (not saturates and axis.startswith(CLIP_KEYS))
                or (not approaches and axis.startswith(APPROACH_KEYS)))


STEP_KEYS = ("trajectory.cycles", "trajectory.period", "controller.rate")
"""A case's control steps: cycles x period x rate."""


class SweepError(ValueError):
    """An invalid sweep file; the message names the key (exit code 2 in the CLI)."""


@dataclass(frozen=True)
class Case:
    """One case: its index and the value of every axis, by dotted key."""
    index: int
    values: dict[str, Any]


class Cases(Sequence):
    """The cases of a sweep, generated on demand from their index: every grid
    combination (the last grid axis fastest) times every random sample.
    Memory does not grow with the number of cases: ``cases[i]`` is index
    arithmetic over the grid and a block of seeded draws; a slice, or
    :meth:`without`, is a view of the case indices."""

    def __init__(self, grid: dict[str, list], random: dict[str, dict], samples: int, seed: int,
                 positions: range | np.ndarray | None = None):
        self.grid, self.random, self.samples, self.seed = grid, random, samples, seed
        lens = [len(v) for v in grid.values()]
        self.total = math.prod(lens) * samples
        self._strides = [math.prod(lens[j + 1:]) for j in range(len(lens))]
        self._positions = range(self.total) if positions is None else positions
        self._blocks: dict[int, dict[str, np.ndarray]] = {}

    def __len__(self) -> int:
        return len(self._positions)

    def __getitem__(self, i):
        if isinstance(i, slice):
            return Cases(self.grid, self.random, self.samples, self.seed, self._positions[i])
        return self.case(int(self._positions[i]))

    def __iter__(self):
        for index in self._positions:
            yield self.case(int(index))

    def __getstate__(self):
        return {**self.__dict__, "_blocks": {}}

    def case(self, index: int) -> Case:
        """The case of index ``index`` (0 <= index < total)."""
        if not 0 <= index < self.total:
            raise IndexError(f"case {index} of {self.total}")
        g, s = divmod(index, self.samples)
        values = {key: vals[(g // stride) % len(vals)]
                  for (key, vals), stride in zip(self.grid.items(), self._strides)}
        values.update(self.draw(s))
        return Case(index, values)

    def draw(self, sample: int) -> dict[str, float]:
        """The random axes' values of sample ``sample``."""
        if not self.random:
            return {}
        j, k = divmod(sample, DRAW_BLOCK)
        if j not in self._blocks:
            if len(self._blocks) >= 4:
                self._blocks.clear()
            self._blocks[j] = _draw_block(self.random, self.seed, j)
        return {key: float(v[k]) for key, v in self._blocks[j].items()}

    def without(self, done) -> "Cases":
        """A view of these cases without the indices in ``done``."""
        if not done:
            return self
        pos = np.asarray(self._positions if isinstance(self._positions, np.ndarray) else
                         np.arange(self._positions.start, self._positions.stop, self._positions.step))
        return Cases(self.grid, self.random, self.samples, self.seed,
                     pos[~np.isin(pos, np.fromiter(done, dtype=np.int64, count=len(done)))])


@dataclass(frozen=True)
class Sweep:
    """A validated sweep: the base scenario (as a dict), the axes and the cases
    (generated lazily, see :class:`Cases`)."""
    base: dict
    grid: dict[str, list]
    random: dict[str, dict]
    samples: int
    seed: int
    cases: Cases

    @property
    def axes(self) -> list[str]:
        return [*self.grid, *self.random]

    @property
    def shape(self) -> str:
        """The sweep's size in words: ``3 x 2 grid x 100 random samples``."""
        grid = " x ".join(f"{len(v):,}" for v in self.grid.values())
        return " x ".join([*([f"{grid} grid"] if grid else []),
                           *([f"{self.samples:,} random samples"] if self.random else [])])

    def scenario(self, case: Case) -> Scenario:
        return case_scenario(self.base, case.values)

    @property
    def units(self) -> dict[str, str]:
        """Each axis' SI unit from the scenario schema ("" where it has none,
        such as a law's name), as the first case's scenario applies it."""
        rows = {r.key: r.unit for r in applicable_settings(self.scenario(self.cases[0]))} if self.cases else {}
        return {axis: "" if rows.get(axis, "") == "1" else rows.get(axis, "") for axis in self.axes}

    @property
    def fingerprint(self) -> str:
        """SHA-256 of the base scenario and everything that generates the cases
        (axes, samples, seed, the draw scheme): a resumed sweep must match it."""
        blob = json.dumps({"base": self.base, "grid": self.grid, "random": self.random, "samples": self.samples,
                           "seed": self.seed, "draws": f"PCG64([seed, block]) blocks of {DRAW_BLOCK}"},
                          sort_keys=True, default=str)
        return hashlib.sha256(blob.encode()).hexdigest()

    def steps(self) -> tuple[float, int, int]:
        """``(total, largest, index)``: the control steps of all cases, the
        most of one case and that case's index, from the axes that set
        ``trajectory.cycles``, ``trajectory.period`` or ``controller.rate``
        (one evaluation per combination of those axes, not per case)."""
        relevant = [a for a in self.axes if any(_covers(a, k) for k in STEP_KEYS)]
        gkeys = [a for a in relevant if a in self.grid]
        rand = any(a in self.random for a in relevant)
        combos = math.prod(len(self.grid[a]) for a in gkeys) * (self.samples if rand else 1)
        per = self.cases.total // combos          # cases per combination
        total, most, where = 0.0, -1.0, 0
        strides = dict(zip(self.grid, self.cases._strides))
        for gi in itertools.product(*(range(len(self.grid[a])) for a in gkeys)):
            for s in range(self.samples if rand else 1):
                values = {a: self.grid[a][i] for a, i in zip(gkeys, gi)}
                if rand:
                    values.update({a: v for a, v in self.cases.draw(s).items() if a in relevant})
                index = sum(i * strides[a] for a, i in zip(gkeys, gi)) * self.samples + s
                got = [_resolve(self.base, values, [a for a in self.axes if a in values], k) for k in STEP_KEYS]
                if None in got:         # a whole table as an axis value: its missing fields take the defaults
                    sc = self.scenario(self.cases.case(index))
                    got = [sc.trajectory.cycles, sc.trajectory.period, sc.controller.rate]
                n = math.prod(float(v) for v in got)
                total += n * per
                if n > most:
                    most, where = n, index
        return total, int(round(most)), where

    def plan(self, todo: int | None = None, workers: int = 1, limits: bool = False) -> str:
        """The line printed before the first case runs: the number of cases,
        the sweep's shape and the estimated run time of the ``todo`` cases
        still to run (default all), with ``limits`` the cases' limit
        analyses included (:meth:`limit_families`)."""
        todo = self.cases.total if todo is None else todo
        left = f", {self.cases.total - todo:,} already done" if todo < self.cases.total else ""
        sec = self.estimate_seconds(todo, workers, limits)
        when = f"{sec:.0f} s" if sec < 120 else f"{sec / 60:.0f} min" if sec < 7200 else f"{sec / 3600:.1f} h"
        n = self.limit_families()
        how = (f"estimate, {n:,} limit analys{'i' if n == 1 else 'e'}s included" if limits else "estimate")
        return (f"sweep: {self.cases.total:,} cases ({self.shape}){left}; about {when} on {workers} "
                f"worker{'s' if workers > 1 else ''} ({how})")

    def limit_families(self) -> int:
        """How many distinct limit analyses the cases need (their families,
        ``sweep.run.case_limits``): the combinations of the grid axes that
        change the analysis (all but :data:`ANALYSIS_FREE_PREFIXES`), times
        the random samples if a random axis changes it too."""
        flags = self.may_saturate(), self.may_approach()
        n = math.prod(len(v) for a, v in self.grid.items() if changes_analysis(a, *flags))
        return n * (self.samples if any(changes_analysis(a, *flags) for a in self.random) else 1)

    def unit_notes(self) -> list[str]:
        """The notes of values whose verdicts say little or that read like a
        unit mistake (``EnvironmentSettings.unit_notes``: a part's radius
        above ``LARGE_RADIUS``; ``ControllerSettings.unit_notes``: a force
        tolerance not below f_d, an f_d below twice the law's force
        threshold) in the base scenario and on the axes, each
        once (review 48: a sweep printed none). The axes that can set those
        keys are taken at their extremes (a scalar grid axis's smallest and
        largest value, a random axis's range ends, every value of an axis over
        a whole table) and combined: the notes are monotone in each key."""
        keys = ("environment.radius", "controller.f_d", "controller.force_tolerance", "controller.law.force_threshold")
        axes: dict[str, list] = {}
        for axis, values in self.grid.items():
            if any(_covers(axis, k) for k in keys):
                numbers = all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in values)
                axes[axis] = sorted({min(values), max(values)}) if axis in keys and numbers else list(values)
        for axis, spec in self.random.items():
            if any(_covers(axis, k) for k in keys):
                axes[axis] = sorted(set(_range(spec)))
        notes: list[str] = []
        for combo in itertools.product(*axes.values()):
            try:
                sc = case_scenario(self.base, dict(zip(axes, combo)))
            except ScenarioError:     # a combination no case has (the sweep's own checks refuse real ones)
                continue
            notes += sc.environment.unit_notes() + sc.controller.unit_notes()
        return list(dict.fromkeys(notes))

    def may_saturate(self) -> bool:
        """Whether some case may clip its torque (``robot.saturate`` on in the
        base scenario, or an axis that sets it): only then do the torque
        limits change a case's analysis (``stability.limit.CLIP_KEYS``)."""
        return bool(self.base["robot"].get("saturate")) or any(_covers(a, "robot.saturate")
                                                                for a in (*self.grid, *self.random))

    def may_approach(self) -> bool:
        """Whether some case may start with a guarded approach (in the base
        scenario, or an axis that sets its gap or speed): only then does the
        sensor noise change a case's analysis (``stability.limit.APPROACH_KEYS``)."""
        from ..simulation.environment import has_approach

        return has_approach(case_scenario(self.base, {})) or any(
            _covers(a, k) for a in (*self.grid, *self.random) for k in ("trajectory.approach_gap",
                                                                        "controller.approach_speed"))

    def arm_cost(self) -> float:
        """How much a control step and a limit analysis of the cases' arm cost
        against a 3-joint arm's: ``(n / 3)**2`` for n joints (the dynamics'
        operations grow about so: a step measured 3.7x for the UR5's 6
        joints, 6.2x for the Panda's 7, docs/robots.md; a UR5 limit analysis
        about 4.4x, review 31); 1 for an arm that cannot be loaded (the
        cases' validation says why). With an axis under ``robot``, the mean
        over up to :data:`ARM_COST_CASES` cases spread evenly over the sweep
        (every case of a smaller one: review 35, the first case's arm alone
        made the estimate depend on the grid's order)."""
        from ..simulation.simulator import robot_of

        def cost(index: int) -> float:
            try:
                joints = robot_of(self.scenario(self.cases.case(index))).n
            except (ValueError, OSError):          # ScenarioError among them
                return 1.0
            return (max(joints, 3) / 3.0) ** 2

        return float(self._over_cases(cost, "robot", 1.0))

    def _over_cases(self, cost, key: str, empty):
        """``cost(case index)`` of the first case, or (an axis covering
        ``key``) its mean over up to :data:`ARM_COST_CASES` cases spread
        evenly over the sweep; ``empty`` for a sweep without cases."""
        total = self.cases.total
        if total == 0:
            return empty
        if not any(_covers(axis, key) for axis in self.axes):
            return cost(0)
        picks = sorted({int(i) for i in np.linspace(0, total - 1, min(total, ARM_COST_CASES))})
        return np.mean([cost(i) for i in picks], axis=0)

    def surface_cost(self) -> tuple[float, float]:
        """What the cases' surfaces add to a step's and to a limit
        analysis's cost, in units of a 3-joint arm's on a plane
        (:attr:`~tmtcontrol.surface.Surface.step_cost`,
        :attr:`~tmtcontrol.surface.Surface.analysis_cost`: a measured height
        map's spline costs about 12x the plane's step; review 43: a 4-case
        sweep over height maps was estimated at 11 s and took 324 s); with an
        axis that sets ``environment.shape``, the mean over up to
        :data:`ARM_COST_CASES` cases spread evenly over the sweep, as
        :meth:`arm_cost`, read from each case's ``environment.shape`` (the
        shape's class: no surface is built; review 44, a 256 x 256 map took 2 s
        a case); (0, 0) for a case that cannot be built."""
        from ..surface import SHAPES

        def cost(index: int) -> tuple[float, float]:
            try:
                shape = SHAPES[self.scenario(self.cases.case(index)).environment.shape]
            except (ValueError, OSError, KeyError):          # ScenarioError among them
                return 0.0, 0.0
            return shape.step_cost, shape.analysis_cost

        step, analysis = self._over_cases(cost, "environment.shape", (0.0, 0.0))    # only the shape chooses it
        return float(step), float(analysis)

    def estimate_seconds(self, cases: int | None = None, workers: int = 1, limits: bool = False) -> float:
        """A rough run time (s) of ``cases`` of the cases (default all) on
        ``workers`` processes: :data:`SECONDS_TO_START`, then
        :data:`SECONDS_PER_STEP` per control step (times :meth:`arm_cost`)
        and :data:`SECONDS_PER_CASE` per case shared by the workers, before
        any compilation; with ``limits``, :data:`SECONDS_PER_LIMIT` (times
        :meth:`arm_cost`) per limit analysis (the families' share of
        ``cases``), which every worker computes for itself. The surfaces'
        own costs (:meth:`surface_cost`) add to the arm's."""
        n = self.cases.total if cases is None else cases
        share = n / max(self.cases.total, 1)
        total = self.steps()[0] * share
        cost = self.arm_cost()
        step_extra, analysis_extra = self.surface_cost()
        analyses = (self.limit_families() * share * SECONDS_PER_LIMIT * (cost + analysis_extra) if limits
                    else 0.0)
        return SECONDS_TO_START + (total * SECONDS_PER_STEP * (cost + step_extra)
                                   + n * SECONDS_PER_CASE) / max(1, workers) + analyses


def check_sweep_size(sweep: Sweep, max_steps: int | None = None) -> None:
    """Refuse (:class:`ScenarioError`, naming the case) a sweep whose longest
    case has more than ``max_steps`` control steps (default
    :data:`~tmtcontrol.simulation.simulator.MAX_STEPS`); found from the axes
    (:meth:`Sweep.steps`), not by building every case."""
    from ..simulation.simulator import check_run_size

    index = sweep.steps()[2]
    case = sweep.cases.case(index)
    try:
        check_run_size(sweep.scenario(case), max_steps)
    except ScenarioError as exc:
        raise ScenarioError(f"{exc} (case {index}: {_describe(case.values)})") from None


ARM_KEYS = ("robot.model", "robot.tip", "robot.q0", "robot.tau_max", "robot.dq_max", "robot.saturate")
"""The keys that choose a case's arm (and its joints) or are checked per
joint against it (:func:`check_sweep_robots`)."""


def check_sweep_robots(sweep: Sweep) -> None:
    """Refuse (:class:`ScenarioError`, naming the key and the case) a sweep in
    which a case's arm cannot be loaded or its per-joint settings
    (``robot.q0``, ``robot.tau_max``, ``robot.dq_max``) do not fit it
    (:func:`~tmtcontrol.simulation.simulator.check_joint_settings`): the
    schema checks each axis without the arm, so a grid over ``robot.model``
    with a base's 6-value ``q0`` passed it and stopped at its first 7-joint
    case, with the finished cases written. Once per combination of the grid
    axes under ``robot`` (a case's arm and per-joint values come from those
    and the base; a random axis is a number that changes neither) that can
    change the arm or those settings (:data:`ARM_KEYS`: review 40, a
    100,000-case grid of ``robot.posture_kp`` beside two arms took 15 s of
    checks), before any case runs."""
    from ..simulation.simulator import check_joint_settings, robot_of

    keys = [k for k in sweep.grid if any(_covers(k, key) for key in ARM_KEYS)]
    strides = dict(zip(sweep.grid, sweep.cases._strides))
    for combo in itertools.product(*(range(len(sweep.grid[k])) for k in keys)):
        index = sum(i * strides[k] for k, i in zip(keys, combo)) * sweep.cases.samples
        case = sweep.cases.case(index)
        try:
            sc = sweep.scenario(case)
            check_joint_settings(robot_of(sc), sc)
        except ScenarioError as exc:
            raise ScenarioError(f"{exc} (case {index}: {_describe(case.values)})") from None


def _covers(axis: str, key: str) -> bool:
    """Whether setting ``axis`` can change ``key`` or what is under it (either is a prefix of the other)."""
    return axis == key or key.startswith(axis + ".") or axis.startswith(key + ".")


def _resolve(base: dict, values: dict, order: list[str], key: str):
    """The value of scalar ``key`` once ``values`` (applied in ``order``) are set
    on ``base``; None when an axis sets a whole table without it (the schema's
    default then applies, not the base's value)."""
    for axis in reversed(order):
        if axis == key or key.startswith(axis + "."):
            node = values[axis]
            for part in key[len(axis):].split(".")[1:]:
                if not isinstance(node, dict) or part not in node:
                    return None
                node = node[part]
            return node
    node = base
    for part in key.split("."):
        node = node[part]
    return node


def _current(d: dict, key: str):
    node = d
    for part in key.split("."):
        if not isinstance(node, dict) or part not in node:
            return None
        node = node[part]
    return node


def case_scenario(base: dict, values: dict) -> Scenario:
    """The scenario of one case: ``base`` with each axis value set. A number
    given for a list-valued key (e.g. a generated stiffness) is a one-element
    list."""
    d = json.loads(json.dumps(base))
    replace_plane(d, values)              # an axis over the plane's normal or tilt replaces the base's other form
    # the outer key first: a law's kind ("controller.law" = "rls", which resets the table) before its parameters
    for key, value in sorted(values.items(), key=lambda kv: kv[0].count(".")):
        if isinstance(value, (int, float)) and not isinstance(value, bool) and isinstance(_current(d, key), list) \
                and not takes_a_number(key):
            value = [value]
        set_key(d, key, copy.deepcopy(value))   # a table value is the sweep's own: never edited in place
    return scenario_from_dict(d)


def _generated_length(key: str, spec: dict) -> int:
    """The number of values of a generated grid axis, checked, without generating them."""
    (kind, args), = spec.items() if len(spec) == 1 else (("?", None),)
    if kind not in ("linspace", "geomspace") or not (isinstance(args, list) and len(args) == 3):
        raise SweepError(f"grid.{key}: expected a list of values, {{ linspace = [a, b, n] }} or "
                         f"{{ geomspace = [a, b, n] }}, got {spec!r}")
    a, b, n = args
    if not all(isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in (a, b)):
        raise SweepError(f"grid.{key}: {kind} needs finite numbers for start and stop, got {args!r}")
    if not (isinstance(n, int) and not isinstance(n, bool) and n >= 1):
        raise SweepError(f"grid.{key}: {kind} needs [start, stop, n] with n an integer >= 1, got {args!r}")
    if kind == "geomspace" and not (a > 0 and b > 0):
        raise SweepError(f"grid.{key}: geomspace needs start, stop > 0, got {args!r}")
    return n


def _generated(spec: dict) -> list:
    (kind, (a, b, n)), = spec.items()
    return [float(v) for v in getattr(np, kind)(a, b, n)]


def _normal_range(spec: dict) -> tuple[float, float]:
    mean, std = spec["normal"]
    return tuple(spec["bounds"]) if "bounds" in spec else (mean - NORMAL_SPAN * std, mean + NORMAL_SPAN * std)


def _normal_mass(spec: dict) -> float:
    """The probability of the normal's truncation range."""
    mean, std = spec["normal"]
    lo, hi = _normal_range(spec)
    if std == 0:
        return 1.0 if lo <= mean <= hi else 0.0
    from scipy.special import ndtr

    a, b = (lo - mean) / std, (hi - mean) / std
    return float(ndtr(-a) - ndtr(-b)) if a > 0 else float(ndtr(b) - ndtr(a))


def _draw_block(random: dict[str, dict], seed: int, block: int) -> dict[str, np.ndarray]:
    """Block ``block`` of :data:`DRAW_BLOCK` draws of every random axis (in order)."""
    rng = np.random.default_rng([seed, block])
    out = {}
    for key, spec in random.items():
        if "uniform" in spec:
            a, b = spec["uniform"]
            x = np.clip(rng.uniform(a, b, DRAW_BLOCK), a, b)
        elif "loguniform" in spec:
            a, b = spec["loguniform"]
            x = np.clip(np.exp(rng.uniform(math.log(a), math.log(b), DRAW_BLOCK)), a, b)
        else:       # a truncated normal by its inverse CDF, computed in the lower tail for precision
            from scipy.special import ndtr, ndtri

            mean, std = spec["normal"]
            lo, hi = _normal_range(spec)
            u = rng.uniform(0.0, 1.0, DRAW_BLOCK)
            if std == 0:
                x = np.full(DRAW_BLOCK, mean)
            else:
                a, b = (lo - mean) / std, (hi - mean) / std
                if a > 0:
                    pa, pb = ndtr(-b), ndtr(-a)
                    x = mean - std * ndtri(pa + u * (pb - pa))
                else:
                    pa, pb = ndtr(a), ndtr(b)
                    x = mean + std * ndtri(pa + u * (pb - pa))
            x = np.clip(x, lo, hi)
        out[key] = x
    return out


def _check_random(key: str, spec) -> dict:
    def pair(name, v, positive=False):
        if not (isinstance(v, list) and len(v) == 2 and all(isinstance(x, (int, float)) and not isinstance(x, bool)
                                                             and math.isfinite(x) for x in v)):
            raise SweepError(f"random.{key}: {name} needs two finite numbers, got {v!r}")
        if positive and not (v[0] > 0 and v[1] > 0):
            raise SweepError(f"random.{key}: {name} needs numbers > 0, got {v!r}")
        return [float(x) for x in v]

    if not isinstance(spec, dict):
        raise SweepError(f"random.{key}: expected {{ uniform = [a, b] }}, {{ loguniform = [a, b] }} or "
                         f"{{ normal = [mean, std], bounds = [lo, hi] }}, got {spec!r}")
    kinds = set(spec) & {"uniform", "loguniform", "normal"}
    if len(kinds) != 1 or set(spec) - {"uniform", "loguniform", "normal", "bounds"} or \
            ("bounds" in spec and "normal" not in spec):
        raise SweepError(f"random.{key}: expected exactly one of uniform, loguniform, normal (bounds only with "
                         f"normal), got {sorted(spec)}")
    kind = kinds.pop()
    out = {kind: pair(kind, spec[kind], positive=kind == "loguniform")}
    if kind in ("uniform", "loguniform") and out[kind][0] > out[kind][1]:
        raise SweepError(f"random.{key}: {kind} needs a <= b, got {spec[kind]!r}")
    if kind == "normal":
        if out["normal"][1] < 0:
            raise SweepError(f"random.{key}: normal needs std >= 0, got {spec['normal']!r}")
        if "bounds" in spec:
            out["bounds"] = pair("bounds", spec["bounds"])
            if out["bounds"][0] > out["bounds"][1]:
                raise SweepError(f"random.{key}: bounds need lo <= hi, got {spec['bounds']!r}")
    lo, hi = _range(out)
    if not (math.isfinite(lo) and math.isfinite(hi)) or (kind == "uniform" and not math.isfinite(hi - lo)):
        # a uniform draw computes a + (b - a) u: a width past the largest float
        # (1.8e308) would overflow in every case; a normal's mean +- 10 std must be a number
        raise SweepError(f"random.{key}: range [{lo:g}, {hi:g}] is wider than the largest float, "
                         f"{np.finfo(float).max:g}")
    if kind == "normal" and _normal_mass(out) < 1e-9:
        (mean, std), (lo, hi) = out["normal"], _normal_range(out)
        raise SweepError(f"random.{key}: bounds [{lo:g}, {hi:g}] too far in the tail of normal({mean:g}, {std:g})")
    return out


def _range(spec: dict) -> tuple[float, float]:
    """The interval a random axis draws from (a normal of std 0: its mean)."""
    if "normal" in spec:
        mean, std = spec["normal"]
        return (mean, mean) if std == 0 else _normal_range(spec)
    return tuple(spec["uniform" if "uniform" in spec else "loguniform"])


def _scopes() -> list[tuple[str, ...]]:
    """Groups of keys the schema checks together: each section with a check
    across its fields, each tagged union (its kind decides its fields), and
    the one check across sections (:data:`SAMPLED_KEYS`). Axes in no common
    group cannot make each other invalid."""
    from pydantic import BaseModel

    from ..simulation.scenario import TAGGED_TABLES

    scopes = [(".".join(loc),) for loc in TAGGED_TABLES]
    for name, info in Scenario.model_fields.items():
        ann = info.annotation
        if isinstance(ann, type) and issubclass(ann, BaseModel) and ann.__pydantic_decorators__.model_validators:
            scopes.append((name,))
    scopes.append(SAMPLED_KEYS)
    return scopes


def _coupled_groups(axes: list[str]) -> list[list[str]]:
    """The axes in groups that must be validated together (union-find over :func:`_scopes`)."""
    parent = {a: a for a in axes}

    def find(a):
        while parent[a] != a:
            a = parent[a]
        return a

    scopes = _scopes()
    for i, a in enumerate(axes):
        for b in axes[i + 1:]:
            if _covers(a, b) or any(any(_covers(a, p) for p in sc) and any(_covers(b, p) for p in sc)
                                    for sc in scopes):
                parent[find(a)] = find(b)
    groups: dict[str, list[str]] = {}
    for a in axes:
        groups.setdefault(find(a), []).append(a)
    return [g for g in groups.values() if len(g) > 1]


def _validate(base: dict, grid: dict[str, list], random: dict[str, dict], cases: Cases) -> None:
    """Every case's scenario is valid. An axis the schema checks alone is
    checked by itself: each grid value once; each random axis at both ends
    of its range and at the numbers just inside them (the schema's
    constraints are intervals and linear inequalities, so a box is valid if
    its corners are; an isolated valid value, a 0 meaning "off" or "the
    path's period" beside a least positive value, is found next to the end
    it sits on). Axes the schema checks together (:func:`_coupled_groups`)
    are checked only together, never against the base's value of the
    others (which no case may have): every combination of their grid values
    with the corners of their random ranges' box and of the box just inside
    it (2 x 2^k checks for k random axes, not 4^k). When a random axis is a
    key in which the checks of some case's part do not hold on an interval
    (``NOT_INTERVALS`` of its shape, :func:`_shapes`): every case."""
    order = [*grid, *random]
    groups = _coupled_groups(order)
    coupled = {k for group in groups for k in group}
    for key, values in grid.items():
        for i, v in enumerate(values if key not in coupled else ()):
            try:
                case_scenario(base, {key: v})
            except ScenarioError as exc:
                raise SweepError(f"grid.{key}[{i}] = {v!r}: {exc}") from None
    for key, spec in random.items():
        if key in coupled:
            continue
        for v in dict.fromkeys(_ends(spec)):
            try:
                case_scenario(base, {key: v})
            except ScenarioError as exc:
                kind = next(k for k in ("uniform", "loguniform", "normal") if k in spec)
                raise SweepError(f"random.{key}: {kind} range [{_range(spec)[0]:g}, {_range(spec)[1]:g}] "
                                 f"reaches {v!r}: {exc}") from None
    strides = dict(zip(grid, cases._strides))
    for group in groups:
        gkeys = [k for k in group if k in grid]
        rkeys = [k for k in group if k in random]
        # the corners of the box and of the box just inside: 2 x 2^k checks, not 4^k
        corners = list(dict.fromkeys([*itertools.product(*(_range(random[k]) for k in rkeys)),
                                      *itertools.product(*(_ends(random[k])[2:] for k in rkeys))]))
        for gi in itertools.product(*(range(len(grid[k])) for k in gkeys)):
            for corner in corners:
                values = {k: grid[k][i] for k, i in zip(gkeys, gi)} | dict(zip(rkeys, corner))
                values = {k: values[k] for k in order if k in values}
                if rkeys:
                    try:
                        case_scenario(base, values)
                    except ScenarioError as exc:
                        raise SweepError(f"cases with {_describe(values)} (ends of the random ranges): "
                                         f"{exc}") from None
                else:
                    _check_case(base, cases, sum(i * strides[k] for k, i in zip(gkeys, gi)) * cases.samples)
    if random and set(random) & {k for shape in _shapes(base, grid) for k in NOT_INTERVALS[shape]}:
        for index in range(cases.total):      # about 2 ms a case
            _check_case(base, cases, index)


def _ends(spec: dict) -> list[float]:
    """A random axis's range ends and the numbers just inside them: a valid
    set with an isolated point at an end (a stiffness segment of 0 = the
    path's period, else at least 10 control periods) passes at its ends only."""
    lo, hi = _range(spec)
    return [lo, hi, float(np.nextafter(lo, hi)), float(np.nextafter(hi, lo))]


def _check_case(base: dict, cases: Cases, index: int) -> None:
    """Case ``index``'s scenario through the schema; invalid: a SweepError
    naming the case by its index and values."""
    values = cases.case(index).values
    try:
        case_scenario(base, values)
    except ScenarioError as exc:
        raise SweepError(f"case {index} ({_describe(values)}): {exc}") from None


def _shapes(base: dict, grid: dict[str, list]) -> set[str]:
    """The part shapes the sweep's cases take: the base's, or with grid axes
    that set the shape (``environment.shape``, a whole ``environment``
    table), each combination's (already validated)."""
    keys = [k for k in grid if _covers(k, "environment.shape")]
    # each combination of those axes, applied in order as a case applies them (a value may be
    # replaced by a later axis's table, and valid only beside the others)
    return {_resolve(base, dict(zip(keys, combo)), keys, "environment.shape") or "plane"
            for combo in itertools.product(*(grid[k] for k in keys))}


def sweep_from_dict(data: Any, folder: pathlib.Path | None = None,
                    max_cases: int | None = DEFAULT_MAX_CASES) -> Sweep:
    """Validate a parsed sweep file (see the module docstring). A sweep of
    more than ``max_cases`` cases (None: no limit) is refused before any case
    or generated axis value exists."""
    if not isinstance(data, dict):
        raise SweepError(f"sweep: expected a table, got {data!r}")
    unknown = set(data) - {"scenario", "grid", "random"}
    if unknown:
        raise SweepError(f"{sorted(unknown)[0]}: unknown key (expected scenario, [grid], [random])")
    src = data.get("scenario", "paper")
    if not isinstance(src, str):
        raise SweepError(f"scenario: expected \"paper\" or a file name, got {src!r}")
    grid_in = data.get("grid", {})
    random_in = dict(data.get("random", {})) if isinstance(data.get("random", {}), dict) else None
    if not isinstance(grid_in, dict) or random_in is None:
        raise SweepError("grid, random: expected tables")
    samples = random_in.pop("samples", 1 if not random_in else None)
    seed = random_in.pop("seed", 0)
    if random_in and samples is None:
        raise SweepError("random.samples: required with random axes (an integer >= 1)")
    if not (isinstance(samples, int) and not isinstance(samples, bool) and samples >= 1):
        raise SweepError(f"random.samples: expected an integer >= 1, got {samples!r}")
    if not (isinstance(seed, int) and not isinstance(seed, bool) and seed >= 0):
        raise SweepError(f"random.seed: expected an integer >= 0, got {seed!r}")
    lengths = {}
    for key, values in grid_in.items():
        if isinstance(values, dict):
            lengths[key] = _generated_length(key, values)
        elif not isinstance(values, list) or not values:
            raise SweepError(f"grid.{key}: expected a non-empty list of values, got {values!r}")
        else:
            lengths[key] = len(values)
    random = {key: _check_random(key, spec) for key, spec in random_in.items()}
    overlap = set(grid_in) & set(random)
    if overlap:
        raise SweepError(f"{sorted(overlap)[0]}: both a grid and a random axis")
    axes = [*grid_in, *random]
    tables = {a for a in grid_in if isinstance(grid_in[a], list) and any(isinstance(v, dict) for v in grid_in[a])}
    nested = [(a, b) if len(a) < len(b) else (b, a) for i, a in enumerate(axes) for b in axes[i + 1:]
              if a != b and _covers(a, b)]
    # a table overwrites what is inside it; a kind's name and its .kind set the same key (review 27)
    nested = [(outer, inner) for outer, inner in nested if outer in tables or inner == outer + ".kind"]
    if nested:      # the table would overwrite the other's values (review 23: a "controller" table dropped f_d)
        outer, inner = nested[0]
        holds = "whose tables hold it" if outer in tables else "whose names set it"
        raise SweepError(f"{inner}: also set by the axis {outer}, {holds}; sweep one of them (or "
                         f"give {inner} inside each value of {outer})")
    if not grid_in and not random:
        raise SweepError("grid, random: a sweep needs at least one axis")
    if max_cases is not None and (isinstance(max_cases, bool) or not (isinstance(max_cases, int) and max_cases >= 1)):
        raise SweepError(f"--max-cases: must be an integer >= 1, got {max_cases!r}")
    total = math.prod(lengths.values()) * samples
    if max_cases is not None and total > max_cases:
        shape = " x ".join([*(f"{n:,}" for n in lengths.values()), *([f"{samples:,} samples"] if random else [])])
        raise SweepError(f"--max-cases: the sweep has {total:,} cases ({shape}), more than the limit of "
                         f"{max_cases:,}; shrink its axes or raise --max-cases")
    try:
        if src == "paper" or src in BUILTIN_ARMS:            # the built-in scenarios by name
            base_sc = load_scenario(src)
        else:
            base_sc = load_scenario((folder / src) if folder is not None and not pathlib.Path(src).is_absolute()
                                    else src)
    except ScenarioError as exc:
        raise SweepError(f"scenario: {exc}") from None
    base = scenario_to_dict(base_sc)
    grid = {key: _generated(v) if isinstance(v, dict) else v for key, v in grid_in.items()}
    if folder is not None:      # a file a grid value names is found beside the sweep file, as in a scenario
        grid = {key: [_beside(key, v, folder) for v in values] for key, values in grid.items()}
    cases = Cases(grid, random, samples, seed)
    _validate(base, grid, random, cases)
    return Sweep(base, grid, random, samples, seed, cases)


def _beside(key: str, value: Any, folder: pathlib.Path) -> Any:
    """Grid value ``value`` of ``key`` with a relative file it names (a
    stiffness table, height map or URDF) joined to ``folder``."""
    parts = key.split(".")
    nested = copy.deepcopy(value)
    for part in reversed(parts):
        nested = {part: nested}
    resolve_files(nested, folder)
    for part in parts:
        nested = nested[part]
    return nested


def _describe(values: dict) -> str:
    return ", ".join(f"{k} = {v!r}" for k, v in values.items())


def load_sweep(path: str | pathlib.Path, max_cases: int | None = DEFAULT_MAX_CASES) -> Sweep:
    """Read and validate a sweep TOML file (a regular file of at most 16 MiB,
    see :func:`~tmtcontrol.simulation.scenario.read_text_file`)."""
    path = pathlib.Path(path)
    return sweep_from_dict(read_toml(path, "sweep", SweepError), path.parent, max_cases)
