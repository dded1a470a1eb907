"""Environment: stiffness profiles k_e(t) such as Fig. 3 (the surface's shapes and
their contact law are :mod:`tmtcontrol.surface`; ``task_frame`` and
``contact_force`` are re-exported from there).

Task frame: origin at the circle centre on the plane; axis 0 ("normal") points
*into* the surface, so that the normal coordinate x grows with penetration and
the contact law reads, as in section III, ``f_e = k_e (x - x_e)`` with
``x_e = 0`` the surface; axes 1 and 2 span the plane.
"""

from __future__ import annotations

import numpy as np

from ..surface import contact_force
from ..surface import tilt_frame as task_frame
from .geometry import surface_of
from .scenario import read_stiffness_table

__all__ = ["task_frame", "contact_force", "stiffness_samples", "CONTACT_NOISE_SIGMAS", "contact_detection_threshold",
           "surface_error"]


def stiffness_samples(profile, t: np.ndarray, default_segment: float) -> np.ndarray:
    """k_e at times ``t`` (N/m). ``default_segment`` (s) is the piecewise-constant
    segment length when the profile does not set one (the trajectory period)."""
    t = np.asarray(t, dtype=float)
    if profile.kind == "piecewise_constant":
        seg = profile.segment or default_segment
        idx = np.minimum(np.floor(t / seg + 1e-9).astype(int), len(profile.values) - 1)
        return np.asarray(profile.values, dtype=float)[idx]
    if profile.kind == "piecewise_linear":
        return np.interp(t, profile.times, profile.values)
    if profile.kind == "sinusoidal":
        return profile.mean + profile.amplitude * np.sin(2 * np.pi * t / profile.period)
    tt, kk = read_stiffness_table(profile.file)
    return np.interp(t, tt, kk)


CONTACT_NOISE_SIGMAS = 6.0
"""Standard deviations of the filtered sensor noise added to the contact
threshold of the guarded approach (a Gaussian sample exceeds 6 sigma about
once in 1e9 samples: no false contact in a 1,000 s approach at 1 kHz)."""


def contact_detection_threshold(threshold: float, noise_std: float, alpha: float) -> float:
    """The measured force (N) that ends the guarded approach:
    ``controller.contact_threshold`` plus :data:`CONTACT_NOISE_SIGMAS` standard
    deviations of the sensor noise after the force filter, ``noise_std
    sqrt((1 - alpha)/(1 + alpha))`` (the first-order filter
    ``f_m = alpha f_m + (1 - alpha)(f + n)`` with pole ``alpha``; 0: none).
    Noise alone then never ends the approach early (one sample above 1 N with
    0.5 N noise did, 0.3 s early, taking the surface 3 mm too high and hitting
    at 2.6-2.9 f_d);
    without noise it is the threshold itself."""
    if noise_std == 0:
        return threshold
    return threshold + CONTACT_NOISE_SIGMAS * noise_std * (((1.0 - alpha) / (1.0 + alpha)) ** 0.5)


def surface_error(scenario) -> float:
    """The controller's surface-location error along the inward normal at the
    path's centre (m, positive: believed deeper than it is):
    ``controller.x_e_error + controller.part_offset . n``. Exact on a plane
    (a part offset along the normal is an x_e error there, tested); on a
    curved part the value at the centre, for the 1-D analyses. With a
    guarded approach the approach finds the surface, and the estimate is set
    to where the tool is when the measured force reaches the detection
    threshold f_c, plus ``x_e_error``: f_c/k_e inside the surface (k_e at
    the first contact, about trajectory.approach_gap / controller.approach_speed
    into the run), an error that stays for the run (review 22: the known law
    with its exact stiffness settles k_eff f_c/k_e above f_d, 19.8 mN on 5e3
    N/m; "the contact point" was assumed)."""
    sc = scenario
    if sc.trajectory.approach_gap > 0 and sc.controller.approach_speed > 0:
        # a guarded approach measures the surface: at contact x_e^ = x + x_e_error, the offset's normal part gone
        f_c = contact_detection_threshold(sc.controller.contact_threshold, sc.sensor.noise_std,
                                          sc.sensor.pole(sc.controller.Ts))
        t_c = sc.trajectory.approach_gap / sc.controller.approach_speed
        k_c = float(stiffness_samples(sc.environment.stiffness, np.array([t_c]), sc.trajectory.period)[0])
        return float(sc.controller.x_e_error + f_c / k_c)
    n = surface_of(sc).normal(np.asarray(sc.trajectory.center, dtype=float))
    return float(sc.controller.x_e_error + np.dot(sc.controller.part_offset, n))
