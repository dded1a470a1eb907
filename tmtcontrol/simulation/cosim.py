"""The closed loop split at the sensors and run period by period: any controller against any plant.

The built-in simulation fuses controller and plant into one compiled step
(:mod:`.closedloop`). Two checks need them apart: the exported C controller
against tmtcontrol's plant (software in the loop, :mod:`tmtcontrol.export.sil`)
and tmtcontrol's controller against a plant nobody here wrote (MuJoCo,
:mod:`.mujoco_plant`). :func:`run_split` is that loop, written once: each
control period t_k it hands the controller the measurement of
:func:`.closedloop.measurement_layout` (joints, the contact force in the
base frame with the scenario's sensor noise, the tangential reference),
holds the returned torque (zero-order hold) while the plant advances one
period, and packs the same :class:`~.simulator.SimulationResult` as the
built-in run (its inputs, log layout and verdicts).

A *controller* is ``control(y) -> out``: ``out`` the command of
:func:`.closedloop.command_layout` followed by the diagnostics of
:func:`.closedloop.diagnostics_layout` (the exported C's command struct; the
joint torques are the command's last n entries). A *plant* has
``sense(z, k_e) -> (f_e, normal)`` (the true normal contact force, N, and the
inward unit normal at the tool) and ``advance(z, tau, k_e) -> z`` over one
period (z = [q, dq]).
"""

from __future__ import annotations

import time
from typing import Callable

import numpy as np

from ..files import check_interrupt
from .closedloop import INPUT, believed, build_controller, controller_param_layout, controller_state_layout, param_layout

__all__ = ["run_split", "builtin_controller"]


def run_split(sim, scenario, control: Callable, plant, info: dict, n_cmd: int):
    """Run ``scenario`` (its :class:`~.simulator.Simulator` ``sim``: inputs,
    path, result packing; its step is never built) with ``control`` against
    ``plant`` (module docstring); ``n_cmd`` the command's length (the
    diagnostics follow it). Returns the :class:`~.simulator.SimulationResult`
    with ``info`` added to its ``info``."""
    n = sim.task.n
    path = sim.path(scenario)
    U, _, s0, t = sim.inputs(scenario, path)
    N = U.shape[1]
    L = np.empty((sim.log.size, N))
    Uin = INPUT.split(U)
    z = s0[:2 * n].copy()
    y = np.empty(2 * n + 9)
    t0 = time.perf_counter()
    for k in range(N):
        k_e = Uin["k_e"][0, k]
        f_true, normal = plant.sense(z, k_e)
        y[0:2 * n] = z
        y[2 * n:2 * n + 3] = -normal * (f_true + Uin["noise"][0, k])
        y[2 * n + 3:2 * n + 5], y[2 * n + 5:2 * n + 7] = Uin["pos_t"][:, k], Uin["vel_t"][:, k]
        y[2 * n + 7:2 * n + 9] = Uin["acc_t"][:, k]
        out = control(y)
        tau = out[n_cmd - n:n_cmd]
        d = out[n_cmd:]
        L[:, k] = np.concatenate([z, tau, d[9:12], d[0:3], d[6:9], out[0:3], [f_true], d[12:16], d[16:]])
        z = plant.advance(z, tau, k_e)
        if k % 1000 == 0:
            check_interrupt()
    run_time = time.perf_counter() - t0
    S = np.hstack([L[0:2 * n, 1:], z[:, None]])      # the joints after each period, as the built-in run's
    sim._check_finite(S, L, t, n)
    return sim._result(scenario, t, L, U, path, {**info, "run_time_s": run_time, "steps": t.size,
                                                 "robot": sim.plant.name})


def builtin_controller(sim, scenario) -> tuple[Callable, int]:
    """``(control, n_cmd)``: the scenario's own controller (the expressions
    the built-in step runs, :func:`.closedloop.build_controller`, on CasADi's
    virtual machine) as a :func:`run_split` controller, started in the
    simulator's start state."""
    task, law, delay = sim.task, sim.law, sim.delay
    fn = build_controller(sim.model, law, delay, True, surface=sim.surface, hold=sim.hold)
    _, P, s0, _ = sim.inputs(scenario)
    p = controller_param_layout(task, law, sim.surface).pack(**believed(param_layout(task, law, sim.surface).split(P)))
    n_s = controller_state_layout(task, law, delay, hold=sim.hold).size
    state = {"s": s0[2 * task.n:2 * task.n + n_s].copy()}

    def control(y):
        s_next, cmd, diag = fn(state["s"], y, p)
        state["s"] = np.asarray(s_next).ravel()
        return np.concatenate([np.asarray(cmd).ravel(), np.asarray(diag).ravel()])

    return control, fn.size1_out(1)
