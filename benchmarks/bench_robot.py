"""Mass matrix + bias per evaluation for the UR5 and the Panda, against Pinocchio.

Run: python benchmarks/bench_robot.py [--states N]

For each bundled arm, at N seeded random states, times (median of 7 passes
over the states, per state):

* tmtcontrol, CasADi virtual machine: ``robot.dynamics(compiled=False)(q, dq)``
  (one SX Function ``["q","dq"] -> ["M","n"]``) called from Python;
* tmtcontrol, compiled: ``robot.dynamics()(q, dq)``, the same Function as C
  (``gcc -O3``, cached), called from Python;
* tmtcontrol, compiled and mapped: the compiled Function's ``map`` over all N
  states in one call (what a rollout pays: no Python per state);
* Pinocchio (C++ through its Python API, same process): ``crba(q)`` +
  ``rnea(q, dq, 0)`` per state;

and prints each time, its ratio to Pinocchio's, and, beside it, the largest
relative difference of M and n from Pinocchio's over the states (accuracy).
Also the time to build the robot's Functions (parse + symbolic), and to load
them from the cache.
"""
import argparse
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(__file__))

from bench_all import median_time  # noqa: E402


def main(argv=None) -> int:
    import pinocchio as pin

    from tmtcontrol import load_robot
    from tmtcontrol.model.verify import random_states

    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--states", type=int, default=2000)
    args = ap.parse_args(argv)
    print(f"M + bias per state, {args.states} seeded random states, median of 7 passes")
    for name in ("ur5", "panda"):
        t_build = median_time(lambda: load_robot(name, cache=False), 5)
        t_load = median_time(lambda: load_robot(name), 5)
        robot = load_robot(name)
        states = list(random_states(robot, args.states, seed=0))
        Q = np.array([s[0] for s in states])
        DQ = np.array([s[1] for s in states])
        vm, compiled = robot.dynamics(compiled=False), robot.dynamics()
        mapped = compiled.map(len(states))

        model = pin.buildModelFromXML(robot.urdf)
        lock = [model.getJointId(j) for j in robot.held]
        if lock:
            model = pin.buildReducedModel(model, lock, pin.neutral(model))
        data = model.createData()
        zero = np.zeros(robot.n)

        def run_pin():
            for q, dq in zip(Q, DQ):
                pin.crba(model, data, q)
                pin.rnea(model, data, q, dq, zero)

        def run(f):
            def go():
                for q, dq in zip(Q, DQ):
                    f(q, dq)
            return go

        n = len(states)
        t_pin = median_time(run_pin, 7) / n
        t_vm = median_time(run(vm), 7) / n
        t_c = median_time(run(compiled), 7) / n
        t_map = median_time(lambda: mapped(Q.T, DQ.T), 7) / n

        err_M = err_n = 0.0
        Mall, nall = mapped(Q.T, DQ.T)
        Mall, nall = np.array(Mall), np.array(nall)
        for k, (q, dq) in enumerate(zip(Q, DQ)):
            Mp = pin.crba(model, data, q)
            Mp = np.triu(Mp) + np.triu(Mp, 1).T
            npn = pin.rnea(model, data, q, dq, zero)
            Mk = Mall[:, k * robot.n:(k + 1) * robot.n]
            err_M = max(err_M, np.linalg.norm(Mk - Mp) / np.linalg.norm(Mp))
            err_n = max(err_n, np.linalg.norm(nall[:, k] - npn) / np.linalg.norm(npn))
        print(f"\n{name} ({robot.n} joints): build {t_build * 1e3:.0f} ms, from the cache {t_load * 1e3:.0f} ms; "
              f"largest relative difference from Pinocchio: M {err_M:.1e}, n {err_n:.1e}")
        for label, t in (("Pinocchio crba + rnea (Python API)", t_pin),
                         ("tmtcontrol, CasADi virtual machine", t_vm),
                         ("tmtcontrol, compiled C", t_c),
                         ("tmtcontrol, compiled C, mapped over the states", t_map)):
            print(f"  {label:<48} {t * 1e6:8.2f} us/state   ratio to Pinocchio {t / t_pin:5.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
