"""Running a sweep: many simulations on local worker processes or a Dask cluster.

Each worker keeps one :class:`~tmtcontrol.Simulator` per closed-loop structure
(law, robot options, integrator, delay), so it loads (or compiles) each
compiled step once and then runs case after case; the path check is cached
per distinct path. Cases go out in chunks; every finished chunk is written at
once as ``part-NNNNNN.parquet`` in ``OUT.partial/`` beside the output folder,
so Ctrl-C or a crash loses no finished case and ``--resume`` runs only the
missing ones. A case's row depends only on its inputs (simulations are
deterministic, and compiled and virtual-machine runs are bit-identical), so
the results do not depend on the number of workers or on the engine.

Local parallelism uses :mod:`concurrent.futures` worker processes; a
distributed run uses ``dask.distributed`` (a ``LocalCluster`` or a running
scheduler's address). No scheduling of our own. Every worker runs with one
BLAS thread, and local workers die with the process that started them, even
one killed by SIGKILL (:mod:`tmtcontrol.processes`). A scheduler address is
checked (:func:`check_dask`) before anything is created.
"""

from __future__ import annotations

import contextlib
import json
import math
import os
import pathlib
import sys
import time
from typing import Any, Callable


from ..files import OutputError, check_interrupt
from ..processes import blas_threads_limited, one_blas_thread, signals_held, worker_init
from .spec import Case, Sweep, case_scenario, changes_analysis

__all__ = ["REFUSED", "run_cases", "case_row", "case_limits", "limits_by_default", "SEGMENT_FIELDS", "PartialFolder",
           "Progress", "check_dask",
           "SchedulerUnavailable", "kept_note"]

CONNECT_TIMEOUT = 3.0
"""Seconds to wait for a Dask scheduler's TCP port to accept a connection."""

CLIENT_TIMEOUT = "10s"
"""How long the Dask client may take to reach a scheduler whose port answered."""

SEGMENT_FIELDS = ("stiffness", "verdict", "steady_state_error", "steady_rms_error", "switch_jump",
                  "overshoot_pct", "settling_time")
"""Per-segment metrics in each row, as ``seg<i>_<field>`` (i from 1)."""

_SIMS: dict = {}       # per worker process: one Simulator per closed-loop structure


def _flat(value):
    """A swept value as a table cell: a one-element list as its element, a longer list as text."""
    if isinstance(value, list):
        return value[0] if len(value) == 1 and isinstance(value[0], (int, float)) else json.dumps(value)
    return value


REFUSED = "refused"
"""A sweep case's verdict when its run refuses it: a scenario the schema
accepts whose path the arm cannot follow (unreachable, outside the joint
limits, near a singularity; the row's ``error`` says which)."""


def case_row(base: dict, case: Case, max_steps: int | None = None, limits: bool = True) -> dict:
    """Simulate one case and return its row: the swept values (by dotted key),
    the case verdict (the worst segment's; ``diverged`` if the simulation blew
    up, :data:`REFUSED` if the run refused the case's path),
    ``max_steady_error`` (N, worst segment), the first contact and the
    per-segment metrics. With ``limits``, also the case's own predicted
    stiffness limits (:func:`case_limits`)."""
    from ..simulation.metrics import VERDICTS, first_contact, segment_metrics
    from ..simulation.simulator import simulator_for
    from ..stability.limit import with_stiffness_limit
    from ..simulation.posture import PathError
    from ..simulation.simulator import SimulationError, structure as _structure

    sc = case_scenario(base, case.values)
    key = _structure(sc)
    if key not in _SIMS:
        if len(_SIMS) >= 8:
            _SIMS.clear()
        _SIMS[key] = simulator_for(sc)
    row: dict[str, Any] = {"case": case.index, **{k: _flat(v) for k, v in case.values.items()}}
    found = None
    if limits:
        row.update(case_limits(sc, _SIMS[key]))
        found = row.pop("_limit")                       # the ScenarioLimit for the verdicts: not a column
    t0 = time.perf_counter()
    try:
        res = _SIMS[key].run(sc, max_steps=max_steps)
    except (SimulationError, PathError) as exc:
        # a case the run refuses (its path unreachable, outside the joint limits or near a singularity: checked
        # when it runs, not by the schema) is a row saying so, and the sweep goes on (review 68: it stopped
        # the sweep with a line naming no case, and --resume met the same case again); any other refusal (a
        # run longer than max_steps) stops the sweep, as before (review 70)
        refused = isinstance(exc, PathError)               # never run: no error to measure (NaN), not inf
        row.update({"verdict": REFUSED if refused else "diverged",
                    "max_steady_error": math.nan if refused else math.inf,
                    "first_contact_time": None,
                    "first_contact_peak": None, "first_contact_ratio": None, "first_contact_bounces": None,
                    "torque_margin": math.nan, "rate_margin": math.nan, "position_margin": math.nan,
                    "clip_time": math.nan, "error": str(exc), "run_time_s": time.perf_counter() - t0})
        return row
    if found is not None:
        res = with_stiffness_limit(res, found)         # as simulate attaches it
    segs = segment_metrics(res)
    fc = first_contact(res)
    row.update({"verdict": max((s.verdict for s in segs), key=VERDICTS.index),
                "max_steady_error": max(s.steady_state_error for s in segs),
                "first_contact_time": fc.time, "first_contact_peak": fc.peak_force,
                "first_contact_ratio": fc.peak_ratio, "first_contact_bounces": fc.bounces,
                # the arm's limits (simulation.limits): the least fraction of a torque / rate limit left, the
                # least distance to a joint end (rad); inf without limits, negative over them
                "torque_margin": min(s.torque_margin for s in segs), "rate_margin": min(s.rate_margin for s in segs),
                "position_margin": min(s.position_margin for s in segs),
                # the most time one joint's torque spent on its clip (robot.saturate; its episodes summed), s: a
                # converged case that only converged on the clip shows it (review 62)
                "clip_time": float(use.saturated.max()) if (use := res.limit_use()) is not None else 0.0,
                "error": "", "run_time_s": time.perf_counter() - t0})
    for i, s in enumerate(segs, 1):
        for f in SEGMENT_FIELDS:
            row[f"seg{i}_{f}"] = getattr(s, f)
    return row


_LIMITS: dict = {}     # per worker process: the deciding limit per case family (:func:`_family_key`)


def _family_key(sc, k_e_min: float) -> str:
    """What a case's limits depend on: the settings they read
    (``stability.limit.analysed_settings``: not the joint rates, the
    verdicts' tolerances, ..., nor the torque limits unless the case clips
    its torque, nor the noise unless it starts with a guarded approach)
    without the stiffness profile and the run length (the analyses run at
    constant k_e for their own durations); the files it names, by content."""
    from ..simulation.simulator import structure
    from ..stability.limit import analysed_settings

    d = analysed_settings(sc)
    d["environment"] = {k: v for k, v in d["environment"].items() if k != "stiffness"}
    d["trajectory"] = {k: v for k, v in d["trajectory"].items() if k != "cycles"}
    # the files the scenario names by path, by their content (review 47: a height map rewritten in place between
    # two run_sweep calls in one process kept the old map's limits): the structure holds the part's and the arm's keys
    d["content"] = repr(structure(sc))
    if sc.environment.damping > 0:
        # a contact damper can make the loop unstable on soft surfaces: the searches then take the stable
        # band that contains the smallest stiffness, so that stiffness is part of the family
        d["k_e_min"] = float(k_e_min)
    return json.dumps(d, sort_keys=True, default=str)



def limits_by_default(sweep: Sweep) -> tuple[bool, str]:
    """Whether a sweep computes each case's predicted limits when the user did
    not say (``--limits auto``), and why, as one line. On unless a random axis
    changes the analysis (``spec.changes_analysis``): a grid has few
    distinct case families (the limit is memoised per worker and family;
    a few seconds each), but every draw of, e.g., the x_e error is a new
    analysis of the loop."""
    costly = [k for k in sweep.random if changes_analysis(k, sweep.may_saturate(), sweep.may_approach())]
    if costly:
        return False, (f"sweep: predicted limits off (random {', '.join(costly)}: each draw is a new stability "
                       "analysis, seconds per case); --limits on computes them")
    return True, ("sweep: predicted limits on (each case family's deciding limit, as analyze --scenario; "
                  "--limits off skips)")


def case_limits(sc, sim=None) -> dict:
    """A case's stiffness limits with its own values (x_e error, delay, rate,
    impedance, law parameters ... as drawn), N/m: ``predicted_limit``, the
    limit that decides its verdict, as ``analyze --scenario`` and
    ``simulate`` quote it (``stability.limit.deciding_limit``, memoised per
    worker and case family: the stiffness profile, noise and length left
    out), ``predicted_limit_from`` (which of the limits decides),
    ``small_signal_limit`` (the 1-D sampled loop's, labelled as such),
    ``periodic_limit`` (along the path), ``first_contact_limit`` (from the
    case's own start, with the case's simulator ``sim``) and
    ``predicted_stable``: the case's largest stiffness below the predicted
    limit. NaN (and ``predicted_stable`` None) for a law without a linear
    verdict or an analysis that fails (``limits_error`` says why). ``_limit``
    carries the :class:`~tmtcontrol.stability.limit.ScenarioLimit` (or the
    ``AnalysisError`` it raised) to the run's verdicts (not a column)."""
    from ..stability.continuous import AnalysisError
    from ..stability.first_contact import LoopRunner
    from ..stability.limit import deciding_limit
    from ..stability.onedim import stiffness_seen

    nan = math.nan
    out = {"small_signal_limit": nan, "periodic_limit": nan, "first_contact_limit": nan, "predicted_limit": nan,
           "predicted_limit_from": "", "predicted_stable": None, "limits_error": "", "_limit": None}
    try:
        k_e = stiffness_seen(sc)        # not scenario_parameters: its path masses are the family's (12 ms a case)
        key = _family_key(sc, k_e.min())
        if key not in _LIMITS:
            if len(_LIMITS) >= 4096:
                _LIMITS.clear()
            _LIMITS[key] = deciding_limit(sc, runner=LoopRunner(sc, sim=sim))
        lim = _LIMITS[key]
        k_max = float(k_e.max())
    except Exception as exc:          # an analysis that does not apply to this case: said in the row
        out["limits_error"] = str(exc).splitlines()[0] if str(exc) else exc.__class__.__name__
        if isinstance(exc, AnalysisError):
            out["_limit"] = exc       # the verdicts fall back to the 1-D figure and say why, as simulate's
        return out
    if lim is None:
        out["limits_error"] = "the law has no linear verdict"
        return out
    val = lambda v: nan if v is None else float(v)
    out.update({"small_signal_limit": val(lim.small_signal), "periodic_limit": val(lim.periodic),
                "first_contact_limit": val(lim.first_contact), "predicted_limit": float(lim.limit),
                "predicted_limit_from": lim.limit_from, "predicted_stable": bool(k_max < lim.limit),
                "_limit": lim})
    return out


def run_chunk(base: dict, cases: list[Case], max_steps: int | None = None, limits: bool = True) -> list[dict]:
    """The rows of a chunk of cases (runs in a worker, with one BLAS thread)."""
    with blas_threads_limited():
        return [case_row(base, c, max_steps, limits) for c in cases]


class SchedulerUnavailable(ValueError):
    """``--dask ADDRESS`` names no running scheduler (exit code 2 in the CLI)."""


def check_dask(dask: str | None, timeout: float = CONNECT_TIMEOUT) -> None:
    """Raise :class:`SchedulerUnavailable` (one line naming the address) unless
    ``dask`` is None, ``"local"``, a non-TCP address, or a host and port that
    accept a TCP connection within ``timeout`` seconds. Called before the
    sweep creates anything, so a wrong address leaves nothing behind."""
    import socket
    import urllib.parse

    if dask is None or dask == "local":
        return
    parts = urllib.parse.urlsplit(dask if "://" in dask else "tcp://" + dask)
    if parts.scheme not in ("tcp", "tls"):
        return                           # inproc://, ucx://, ...: the client says
    try:
        host, port = parts.hostname, parts.port or 8786
    except ValueError:
        raise SchedulerUnavailable(f"--dask {dask}: not a host:port address") from None
    if not host:
        raise SchedulerUnavailable(f"--dask {dask}: no host in the address")
    try:
        with socket.create_connection((host, port), timeout=timeout):
            pass
    except ConnectionRefusedError:
        raise SchedulerUnavailable(f"--dask {dask}: no scheduler answered (connection refused)") from None
    except socket.gaierror as exc:
        raise SchedulerUnavailable(f"--dask {dask}: unknown host {host} ({exc.strerror})") from None
    except TimeoutError:
        raise SchedulerUnavailable(f"--dask {dask}: no scheduler answered within {timeout:g} s") from None
    except OSError as exc:
        raise SchedulerUnavailable(f"--dask {dask}: no scheduler answered "
                                   f"({exc.strerror or exc.__class__.__name__})") from None


def identify_scheduler(dask: str, seconds: float = float(CLIENT_TIMEOUT.rstrip("s"))) -> None:
    """Ask ``dask`` (an address whose port answered, :func:`check_dask`) who it
    is, over Dask's own protocol, within ``seconds``; raise
    :class:`SchedulerUnavailable` unless a Dask scheduler replies (review 59: a
    port that accepted the connection and never spoke held ``Client(...,
    timeout=...)`` past its timeout, for as long as the port stayed open)."""
    import asyncio

    from distributed.comm import connect

    async def identity():
        comm = await connect(dask, timeout=seconds)
        try:
            await comm.write({"op": "identity", "reply": True})
            return await comm.read()
        finally:
            await comm.close()

    try:
        reply = asyncio.run(asyncio.wait_for(identity(), seconds))
    except (OSError, TimeoutError, asyncio.TimeoutError) as exc:
        raise SchedulerUnavailable(f"--dask {dask}: no Dask scheduler answered within {seconds:g} s"
                                   + (f" ({str(exc).splitlines()[0]})" if str(exc) else "")) from None
    except Exception as exc:        # noqa: BLE001 - whatever the port sent, it was not a scheduler's reply
        raise SchedulerUnavailable(f"--dask {dask}: not a Dask scheduler ({exc.__class__.__name__})") from None
    kind = reply.get("type") if isinstance(reply, dict) else None
    if kind != "Scheduler":
        raise SchedulerUnavailable(f"--dask {dask}: not a Dask scheduler (it answered as {kind or 'something else'}"
                                   + ("; give the scheduler's address" if kind == "Worker" else "") + ")")


class PartialFolder:
    """``OUT.partial/``: the finished chunks of a sweep, marked with the sweep's
    fingerprint. Created by a fresh run, reused by ``--resume``, removed once
    the results are committed; never touched if it is not a sweep's."""

    MARK = "sweep.json"

    @staticmethod
    def path_for(out) -> pathlib.Path:
        """``OUT.partial`` beside the output folder ``out``."""
        out = pathlib.Path(out).expanduser().resolve()
        return out.parent / (out.name + ".partial")

    def __init__(self, out: pathlib.Path, sweep: Sweep, resume: bool, options: dict | None = None):
        self.path = self.path_for(out)
        self.fresh = False                   # True if this run created it
        # what else shapes a row: a resumed sweep must run its cases as the interrupted one did
        self.options = _spelled_out(options or {})
        # an axis whose values include a list that is not one number: every cell of it is JSON text (a column
        # mixing numbers and text cannot be written; review 10)
        self.text_axes = {a: all(isinstance(v, list) for v in vals) for a, vals in sweep.grid.items()
                          if any(isinstance(v, (list, dict)) and not (isinstance(v, list) and len(v) == 1
                                                                      and isinstance(v[0], (int, float)))
                                 for v in vals)}
        mark = self.path / self.MARK
        if self.path.exists():
            try:
                stored = json.loads(mark.read_text())
                fp = stored["fingerprint"]
            except (OSError, ValueError, KeyError, TypeError):
                raise OutputError(f"--out: {self.path} exists and is not a tmtcontrol sweep's; "
                                  "move it or choose another --out") from None
            if not resume:
                raise OutputError(f"--out: an interrupted sweep is in {self.path}; --resume continues it "
                                  "(or remove that folder)")
            if fp != sweep.fingerprint:
                raise OutputError(f"--resume: {self.path} holds a different sweep (other base scenario or cases)")
            before = _spelled_out(stored.get("options", {}))
            # (a mark without options, an older tmtcontrol's, is not checked for them)
            changed = [k for k in sorted(before) if before.get(k) != self.options.get(k)]
            if changed:
                raise OutputError("--resume: " + ", ".join(f"--{k.replace('_', '-')} was {_said(before.get(k))}"
                                                           f", now {_said(self.options.get(k))}" for k in changed)
                                  + f" ({self.path}); resume with the same, or the rows would mix")
        else:
            try:
                self.path.mkdir(parents=False)
                self.fresh = True
                mark.write_text(json.dumps({"fingerprint": sweep.fingerprint, "cases": len(sweep.cases),
                                            "options": self.options}) + "\n")
            except OSError as exc:
                raise OutputError(f"--out: cannot create {self.path} ({exc.strerror})") from None

    def parts(self) -> list[pathlib.Path]:
        """The finished chunks' files."""
        return sorted(self.path.glob("part-*.parquet"))

    def done(self) -> set[int]:
        import pyarrow.parquet as pq

        out = set()
        for part in sorted(self.path.glob("part-*.parquet")):
            try:
                out.update(pq.read_table(part, columns=["case"]).column("case").to_pylist())
            except Exception:      # a part cut short by a crash: its cases run again
                part.unlink()
        return out

    def write(self, rows: list[dict]) -> None:
        import pyarrow as pa
        import pyarrow.parquet as pq

        first = min(r["case"] for r in rows)
        tmp = self.path / f".part-{first:07d}.tmp"
        for r in rows:
            for axis, listed in self.text_axes.items():
                v = r.get(axis)
                if axis in r and not isinstance(v, str):      # a one-number list, stored as its number by case_row
                    r[axis] = json.dumps([v] if listed else v)
        pq.write_table(pa.Table.from_pylist(_uniform(rows)), tmp)
        os.replace(tmp, self.path / f"part-{first:07d}.parquet")

    def table(self):
        import pyarrow as pa
        import pyarrow.parquet as pq

        tables = [pq.read_table(p) for p in sorted(self.path.glob("part-*.parquet"))]
        t = pa.concat_tables(tables, promote_options="permissive")
        return t.sort_by("case")

    def remove(self) -> None:
        """Remove what the sweep wrote here (its mark and its chunks), and the
        folder if that empties it; a file someone else put there stays, with
        the folder (review 10: the folder was removed whole)."""
        for f in [self.path / self.MARK, *self.path.glob("part-*.parquet"), *self.path.glob(".part-*.tmp")]:
            f.unlink(missing_ok=True)
        try:
            self.path.rmdir()
        except FileNotFoundError:
            pass
        except OSError:
            print(f"sweep: kept {self.path}: it holds files tmtcontrol did not write", file=sys.stderr)


def kept_note(out) -> str | None:
    """After an interruption: what ``OUT.partial/`` keeps and how to go on
    (one sentence), or None if there is no such folder of a sweep's."""
    path = PartialFolder.path_for(out)
    if not (path / PartialFolder.MARK).is_file():
        return None
    n = 0
    try:
        import pyarrow.parquet as pq

        for part in path.glob("part-*.parquet"):
            n += pq.read_metadata(part).num_rows
    except Exception:         # a part cut short: --resume reruns its cases
        pass
    return (f"{n} finished case{'s' if n != 1 else ''} kept in {path}/; "
            "run the same command with --resume to continue")


def _spelled_out(options: dict) -> dict:
    """``options`` with a default given as None spelled out: ``--max-steps
    1000000`` is the run without it (review 59: --resume refused it as "was
    not given, now 1000000")."""
    from ..simulation.simulator import MAX_STEPS

    return {k: (MAX_STEPS if k == "max_steps" and v is None else v) for k, v in dict(options).items()}


def _said(value) -> str:
    return "not given" if value is None else "on" if value is True else "off" if value is False else str(value)


def _uniform(rows: list[dict]) -> list[dict]:
    keys: dict[str, None] = {}
    for r in rows:
        keys.update(dict.fromkeys(r))
    return [{k: r.get(k) for k in keys} for r in rows]


class Progress:
    """Progress on stderr: a tqdm bar (rate, ETA) on a terminal; otherwise one
    line every ``every`` seconds and at the end: the rate since the start and
    the time left at the rate since the previous line (the first cases carry
    their families' limit analyses: review 31, an ETA of 136 s for a sweep
    that took 21 s in all)."""

    def __init__(self, total: int, done: int = 0, every: float = 10.0, stream=None):
        self.stream = stream or sys.stderr
        self.total, self.n, self.every = total, done, every
        self.t0 = self.last = time.perf_counter()
        self.start = self.n_last = done
        self.bar = None
        if getattr(self.stream, "isatty", lambda: False)():
            from tqdm import tqdm

            self.bar = tqdm(total=total, initial=done, unit="case", file=self.stream, dynamic_ncols=True)

    def update(self, k: int) -> None:
        self.n += k
        if self.bar is not None:
            self.bar.update(k)
            return
        now = time.perf_counter()
        if now - self.last >= self.every or self.n == self.total:
            rate = (self.n - self.start) / max(now - self.t0, 1e-9)
            recent = ((self.n - self.n_last) / max(now - self.last, 1e-9) if self.last > self.t0 and
                      self.n > self.n_last else rate)
            self.last, self.n_last = now, self.n
            eta = (self.total - self.n) / recent if recent > 0 else math.inf
            print(f"sweep: {self.n}/{self.total} cases ({100 * self.n / max(self.total, 1):.0f} %), "
                  f"{rate:.1f} cases/s, ETA {eta:.0f} s", file=self.stream, flush=True)

    def say(self, line: str) -> None:
        """One line on the stream (above the bar on a terminal)."""
        if self.bar is not None:
            self.bar.write(line, file=self.stream)
        else:
            print(line, file=self.stream, flush=True)

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()


def _chunks(cases: list[Case], workers: int) -> list[list[Case]]:
    size = max(1, min(25, math.ceil(len(cases) / max(1, 4 * workers))))
    return [cases[i:i + size] for i in range(0, len(cases), size)]


def run_cases(sweep: Sweep, todo: list[Case], write: Callable[[list[dict]], None], workers: int = 1,
              dask: str | None = None, max_steps: int | None = None, progress: Progress | None = None,
              limits: bool | None = None) -> None:
    """Run ``todo`` and hand every finished chunk's rows to ``write``, in
    completion order: in this process (``workers == 1``, no Dask), on
    ``workers`` local processes, or on Dask (``dask="local"``: a LocalCluster
    of ``workers`` processes; else a scheduler address). ``limits``: each
    case's predicted limits (:func:`case_limits`); None: :func:`limits_by_default`."""
    if limits is None:
        limits = limits_by_default(sweep)[0]
    chunks = _chunks(todo, workers)
    tick = progress.update if progress is not None else (lambda k: None)
    say = progress.say if progress is not None else (lambda line: None)
    if dask is None and workers == 1:
        with blas_threads_limited():
            for chunk in chunks:
                rows = run_chunk(sweep.base, chunk, max_steps, limits)
                check_interrupt()
                write(rows)
                tick(len(rows))
        return
    if dask is None:
        import concurrent.futures as cf

        # the platform's default start method (fork on Linux): a user's script or notebook needs no
        # `if __name__ == "__main__"` guard; each worker dies with this process and pins BLAS to one thread
        # a fork pool starts all its workers at the first submit: never more than there are chunks
        with cf.ProcessPoolExecutor(max_workers=min(workers, len(chunks)), initializer=worker_init) as pool:
            try:
                with signals_held():        # the workers fork at the first submit
                    futures = [pool.submit(run_chunk, sweep.base, c, max_steps, limits) for c in chunks]
                say(f"sweep: {len(todo)} cases running on {workers} worker processes")
                for fut in cf.as_completed(futures):
                    rows = fut.result()
                    write(rows)
                    tick(len(rows))
            except BaseException:
                # the cases still running are abandoned, not awaited: a compiled simulation sees no
                # signal until it returns, and every finished chunk is already written. No
                # future is cancelled first: the pool then fails them all as broken (Python 3.11's pool
                # raises InvalidStateError in its own thread for a cancelled one)
                _stop_workers(pool)
                raise
        return
    from dask.distributed import Client, LocalCluster, as_completed

    check_dask(dask)
    if dask == "local":
        cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=None,
                               silence_logs=40, preload=[__name__])      # dask_setup below, in each worker
        client = Client(cluster)
    else:
        cluster = None
        identify_scheduler(dask)
        try:
            client = Client(dask, timeout=CLIENT_TIMEOUT)
        except (OSError, TimeoutError) as exc:
            raise SchedulerUnavailable(f"--dask {dask}: no Dask scheduler answered within {CLIENT_TIMEOUT} "
                                       f"({str(exc).splitlines()[0] if str(exc) else exc.__class__.__name__})"
                                       ) from None
    interrupted = False
    try:
        futures = client.map(run_chunk, [sweep.base] * len(chunks), chunks, [max_steps] * len(chunks),
                             [limits] * len(chunks), pure=False)
        say(f"sweep: {len(todo)} cases running on Dask ({dask})")
        for fut in as_completed(futures):
            rows = fut.result()
            write(rows)
            tick(len(rows))
    except KeyboardInterrupt:
        interrupted = True
        raise
    finally:
        with _quiet_dask() if interrupted else contextlib.nullcontext():
            client.close()
            if cluster is not None:
                cluster.close()


def _stop_workers(pool) -> None:
    """Kill a process pool's workers (``kill_workers`` from Python 3.14, the
    pool's process table before)."""
    kill = getattr(pool, "kill_workers", None)
    if kill is not None:
        kill()
        return
    for proc in list((getattr(pool, "_processes", None) or {}).values()):
        try:
            proc.kill()
        except (OSError, ValueError):          # already gone
            pass


def dask_setup(worker) -> None:
    """Preload of a LocalCluster's worker processes (Dask calls it as each
    starts): Ctrl-C is the parent's to handle, since the terminal sends SIGINT
    to every process of the command, and a worker that took it would print
    its own traceback; the parent stops the cluster. One BLAS thread for the
    worker's lifetime."""
    import signal
    import threading

    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGINT, signal.SIG_IGN)
    one_blas_thread()


@contextlib.contextmanager
def _quiet_dask():
    """Silence distributed's (and its event loop's) loggers while a cluster is
    shut down after Ctrl-C: the workers' "task cancelled", "stream closed"
    and nanny messages are the expected consequence of the interruption, which
    the command reports in one line."""
    import logging

    roots = ("distributed", "tornado", "asyncio", "bokeh")
    names = [n for n in list(logging.root.manager.loggerDict)
             if n in roots or n.startswith(tuple(r + "." for r in roots))]
    loggers = [logging.getLogger(n) for n in {*roots, *names}]
    saved = [(lg, lg.disabled) for lg in loggers]
    for lg in loggers:
        lg.disabled = True          # each one: a child's records reach its parents' handlers regardless
    try:
        yield
    finally:
        for lg, disabled in saved:
            lg.disabled = disabled
