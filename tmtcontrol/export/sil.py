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

import casadi as ca
import numpy as np

from ..cache import new_build_folder
from ..model.robot import task_of
from ..processes import run_compiler
from ..simulation.closedloop import (INPUT, believed, build_plant, controller_param_layout, controller_state_layout,
                                     param_layout, plant_inputs_layout)
from ..simulation.rollout import compiler
from ..surface import SHAPES, Plane, contact_force
from .generate import (DEFAULT_PREFIX, METADATA, PREFIX_PATTERN, ExportError, command_fields, diagnostic_fields,
                       measurement_fields, param_fields)
from .host import size_mismatch, state_struct

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
    source = _source(folder, _read_metadata(folder, flag))
    cc = compiler()
    if cc is None:
        raise ExportError(f"{flag}: no C compiler found; install one (apt-get install gcc) or set CC")
    build = new_build_folder("sil")
    lib = build / f"lib{source.stem}.so"
    result = run_compiler([cc, *SIL_FLAGS, "-I", str(folder), str(source), "-o", str(lib),
                           "-lm"], build / "tmp", check=False, text=True)
    if result.returncode != 0:
        shutil.rmtree(build, ignore_errors=True)
        first = (result.stderr.strip().splitlines() or ["no message"])[0]
        raise ExportError(f"{flag}: compiling {source} failed: {first}")
    return lib


def _source(folder: pathlib.Path, meta: dict) -> pathlib.Path:
    """The export's wrapper, ``<prefix>_controller.c``."""
    return folder / f"{meta.get('prefix', DEFAULT_PREFIX)}_controller.c"


def _metadata_schema():
    """The pydantic model of ``export.json`` (every field typed and bounded;
    unknown fields refused)."""
    from typing import Literal

    from pydantic import BaseModel, ConfigDict, Field, StrictBool, StrictFloat, StrictInt, StrictStr

    from ..control.laws import laws

    class _Strict(BaseModel):
        model_config = ConfigDict(extra="forbid", strict=True)

    class Sizes(_Strict):
        state: int = Field(ge=0)
        param: int = Field(ge=1)
        arg: int = Field(ge=0)
        res: int = Field(ge=0)
        iw: int = Field(ge=0)
        w: int = Field(ge=0)

    class Robot(_Strict):
        model: StrictStr
        tip: StrictStr | None
        joints: int = Field(ge=1, le=64)
        armature: StrictBool | StrictFloat | StrictInt | list[StrictFloat | StrictInt] | None
        key: StrictStr

    class Metadata(_Strict):
        written_by: Literal["tmtcontrol export"]
        version: StrictStr
        casadi: StrictStr
        scenario: StrictStr
        prefix: str = Field(DEFAULT_PREFIX, pattern=f"^({PREFIX_PATTERN})$")    # older exports: tmt
        law: Literal[tuple(laws())]                      # a registered law
        surface: Literal[tuple(SHAPES)] = Plane.kind     # an export older than curved surfaces: a plane
        surface_key: StrictStr | None = None              # a height map's heights are in the C code
        inner_loop: StrictBool
        delay: int = Field(ge=0, le=1000)
        delay_in_code: int | None = Field(None, ge=0, le=1000)     # 0 without the inner loop; older exports: none
        hold: Literal["zero_order", "mid_period"] = "zero_order"    # an export older than the mid-period hold
        model_mass_scale: StrictFloat | StrictInt
        compensate_friction: StrictBool
        sizes: Sizes
        instructions: int = Field(ge=0)
        robot: Robot

    return Metadata


def _read_metadata(folder: pathlib.Path, flag: str) -> dict:
    """``export.json`` of ``folder``, every field checked (:func:`_metadata_schema`):
    one line naming the field otherwise."""
    from pydantic import ValidationError

    try:
        meta = json.loads((folder / METADATA).read_text(encoding="utf-8"))
        if not isinstance(meta, dict) or meta.get("written_by") != "tmtcontrol export":
            raise ValueError
    except (OSError, ValueError, AttributeError):
        raise ExportError(f"{flag}: {folder} is not a folder written by `tmtcontrol export` "
                          f"(no {METADATA} written by it)") from None
    try:
        _metadata_schema().model_validate(meta)
    except ValidationError as exc:
        err = exc.errors()[0]
        where = ".".join(str(x) for x in err["loc"]) or "(top level)"
        if err["loc"] and err["loc"][0] == "robot" and err["type"] == "missing":
            raise ExportError(f"{flag}: {folder}/{METADATA} has no robot entry (an export of an earlier "
                              "version); export the scenario again (tmtcontrol export)") from None
        raise ExportError(f"{flag}: {folder}/{METADATA}: {where}: {err['msg']}; export the scenario again "
                          "(tmtcontrol export)") from None
    if not _source(folder, meta).is_file():
        raise ExportError(f"{flag}: {folder} is not a folder written by `tmtcontrol export` "
                          f"(no {_source(folder, meta).name} beside {METADATA})")
    return meta


class CompiledController:
    """The exported controller of ``folder``, compiled and loaded.

    Parameters
    ----------
    folder : path
        A folder written by ``tmtcontrol export``.
    library : path, optional
        An already compiled library (default: :func:`compile_export`).
    isolated : bool
        Load the library only in a child process (:mod:`.host`): its crash,
        exit or hang is reported in one line (:class:`ExportError`) instead
        of ending this process; the command line's ``--controller`` uses it.
        Then the in-process C API (:meth:`step`, :meth:`new_state`) is not
        available; :func:`simulate_with_controller` talks to the child.

    Attributes
    ----------
    meta : dict
        The export's metadata (law, delay, inner loop, model settings).
    """

    def __init__(self, folder: str | os.PathLike, library: str | os.PathLike | None = None,
                 flag: str = "--controller", scenario=None, isolated: bool = False):
        from ..control.laws import get_law

        self.folder = pathlib.Path(folder)
        self.flag = flag
        self.meta = _read_metadata(self.folder, flag)
        self.prefix = self.meta.get("prefix", DEFAULT_PREFIX)
        self.law = get_law(self.meta["law"])
        self.torque = bool(self.meta["inner_loop"])
        self.robot = self.meta["robot"]
        self.n = self.robot["joints"]
        self.task = task_of(self.n)
        self.surface = SHAPES[self.meta.get("surface", Plane.kind)]
        hold = self.meta.get("hold") == "mid_period"
        sizes = {"state": controller_state_layout(self.task, self.law, self.meta["delay"], self.torque, hold).size,
                 "param": controller_param_layout(self.task, self.law, self.surface).size}
        for key, size in sizes.items():     # the structs the C code was written with
            if self.meta["sizes"][key] != size:
                raise ExportError(f"{flag}: {self.folder}/{METADATA}: sizes.{key} is {self.meta['sizes'][key]}, "
                                  f"but law {self.law.name!r} on {self.n} joints has {size}; export the scenario "
                                  "again (tmtcontrol export)")
        if scenario is not None:            # refused before compiling
            self.check_matches(scenario)
        self.library = pathlib.Path(library) if library is not None else compile_export(self.folder, flag)
        self.cmd_fields = command_fields(self.torque, self.task, self.surface)
        self.diag_fields = diagnostic_fields(self.task)
        self.Params = _struct("tmt_params", param_fields(self.law, self.task, self.surface))
        self.Measurement = _struct("tmt_measurement", measurement_fields(self.task, self.surface))
        self.Command = _struct("tmt_command", (*self.cmd_fields, *self.diag_fields))
        sz = self.meta["sizes"]
        self.host_sizes = {"param": sz["param"], "state": sz["state"],
                           "meas": sum(f.size for f in measurement_fields(self.task, self.surface)),
                           "out": sum(f.size for f in (*self.cmd_fields, *self.diag_fields)),
                           "arg": sz["arg"], "res": sz["res"], "iw": sz["iw"], "w": sz["w"]}
        self.State = state_struct(self.host_sizes)
        self.isolated = isolated
        if isolated:                       # the user's code runs in the child only (.host)
            return
        dll = ctypes.CDLL(str(self.library))
        wrong = size_mismatch(dll, {"params": self.Params, "state": self.State, "measurement": self.Measurement,
                                    "command": self.Command}, self.prefix)
        if wrong:
            raise ExportError(f"{flag}: {self.folder}: {wrong}; export it again")
        self._step = getattr(dll, f"{self.prefix}_step")
        self._step.argtypes = [ctypes.c_void_p] * 4
        self._step.restype = ctypes.c_int
        self._init = getattr(dll, f"{self.prefix}_init")
        self._init.argtypes = [ctypes.c_void_p] * 2
        self._default = getattr(dll, f"{self.prefix}_default_params")
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
        vec = controller_param_layout(self.task, self.law, self.surface).pack(
            **believed(param_layout(self.task, self.law, self.surface).split(P_full)))
        return self.Params.from_buffer_copy(np.ascontiguousarray(vec).tobytes())


def check_export_matches(meta: dict, folder, scenario, flag: str = "--controller") -> None:
    """Raise :class:`ExportError` (one line naming ``flag``) unless
    ``scenario`` has the structure the export in ``folder`` (its metadata
    ``meta``) was made for: the arm (for a 6-D arm its controller model's
    identity, the URDF's content and chain, not the path it was read from),
    law, delay, controller model, and the inner loop (the simulated robot is
    torque-driven)."""
    from ..simulation.simulator import robot_of

    robot = meta["robot"]
    r = scenario.robot
    what = f"robot.model = {robot['model']!r} (tip {robot['tip']!r}, armature {robot['armature']!r})"
    def other_arm():
        return ExportError(f"{flag}: {folder} was exported for {what}, the scenario has "
                           f"robot.model = {r.model!r} (tip {r.tip!r}, armature {r.armature!r})"
                           + " or another version of it; export this scenario (tmtcontrol export)")

    from ..simulation.geometry import surface_of

    want = {"law": scenario.controller.law.kind, "surface": surface_of(scenario).kind,
            "delay": scenario.controller.delay_samples,
            "hold": scenario.controller.hold if meta.get("inner_loop") else "zero_order",   # a position command: none
            "model_mass_scale": scenario.robot.model_mass_scale,
            "compensate_friction": scenario.robot.compensate_friction}
    for key, value in want.items():
        have = meta.get(key, {"surface": Plane.kind, "hold": "zero_order"}.get(key))  # an older export
        if have != value:
            raise ExportError(f"{flag}: {folder} was exported with {key} = {have!r}, "
                              f"the scenario has {value!r}; export this scenario (tmtcontrol export)")
    key = surface_of(scenario).key
    if meta.get("surface_key", key) != key:             # a height map's heights are baked into the C code
        raise ExportError(f"{flag}: {folder} was exported for another {meta['surface']} (its heights are part of "
                          "the C code); export this scenario (tmtcontrol export)")
    if robot_of(scenario, controller=True).key != robot["key"]:      # URDF content, chain and model options
        raise other_arm()
    if not meta["inner_loop"]:
        raise ExportError(f"{flag}: {folder} was exported without --inner-loop, so it gives no "
                          "joint torques for the simulated (torque-driven) robot; export with --inner-loop")


def simulate_with_controller(scenario, controller: CompiledController, max_steps: int | None = None,
                             plant: str = "builtin"):
    """Run ``scenario`` with the C ``controller`` in place of the built-in one
    (software in the loop): each period the plant is advanced with the torque
    the C code returned: ``plant="builtin"``, the plant of
    :func:`~tmtcontrol.simulation.closedloop.build_plant` (the simulator's
    integrator); ``"mujoco"``, MuJoCo's dynamics of the same URDF
    (:class:`~tmtcontrol.simulation.mujoco_plant.MujocoPlant`: the exported C
    against a plant nobody here wrote; the built-in plant's own settings set
    back to their defaults, as :func:`~tmtcontrol.simulation.mujoco_plant.simulate_on_mujoco`
    runs them). The simulator's inputs and result packing. Returns a :class:`~tmtcontrol.SimulationResult` with
    ``info["code"] == "exported C (SIL)"``."""
    import time

    from ..simulation.cosim import run_split
    from ..simulation.simulator import Simulator, check_run_size

    if plant == "mujoco":     # the built-in plant's own settings, as simulate_on_mujoco runs them
        scenario = scenario.replace(simulation=scenario.simulation.on_mujoco())
    check_run_size(scenario, max_steps)
    controller.check_matches(scenario)
    t0 = time.perf_counter()
    sim = Simulator(scenario, compile=False)      # its inputs and result packing; its step is never built
    _, P, s0, _ = sim.inputs(scenario)
    extra = {}
    if plant == "mujoco":
        from ..simulation.mujoco_plant import mujoco_plant_for

        plant, extra = mujoco_plant_for(sim, scenario)
    elif plant == "builtin":
        plant = BuiltinPlant(sim, P)
    else:
        raise ValueError(f"plant: expected 'builtin' or 'mujoco', got {plant!r}")
    params = controller.params_from(P)
    n, n_s = sim.task.n, controller.meta["sizes"]["state"]
    s_start = np.ascontiguousarray(s0[2 * n:2 * n + n_s])
    sc = scenario.simulation
    info = {"integrator": sc.integrator, **extra, "code": "exported C (SIL)", "controller": str(controller.folder)}
    n_cmd = sum(f.size for f in controller.cmd_fields)
    flag, Ts = controller.flag, scenario.controller.Ts
    calls = [0]

    def failed(rc):
        raise ExportError(f"{flag}: {controller.prefix}_step returned {rc} at period {calls[0]} "
                          f"(t = {calls[0] * Ts:.3f} s)"
                          + (f" (a non-finite result: {controller.prefix.upper()}_E_NONFINITE)" if rc == -1 else
                             f" (a parameter outside its valid range: {controller.prefix.upper()}_E_RANGE)"
                             if rc == -2 else ""))

    if controller.isolated:
        from .host import ControllerHost, HostFault

        try:
            with ControllerHost(controller.library, controller.host_sizes, prefix=controller.prefix) as host:
                host.init(bytes(params))
                host.set_state(s_start.tobytes())
                info["build_time_s"] = time.perf_counter() - t0

                def control(y):
                    rc, out = host.step(np.ascontiguousarray(y, dtype=float).tobytes())
                    if rc != 0:
                        failed(rc)
                    calls[0] += 1
                    return np.frombuffer(out, dtype=float).copy()

                return run_split(sim, scenario, control, plant, info, n_cmd)
        except HostFault as exc:
            raise ExportError(f"{flag}: {controller.folder}: {exc} at period {calls[0]} "
                              f"(t = {calls[0] * Ts:.3f} s)") from None
    state = controller.new_state(params)
    ctypes.memmove(state.s, s_start.ctypes.data, 8 * n_s)
    meas, cmd = controller.Measurement(), controller.Command()
    y_c, out = np.frombuffer(meas, dtype=float), np.frombuffer(cmd, dtype=float)
    info["build_time_s"] = time.perf_counter() - t0

    def control(y):
        y_c[:] = y
        rc = controller.step(params, state, meas, cmd)
        if rc != 0:
            failed(rc)
        calls[0] += 1
        return out.copy()

    return run_split(sim, scenario, control, plant, info, n_cmd)


class BuiltinPlant:
    """tmtcontrol's plant as a :func:`~tmtcontrol.simulation.cosim.run_split`
    plant: :func:`~tmtcontrol.simulation.closedloop.build_plant` (the
    simulator's integrator and contact refinement) and the simulated force
    sensor, with the scenario's parameters ``P``."""

    def __init__(self, sim, P):
        sc = sim.scenario.simulation
        surface, task = sim.surface, sim.task
        self.plant = build_plant(sim.plant, sc.integrator, sc.substeps, sc.tol, sc.contact_refine, surface)
        self.sensor = _sensor(sim.plant, surface)
        PP = param_layout(task, sim.law, surface).split(P)
        self.PZ = plant_inputs_layout(task, surface)
        self.surf = np.concatenate([PP[name] for name, _ in surface.fields])
        self.d_e = PP["d_e"]
        self.pz = self.PZ.pack(tau=np.zeros(task.n), k_e=0.0, d_e=PP["d_e"], Ts=PP["Ts"],
                               **{k: PP[k] for k, _ in surface.fields})

    def sense(self, z, k_e):
        f, normal = self.sensor(z, k_e, self.d_e, self.surf)
        return float(f), np.asarray(normal).ravel()

    def advance(self, z, tau, k_e):
        self.pz[self.PZ["tau"]], self.pz[self.PZ["k_e"]] = tau, k_e
        return np.asarray(self.plant(z, self.pz)).ravel()


def _sensor(robot, surface) -> ca.Function:
    """The simulated force sensor: the true normal contact force (N) at the
    joints ``z``, as the simulator's step computes it (eq. 1's environment),
    and the surface's inward normal there."""
    from ..simulation.closedloop import kinematics

    n = robot.n
    z, k_e, d_e = ca.SX.sym("z", 2 * n), ca.SX.sym("k_e"), ca.SX.sym("d_e")
    sizes = [size for _, size in surface.fields]
    sv = ca.SX.sym("surface", sum(sizes))
    parts = ca.vertsplit(sv, np.cumsum([0, *sizes]).tolist())
    par = {name: part for (name, _), part in zip(surface.fields, parts)}
    _, _, _, R, X, dX = kinematics(robot, surface, z[:n], z[n:], par)
    return ca.Function("sensor", [z, k_e, d_e, sv], [contact_force(X[0], dX[0], k_e, d_e), R[:, 0]])


def measurement_table(result) -> tuple[np.ndarray, list[str]]:
    """What a robot running ``result``'s loop measured each period, as the
    rows ``replay`` reads: ``[t, q, dq, force (base frame), pos_t, vel_t,
    acc_t]`` and the column names. The force is the simulated sensor's
    (contact force plus the scenario's noise, seeded as in the run)."""
    from ..simulation.geometry import surface_of
    from ..simulation.simulator import Simulator

    sc = result.scenario
    n = result.q.shape[0]
    U, _, _, t = Simulator(sc, compile=False).inputs(sc)      # its inputs; the step is never built
    surface = surface_of(sc)
    normal = np.column_stack([surface.normal(p) for p in result.position.T])
    Uin = INPUT.split(U)
    force = -normal * (result.contact_force + Uin["noise"][0])[None, :]
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
