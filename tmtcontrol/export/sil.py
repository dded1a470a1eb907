"""Software in the loop: the exported C controller against the simulated plant.

:func:`compile_export` builds an exported folder (``tmt_controller.c``) into a
shared library with the system C compiler, in a private temporary folder (the
exported folder is only read); :class:`CompiledController` calls its
``tmt_step`` through ctypes, with ctypes mirrors of the structs written from
the same field tables as the C header (their sizes are checked against the
library's ``tmt_sizeof_*``).

:func:`simulate_with_controller` runs a scenario with the C controller in
place of the built-in one: each period the plant of eq. (1) with the contact
(:func:`~tmtcontrol.simulation.closedloop.build_plant`, the simulator's
integrator) is advanced in Python with the torque the C code returned, and
the force sensor is the simulator's (true contact force plus noise, mapped to
the base frame). The result is a :class:`~tmtcontrol.SimulationResult`, equal
to the built-in run to rounding (the tests: 1e-9 relative).

:func:`measurement_table` turns a simulation into the measurements a robot
would have logged (the input of ``replay``), :func:`read_commands` reads
``replay``'s output.
"""

from __future__ import annotations

import ctypes
import json
import os
import pathlib
import shutil
import subprocess
import tempfile

import casadi as ca
import numpy as np

from ..simulation.closedloop import INPUT, LOG, MEASUREMENT, build_plant, controller_param_layout, param_layout
from ..simulation.environment import contact_force, task_frame
from ..simulation.rollout import compiler
from ..simulation.taskframe import (_kinematics, build_pose_plant, pose_controller_param_layout, pose_log_layout,
                                    pose_param_layout)
from .generate import (METADATA, ExportError, command_fields, diagnostic_fields, measurement_fields,
                       param_fields)

__all__ = ["CompiledController", "compile_export", "check_export_matches", "simulate_with_controller",
           "measurement_table", "write_measurements", "read_commands", "SIL_FLAGS"]

SIL_FLAGS = ["-std=c99", "-O2", "-ffp-contract=off", "-fPIC", "-shared"]
"""-ffp-contract=off: no fused multiply-adds, as in the simulator's compiled
step, so the C controller rounds as the simulation does."""


def _struct(name, fields):
    return type(name, (ctypes.Structure,), {"_fields_": [
        (f.name, ctypes.c_double * f.size if f.size > 1 else ctypes.c_double) for f in fields]})


def compile_export(folder: str | os.PathLike, flag: str = "--controller") -> pathlib.Path:
    """Compile ``folder``'s ``tmt_controller.c`` into a shared library in a
    private temporary folder; return its path. Raises :class:`ExportError`
    (naming ``flag``) for a folder that is not an export or when there is no
    C compiler."""
    folder = pathlib.Path(folder)
    _read_metadata(folder, flag)
    cc = compiler()
    if cc is None:
        raise ExportError(f"{flag}: no C compiler found; install one (apt-get install gcc) or set CC")
    build = pathlib.Path(tempfile.mkdtemp(prefix="tmtcontrol-sil-"))
    lib = build / "libtmt_controller.so"
    result = subprocess.run([cc, *SIL_FLAGS, "-I", str(folder), str(folder / "tmt_controller.c"), "-o", str(lib),
                             "-lm"], capture_output=True, text=True, timeout=600)
    if result.returncode != 0:
        shutil.rmtree(build, ignore_errors=True)
        first = (result.stderr.strip().splitlines() or ["no message"])[0]
        raise ExportError(f"{flag}: compiling {folder / 'tmt_controller.c'} failed: {first}")
    return lib


def _read_metadata(folder: pathlib.Path, flag: str) -> dict:
    try:
        meta = json.loads((folder / METADATA).read_text(encoding="utf-8"))
        if meta.get("written_by") != "tmtcontrol export" or not (folder / "tmt_controller.c").is_file():
            raise ValueError
    except (OSError, ValueError, AttributeError):
        raise ExportError(f"{flag}: {folder} is not a folder written by `tmtcontrol export` "
                          f"(no tmt_controller.c and {METADATA})") from None
    return meta


class CompiledController:
    """The exported controller of ``folder``, compiled and loaded.

    Parameters
    ----------
    folder : path
        A folder written by ``tmtcontrol export``.
    library : path, optional
        An already compiled library (default: :func:`compile_export`).

    Attributes
    ----------
    meta : dict
        The export's metadata (law, delay, inner loop, model settings).
    """

    def __init__(self, folder: str | os.PathLike, library: str | os.PathLike | None = None,
                 flag: str = "--controller", scenario=None):
        from ..control.laws import get_law

        self.folder = pathlib.Path(folder)
        self.flag = flag
        self.meta = _read_metadata(self.folder, flag)
        self.law = get_law(self.meta["law"])
        self.torque = bool(self.meta["inner_loop"])
        self.robot = self.meta.get("robot")        # None: the PUMA's position-only task
        self.n = self.robot["joints"] if self.robot else 3
        if scenario is not None:            # refused before compiling
            self.check_matches(scenario)
        self.library = pathlib.Path(library) if library is not None else compile_export(self.folder, flag)
        self.cmd_fields = command_fields(self.torque, self.n)
        self.diag_fields = diagnostic_fields(self.n)
        self.Params = _struct("tmt_params", param_fields(self.law, self.n))
        self.Measurement = _struct("tmt_measurement", measurement_fields(self.n))
        self.Command = _struct("tmt_command", (*self.cmd_fields, *self.diag_fields))
        sz = self.meta["sizes"]
        alloc = lambda n: max(int(n), 1)
        n_out = sum(f.size for f in (*self.cmd_fields, *self.diag_fields))
        n_y = sum(f.size for f in measurement_fields(self.n))
        self.State = type("tmt_state", (ctypes.Structure,), {"_fields_": [
            ("s", ctypes.c_double * alloc(sz["state"])), ("s_next", ctypes.c_double * alloc(sz["state"])),
            ("y", ctypes.c_double * n_y), ("p", ctypes.c_double * sz["param"]),
            ("out", ctypes.c_double * n_out), ("arg", ctypes.c_void_p * alloc(sz["arg"])),
            ("res", ctypes.c_void_p * alloc(sz["res"])), ("iw", ctypes.c_longlong * alloc(sz["iw"])),
            ("w", ctypes.c_double * alloc(sz["w"]))]})
        dll = ctypes.CDLL(str(self.library))
        for name, cls in (("params", self.Params), ("state", self.State), ("measurement", self.Measurement),
                          ("command", self.Command)):
            fn = getattr(dll, f"tmt_sizeof_{name}")
            fn.restype = ctypes.c_size_t
            if fn() != ctypes.sizeof(cls):
                raise ExportError(f"{flag}: {self.folder}: tmt_{name} has {fn()} bytes in the library, "
                                  f"{ctypes.sizeof(cls)} in {METADATA}; export it again")
        self._step = dll.tmt_step
        self._step.argtypes = [ctypes.c_void_p] * 4
        self._step.restype = ctypes.c_int
        self._init = dll.tmt_init
        self._init.argtypes = [ctypes.c_void_p] * 2
        self._default = dll.tmt_default_params
        self._default.argtypes = [ctypes.c_void_p]
        self._dll = dll

    # -- the C API, one call each ----------------------------------------------------------------
    def default_params(self):
        p = self.Params()
        self._default(ctypes.byref(p))
        return p

    def new_state(self, params=None):
        s = self.State()
        self._init(ctypes.byref(params if params is not None else self.default_params()), ctypes.byref(s))
        return s

    def step(self, params, state, meas, cmd) -> int:
        return self._step(ctypes.byref(params), ctypes.byref(state), ctypes.byref(meas), ctypes.byref(cmd))

    # -- from a scenario ----------------------------------------------------------------------------
    def check_matches(self, scenario) -> None:
        """Raise :class:`ExportError` unless ``scenario`` has the structure
        this controller was exported with (:func:`check_export_matches`)."""
        check_export_matches(self.meta, self.folder, scenario, self.flag)

    def params_from(self, P_full: np.ndarray):
        """The C parameter struct from the simulator's parameter vector."""
        if self.robot:
            vec = pose_controller_param_layout(self.n, self.law).pack(
                **pose_param_layout(self.n, self.law).split(P_full))
            return self.Params.from_buffer_copy(np.ascontiguousarray(vec).tobytes())
        vec = controller_param_layout(self.law).pack(**param_layout(self.law).split(P_full))
        return self.Params.from_buffer_copy(np.ascontiguousarray(vec).tobytes())


def check_export_matches(meta: dict, folder, scenario, flag: str = "--controller") -> None:
    """Raise :class:`ExportError` (one line naming ``flag``) unless
    ``scenario`` has the structure the export in ``folder`` (its metadata
    ``meta``) was made for: the arm (for a 6-D arm its controller model's
    identity, the URDF's content and chain, not the path it was read from),
    law, delay, controller model, and the inner loop (the simulated robot is
    torque-driven)."""
    robot = meta.get("robot")
    r = scenario.robot
    what = (f"robot.model = {robot['model']!r} (tip {robot['tip']!r}, armature "
            f"{robot['armature']!r})" if robot else "robot.model = 'puma560'")

    def other_arm():
        return ExportError(f"{flag}: {folder} was exported for {what}, the scenario has "
                           f"robot.model = {r.model!r} (tip {r.tip!r}, armature {r.armature!r})"
                           + (" or another version of it" if robot and r.model.lower() != "puma560" else "")
                           + "; export this scenario (tmtcontrol export)")

    if bool(robot) != (r.model.lower() != "puma560"):
        raise other_arm()
    want = {"law": scenario.controller.law.kind, "delay": scenario.controller.delay_samples,
            "model_mass_scale": scenario.robot.model_mass_scale,
            "compensate_friction": scenario.robot.compensate_friction}
    for key, value in want.items():
        if meta[key] != value:
            raise ExportError(f"{flag}: {folder} was exported with {key} = {meta[key]!r}, "
                              f"the scenario has {value!r}; export this scenario (tmtcontrol export)")
    if robot:          # the same arm: URDF content, chain and model options (the robot's key)
        from ..simulation.posesim import robot_of

        if robot_of(scenario, controller=True).key != robot["key"]:
            raise other_arm()
    if not meta["inner_loop"]:
        raise ExportError(f"{flag}: {folder} was exported without --inner-loop, so it gives no "
                          "joint torques for the simulated (torque-driven) robot; export with --inner-loop")


def simulate_with_controller(scenario, controller: CompiledController, max_steps: int | None = None):
    """Run ``scenario`` with the C ``controller`` in place of the built-in one
    (software in the loop); returns a :class:`~tmtcontrol.SimulationResult`
    with ``info["code"] == "exported C (SIL)"``."""
    import time

    from ..files import check_interrupt
    from ..simulation.simulator import Simulator, check_path, check_run_size

    check_run_size(scenario, max_steps)
    controller.check_matches(scenario)
    if controller.robot:
        return _simulate_pose(scenario, controller)
    sim = Simulator(scenario, compile=False)          # its inputs and result packing; its step is never built
    t0 = time.perf_counter()
    sc = scenario.simulation
    plant = build_plant(sim.plant, sc.integrator, sc.substeps, sc.tol, sc.contact_refine)
    sensor = _sensor(sim.plant)
    path = check_path(sim.plant, scenario)
    U, P, s0, t = sim._inputs(scenario, path)
    PP = param_layout(controller.law).split(P)
    R, c, Ts, d_e = PP["R"], PP["c"], PP["Ts"], PP["d_e"]
    build_time = time.perf_counter() - t0
    params = controller.params_from(P)
    state = controller.new_state(params)
    n_s = controller.meta["sizes"]["state"]
    ctypes.memmove(state.s, np.ascontiguousarray(s0[6:6 + n_s]).ctypes.data, 8 * n_s)
    meas, cmd = controller.Measurement(), controller.Command()
    y = np.frombuffer(meas, dtype=float)
    out = np.frombuffer(cmd, dtype=float)
    n_c = sum(f.size for f in controller.cmd_fields)
    N = U.shape[1]
    L = np.empty((LOG.size, N))
    Uin = INPUT.split(U)
    z = s0[:6].copy()
    normal = R.reshape(3, 3, order="F")[:, 0]
    pz = np.concatenate([np.zeros(3), [0.0], d_e, R, c, Ts])
    t0 = time.perf_counter()
    for k in range(N):
        k_e = Uin["k_e"][0, k]
        f_true = float(sensor(z, k_e, d_e, R, c))
        y[0:6] = z
        y[6:9] = -normal * (f_true + Uin["noise"][0, k])
        y[9:11], y[11:13], y[13:15] = Uin["pos_t"][:, k], Uin["vel_t"][:, k], Uin["acc_t"][:, k]
        if controller.step(params, state, meas, cmd) != 0:
            raise RuntimeError(f"tmt_step failed at t = {t[k]:.4f} s")
        tau = out[n_c - 3:n_c]
        d = out[n_c:]
        L[:, k] = np.concatenate([z, tau, d[9:12], d[0:3], d[6:9], out[0:3], [f_true], d[12:16]])
        pz[0:3], pz[3] = tau, k_e
        z = np.asarray(plant(z, pz)).ravel()
        if k % 1000 == 0:
            check_interrupt()
    run_time = time.perf_counter() - t0
    S = np.hstack([L[0:6, 1:], z[:, None]])          # the joints after each period, as the built-in run's
    sim._check_finite(S, L, t)
    return sim._result(scenario, t, L, U, path, {"integrator": sc.integrator, "code": "exported C (SIL)",
                                                 "controller": str(controller.folder),
                                                 "build_time_s": build_time, "run_time_s": run_time,
                                                 "steps": t.size})


def _simulate_pose(scenario, controller: CompiledController):
    """:func:`simulate_with_controller` for a 6-D arm: the plant of
    :func:`~tmtcontrol.simulation.taskframe.build_pose_plant` (the 6-D
    simulator's integrator), the 6-D simulator's inputs and result packing."""
    import time

    from ..files import check_interrupt
    from ..simulation.posesim import PoseSimulator, pose_path
    from ..simulation.simulator import Simulator

    t0 = time.perf_counter()
    sim = PoseSimulator(scenario, compile=False)      # its inputs and result packing; its step is never run
    sc = scenario.simulation
    n = sim.plant.n
    plant = build_pose_plant(sim.plant, sc.integrator, sc.substeps, sc.tol, sc.contact_refine)
    sensor = _sensor(sim.plant)
    path = pose_path(sim.plant, scenario)
    U, P, s0, t = sim._inputs(scenario, path)
    PP = pose_param_layout(n, controller.law).split(P)
    R, c, Ts, d_e = PP["R"], PP["c"], PP["Ts"], PP["d_e"]
    build_time = time.perf_counter() - t0
    params = controller.params_from(P)
    state = controller.new_state(params)
    n_s = controller.meta["sizes"]["state"]
    ctypes.memmove(state.s, np.ascontiguousarray(s0[2 * n:2 * n + n_s]).ctypes.data, 8 * n_s)
    meas, cmd = controller.Measurement(), controller.Command()
    y = np.frombuffer(meas, dtype=float)
    out = np.frombuffer(cmd, dtype=float)
    n_c = sum(f.size for f in controller.cmd_fields)
    N = U.shape[1]
    L = np.empty((pose_log_layout(n).size, N))
    Uin = INPUT.split(U)
    z = s0[:2 * n].copy()
    normal = R.reshape(3, 3, order="F")[:, 0]
    pz = np.concatenate([np.zeros(n), [0.0], d_e, R, c, Ts])
    m = 2 * n                                          # the force's place in the measurement
    t0 = time.perf_counter()
    for k in range(N):
        k_e = Uin["k_e"][0, k]
        f_true = float(sensor(z, k_e, d_e, R, c))
        y[0:m] = z
        y[m:m + 3] = -normal * (f_true + Uin["noise"][0, k])
        y[m + 3:m + 5], y[m + 5:m + 7], y[m + 7:m + 9] = Uin["pos_t"][:, k], Uin["vel_t"][:, k], Uin["acc_t"][:, k]
        if controller.step(params, state, meas, cmd) != 0:
            raise RuntimeError(f"tmt_step failed at t = {t[k]:.4f} s")
        tau = out[n_c - n:n_c]
        d = out[n_c:]
        L[:, k] = np.concatenate([z, tau, d[9:12], d[0:3], d[6:9], out[0:3], [f_true], d[12:16], d[16:19]])
        pz[0:n], pz[n] = tau, k_e
        z = np.asarray(plant(z, pz)).ravel()
        if k % 1000 == 0:
            check_interrupt()
    run_time = time.perf_counter() - t0
    S = np.hstack([L[0:2 * n, 1:], z[:, None]])      # the joints after each period, as the built-in run's
    Simulator._check_finite(S, L, t, n)
    return sim._result(scenario, t, L, U, path, {"integrator": sc.integrator, "code": "exported C (SIL)",
                                                 "controller": str(controller.folder), "build_time_s": build_time,
                                                 "run_time_s": run_time, "steps": t.size, "robot": sim.plant.name})


def _sensor(robot) -> ca.Function:
    """The simulated force sensor: the true normal contact force (N) at the
    joints ``z``, as the simulator's step computes it (eq. 1's environment)."""
    n = getattr(robot, "n", 3)
    z, k_e, d_e = ca.SX.sym("z", 2 * n), ca.SX.sym("k_e"), ca.SX.sym("d_e")
    Rv, c = ca.SX.sym("R", 9), ca.SX.sym("c", 3)
    R = ca.reshape(Rv, 3, 3)
    q, dq = z[0:n], z[n:]
    if n >= 6:                                          # a URDF arm: its tool point, as the 6-D step
        _, _, _, X, dX = _kinematics(robot, q, dq, R, c)
    else:
        X = ca.mtimes(R.T, robot.fk(q) - c)
        dX = ca.mtimes(R.T, ca.mtimes(robot.jacobian(q), dq))
    return ca.Function("sensor", [z, k_e, d_e, Rv, c], [contact_force(X[0], dX[0], k_e, d_e)])


def measurement_table(result) -> tuple[np.ndarray, list[str]]:
    """What a robot running ``result``'s loop measured each period, as the
    rows ``replay`` reads: ``[t, q, dq, force (base frame), pos_t, vel_t,
    acc_t]`` and the column names. The force is the simulated sensor's
    (contact force plus the scenario's noise, seeded as in the run)."""
    from ..simulation.geometry import surface_frame
    from ..simulation.posesim import PoseSimulator
    from ..simulation.simulator import Simulator, check_path

    sc = result.scenario
    n = result.q.shape[0]
    if n >= 6:                  # a 6-D arm: its simulator's inputs (the step is built, never run)
        U, _, _, t = PoseSimulator(sc, compile=False).inputs(sc)
        normal = surface_frame(sc.environment)[:, 0]
    else:
        sim = Simulator(sc, compile=False)
        U, _, _, t = sim._inputs(sc, check_path(sim.plant, sc))
        normal = task_frame(sc.environment.tilt_deg)[:, 0]
    Uin = INPUT.split(U)
    force = -normal[:, None] * (result.contact_force + Uin["noise"][0])[None, :]
    rows = np.vstack([t, result.q, result.dq, force, Uin["pos_t"], Uin["vel_t"], Uin["acc_t"]]).T
    names = ["t"] + [c for f in measurement_fields(n) for c in f.columns]
    return rows, names


def write_measurements(result, path: str | os.PathLike) -> None:
    """:func:`measurement_table` as CSV (full precision)."""
    rows, names = measurement_table(result)
    np.savetxt(path, rows, delimiter=",", header=",".join(names), comments="", fmt="%.17g")


def read_commands(path: str | os.PathLike) -> dict[str, np.ndarray]:
    """``replay``'s output CSV as columns by name."""
    with open(path, encoding="utf-8") as fh:
        names = fh.readline().strip().split(",")
    data = np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)
    return {n: data[:, i] for i, n in enumerate(names)}
