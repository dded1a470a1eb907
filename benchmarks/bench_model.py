"""Time to build the PUMA 560 model: the kinematics (built with the model) and all
its CasADi Functions (the dynamics are built on first use); target <= 1 s.

Run: python benchmarks/bench_model.py
Prints the median build time and its ratio to a plain reference run in the same
process (building just forward kinematics with CasADi), so the number can be
compared across machines.
"""
import pathlib
import sys

import casadi as ca

from tmtcontrol import Puma560
from tmtcontrol.model.puma560 import PUMA560_LINKS, _dh

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))   # also under PYTHONSAFEPATH (review 49)
from bench_all import median_time  # noqa: E402


def reference():
    q = ca.SX.sym("q", 3)
    T = ca.SX.eye(4)
    for i, link in enumerate(PUMA560_LINKS):
        T = T @ _dh(q[i], link)
    return ca.Function("fk", [q], [T[:3, 3]])


if __name__ == "__main__":
    t_kin = median_time(lambda: Puma560(armature=True, friction=True), 7)
    t_model = median_time(lambda: Puma560(armature=True, friction=True).mass_matrix, 7)
    print(f"Puma560() kinematics: {t_kin * 1e3:.1f} ms")
    t_ref = median_time(reference, 7)
    print(f"Puma560() with its dynamics: {t_model * 1e3:.1f} ms (target <= 1000 ms)")
    print(f"reference (fk only): {t_ref * 1e3:.2f} ms; ratio {t_model / t_ref:.0f}x")
