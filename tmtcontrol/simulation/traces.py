"""What a simulation's figures draw: its time series and the surface under
them, as plain NumPy arrays.

A :class:`~tmtcontrol.SimulationResult` carries its scenario, whose schema
needs pydantic and the laws' CasADi declarations to unpickle. Its
:class:`SimulationTraces` needs only NumPy, so a process that has imported
matplotlib and nothing of the simulator (:mod:`tmtcontrol.drawing`) can
receive it and draw Figs. 3-5 and the 3-D path.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["SimulationTraces"]


@dataclass(frozen=True, eq=False)
class SimulationTraces:
    """The series of Figs. 3-5 (SI: s, N, N/m, m; positions (3, N) in the
    base frame) and the plane of the 3-D path figure."""
    time: np.ndarray                 # (N,) s
    contact_force: np.ndarray        # (N,) f_e, N
    desired_force: np.ndarray        # (N,) f_d, N
    stiffness: np.ndarray            # (N,) k_e(t), N/m
    stiffness_estimate: np.ndarray   # (N,) f_m / (x - x_e), N/m; NaN out of contact
    position: np.ndarray             # (3, N) tool point X (the tip frame's origin), m
    reference_position: np.ndarray   # (3, N) X_r, m
    surface_frame: np.ndarray        # (3, 3) task axes (e_n, e_1, e_2) as columns
    center: np.ndarray               # (3,) centre of the circle, m
    radius: float                    # radius of the circle, m
    orientation_error: np.ndarray | None = None   # (N,) angle between tool and command, rad (6-D arms only)
    tool: str = "tool point"         # what X is, for the labels: "<robot> <tip frame> origin"
    desired_position: np.ndarray | None = None    # (3, N) X_d: the reference's point on the surface, m
    surface_mesh: np.ndarray | None = None        # (3, a, b) points of the surface around the path, m
    surface_name: str = "tilted plane"            # the surface, for the figure's title
