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
from .geometry import surface_of, under_the_commanded_path
from .scenario import read_stiffness_table

__all__ = ["task_frame", "contact_force", "stiffness_samples", "CONTACT_NOISE_SIGMAS", "contact_detection_threshold",
           "surface_error", "approach_depth", "approach_normal",
           "belief_after_approach", "has_approach"]


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


def approach_normal(scenario) -> np.ndarray:
    """The surface's inward normal where the guarded approach meets it (below
    the path's start, as the simulator starts the approach): there the
    approach measures the part, removing a part offset's component along it."""
    from .trajectory import path_reference

    surface = surface_of(scenario)
    pos0 = path_reference(np.zeros(1), scenario.trajectory).pos[:, 0]
    start = under_the_commanded_path(scenario, np.r_[-scenario.trajectory.approach_gap, pos0])
    return np.asarray(surface.normal(surface.to_base(start)), float)


def approach_depth(scenario) -> float:
    """How deep (m) the tool is in the surface when the guarded approach
    detects it: the true force ``k_e v t`` (the tool at the approach speed v,
    k_e at that time) through the force filter ``f_m[j] = a f_m[j-1] + (1 -
    a) f[j]``, whose output for a ramp ``c j`` is ``c (j - a (1 - a^j)/(1 -
    a))``, reaching the detection threshold f_c
    (:func:`contact_detection_threshold`): ``f_c/k_e`` without a filter, more
    behind a slow one (review 27: a 10 Hz filter took the tool 0.34 mm deep
    at 10 mm/s on 5,000 N/m, not 0.2 mm)."""
    from scipy.optimize import brentq

    sc, ctl = scenario, scenario.controller
    Ts, v, a = ctl.Ts, ctl.approach_speed, sc.sensor.pole(ctl.Ts)
    f_c = contact_detection_threshold(ctl.contact_threshold, sc.sensor.noise_std, a)
    t0 = sc.trajectory.approach_gap / v
    stiffness = lambda t: float(stiffness_samples(sc.environment.stiffness, np.array([t]), sc.trajectory.period)[0])
    j = 0.0
    for _ in range(2):          # k_e at the detection, not at the touch (a switch between them)
        c = stiffness(t0 + j * Ts) * v * Ts
        lag = a / (1.0 - a)
        y = lambda i: c * (i - lag * (1.0 - a ** i)) - f_c
        j = brentq(y, 0.0, f_c / c + lag + 1.0, xtol=1e-9)
    return float(v * Ts * j)


def has_approach(scenario) -> bool:
    """Whether ``scenario`` starts with a guarded approach
    (``trajectory.approach_gap`` and ``controller.approach_speed`` above 0)."""
    return scenario.trajectory.approach_gap > 0 and scenario.controller.approach_speed > 0


def belief_after_approach(scenario) -> tuple[float, np.ndarray]:
    """The controller's surface belief as a guarded approach leaves it:
    ``(x_e_error, part_offset)`` with the estimate :func:`approach_depth`
    deeper and the offset's component along :func:`approach_normal` gone
    (the approach measured the part there); the scenario's own values when
    it has no guarded approach."""
    sc = scenario
    offset = np.asarray(sc.controller.part_offset, dtype=float)
    if not has_approach(sc):
        return float(sc.controller.x_e_error), offset
    m = approach_normal(sc)
    return float(sc.controller.x_e_error + approach_depth(sc)), offset - (offset @ m) * m


def surface_error(scenario) -> float:
    """The controller's surface-location error along the inward normal at the
    path's centre (m, positive: believed deeper than it is):
    ``controller.x_e_error + controller.part_offset . n``. Exact on a plane
    (a part offset along the normal is an x_e error there, tested); on a
    curved part the value at the centre, for the 1-D analyses. With a
    guarded approach the approach finds the surface, and the estimate is set
    to where the tool is when the measured force reaches the detection
    threshold, plus ``x_e_error``: :func:`approach_depth` inside the surface
    (f_c/k_e without a force filter), an error that stays for the run (review
    22: the known law with its exact stiffness settles k_eff f_c/k_e above
    f_d, 19.8 mN on 5e3 N/m; "the contact point" was assumed); the part
    offset's component along :func:`approach_normal` is gone, the rest of it
    projected on the centre's normal."""
    x_e_error, offset = belief_after_approach(scenario)
    n = surface_of(scenario).normal(np.asarray(scenario.trajectory.center, dtype=float))
    return float(x_e_error + np.dot(offset, n))
