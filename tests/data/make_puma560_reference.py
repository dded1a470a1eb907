"""Regenerate puma560_rtb_reference.csv from the Robotics Toolbox for Python.

Not run by the test suite (roboticstoolbox-python is not a dependency); kept so
the reference table's provenance is reproducible:

    pip install roboticstoolbox-python && python tests/data/make_puma560_reference.py

Values: links 1-3 of ``roboticstoolbox.models.DH.Puma560()`` (Corke &
Armstrong-Helouvry 1994 parameters, armature and friction included), its
``rne`` (inverse dynamics), ``inertia`` (M) and ``gravload`` (g), at seeded
random joint states, printed with 17 significant digits.
"""
import csv
import pathlib

import numpy as np
import roboticstoolbox as rtb

p = rtb.models.DH.Puma560()
r3 = rtb.DHRobot([p.links[i].copy() for i in range(3)], gravity=p.gravity)
rng = np.random.default_rng(20261122)
out = pathlib.Path(__file__).with_name("puma560_rtb_reference.csv")
with out.open("w", newline="") as fh:
    w = csv.writer(fh)
    w.writerow([f"q{i}" for i in (1, 2, 3)] + [f"dq{i}" for i in (1, 2, 3)]
               + [f"ddq{i}" for i in (1, 2, 3)] + [f"tau{i}" for i in (1, 2, 3)]
               + [f"M{i}{j}" for i in (1, 2, 3) for j in (1, 2, 3)]
               + [f"g{i}" for i in (1, 2, 3)] + ["px", "py", "pz"])
    for _ in range(24):
        q, dq, ddq = rng.uniform(-3, 3, (3, 3))
        tau = r3.rne(q, dq, ddq)
        M = r3.inertia(q)
        g = r3.gravload(q)
        pw = p.fkine(np.r_[q, 0.0, 0.0, 0.0]).t  # wrist centre: links 4-6 add no offset
        w.writerow([f"{v:.17g}" for v in np.r_[q, dq, ddq, tau, M.ravel(), g, pw]])
