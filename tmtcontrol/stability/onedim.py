"""A scenario's normal axis as the 1-D analyses see it, and its stiffness limit (eqs. 19-25, sampled).

:func:`scenario_parameters` reads a scenario's normal-axis numbers (m, b, k,
f_d, the stiffness range, Ts, the inner-loop gains, the force filter, and the
robot's effective normal mass along the path); :func:`scenario_stiffness_limit`
is the largest stable constant k_e of the sampled 1-D loop of its law, the
limit every verdict and every other analysis starts from
(:mod:`.analysis`, :mod:`.periodic`); :func:`free_axes` are the task's
other axes, which meet no contact force, each a sampled PD loop of its own
(:func:`.sampled.free_axis_radius`). Units are SI.
"""

from __future__ import annotations

import numpy as np

from .sampled import free_axis_radius, largest_stable, max_stable_stiffness, spectral_radius

__all__ = ["scenario_parameters", "stiffness_seen", "normal_masses", "scenario_stiffness_limit",
           "closed_form_applies", "scheduled_damping", "free_axes", "unstable_free_axis"]


def scenario_parameters(scenario) -> dict:
    """Normal-axis parameters of a scenario for the analysis: m, b, k, f_d, the
    stiffness range of its profile, Ts, the inner-loop gains, the force filter
    pole, the robot's effective normal mass along the path (min and max),
    and the controller's surface-location error at the path's centre
    (``x_e_error``, m: ``controller.x_e_error`` plus the part position
    error's component along the inward normal there, ``part_offset . n``;
    exact on a plane, the centre's value on a curved part)."""
    from ..simulation.environment import surface_error

    sc = scenario
    masses = normal_masses(sc)
    k_e = stiffness_seen(sc)
    kd, kp = sc.impedance.gains
    return {"m": sc.impedance.m[0], "b": sc.impedance.b[0], "k": sc.impedance.k[0],
            "f_d": sc.controller.f_d, "k_e_min": float(k_e.min()), "k_e_max": float(k_e.max()),
            "k_e_values": sorted({float(v) for v in k_e}) if len(set(k_e)) <= 20 else [],
            "Ts": sc.controller.Ts, "kd": kd[0], "kp": kp[0],
            "alpha": sc.sensor.pole(sc.controller.Ts),
            "d_e": sc.environment.damping, "m_p_min": min(masses), "m_p_max": max(masses),
            "law": sc.controller.law.kind, "delay": sc.controller.delay_samples,
            "x_e_error": surface_error(sc)}


def stiffness_seen(sc) -> np.ndarray:
    """The surface stiffness k_e (N/m) at each control instant of the run."""
    from ..simulation.environment import stiffness_samples

    return stiffness_samples(sc.environment.stiffness, np.arange(0.0, sc.duration, sc.controller.Ts),
                             sc.trajectory.period)


def normal_masses(sc) -> list:
    """The arm's effective mass (kg) along the surface's inward normal n at the
    checked path poses, ``1/(n^T J_v M^-1 J_v^T n)`` (J_v the linear rows of
    J: the mass the normal axis meets with the other axes free; for a square
    position task this is ``1/(n^T D*^-1 n)`` with the Cartesian inertia D*
    of eq. 5)."""
    from ..simulation.geometry import surface_of
    from ..simulation.simulator import normal_mass, path_of, robot_of

    robot = robot_of(sc)
    path = path_of(robot, sc)
    surface = surface_of(sc)
    return [normal_mass(robot, q, surface.normal(robot.fk(q)[:3, 3])) for q in path.q.T]


def scenario_stiffness_limit(scenario, params: dict | None = None) -> float | None:
    """The largest stable constant k_e (N/m) predicted for a scenario by the
    sampled normal-axis loop of its law (``stability.lawloop``), the worse
    of the path's two extreme effective masses, with the scenario's x_e
    error, computation delay, force filter, contact damping and inner-loop
    gains: the upper edge of the stable band of k_e that contains the
    scenario's smallest stiffness (a stiff contact damper makes the loop
    unstable on soft surfaces, below that band), 0 if the loop is unstable
    there (the limit is below the scenario). ``None`` for
    a law without a linear verdict (``Law.linear_analysis``) and for a loop
    with the mid-period hold (``controller.hold``): the 1-D model has no
    hold, whose lead puts the loop's limit about 4x higher on the pipe
    (``analyze --scenario`` gives that loop's own limits), so every user of
    this figure (simulate's verdicts and messages, the sweep's line and
    range) treats it as "no 1-D prediction"."""
    from ..control.laws import get_law
    from .lawloop import law_stiffness_limit

    if scenario.controller.hold == "mid_period":
        return None

    p = scenario_parameters(scenario) if params is None else params
    law = get_law(scenario.controller.law.kind)
    if not law.linear_analysis:
        return None
    ctl = scenario.controller
    bk = scheduled_damping(scenario, p["m"])
    if closed_form_applies(law.name, ctl.delay_samples, p["x_e_error"], p["k_e_min"], ctl.law):
        # the same loop in closed form (stability.sampled; equal to the law loop, tested), ~15x faster
        kw = dict(kd=p["kd"], kp=p["kp"], alpha=p["alpha"], d_e=p["d_e"], law=law.name)
        if bk is None:
            return min(max_stable_stiffness(p["m"], p["b"], p["k"], p["Ts"], mp, within=p["k_e_min"], **kw)
                       for mp in (p["m_p_min"], p["m_p_max"]))
        return min(largest_stable(lambda ke: spectral_radius(p["m"], k=p["k"], k_e=ke, Ts=p["Ts"], m_p=mp,
                                                     **{**kw, **bk(ke)}) < 1.0, within=p["k_e_min"],
                                  resonance=(mp, p["Ts"]))
                   for mp in (p["m_p_min"], p["m_p_max"]))
    kw = dict(m=p["m"], b=p["b"], k=p["k"], Ts=p["Ts"], f_d=p["f_d"], kd=p["kd"], kp=p["kp"], alpha=p["alpha"],
              d_e=p["d_e"], delta=p["x_e_error"], delay=scenario.controller.delay_samples)
    if bk is None:
        return min(law_stiffness_limit(law, scenario.controller.law, m_p=mp, within=p["k_e_min"], **kw)
                   for mp in (p["m_p_min"], p["m_p_max"]))
    from .lawloop import law_loop

    return min(largest_stable(lambda ke: law_loop(law, scenario.controller.law, k_e=ke, m_p=mp,
                                          **{**kw, **bk(ke)}).spectral_radius < 1.0,
                              within=p["k_e_min"], resonance=(mp, p["Ts"]))
               for mp in (p["m_p_min"], p["m_p_max"]))


def scheduled_damping(scenario, m: float):
    """With a scheduled damping (``controller.damping_schedule.kind = "zeta"``),
    ``k_e -> {"b": b, "kd": b/m}`` at the schedule's fixed point
    (``stability.wholeloop.equilibrium_damping``); else None."""
    if scenario.controller.damping_schedule.kind != "zeta":
        return None
    from .wholeloop import equilibrium_damping

    def bk(ke):
        b = equilibrium_damping(scenario, ke)
        return {"b": b, "kd": b / m}
    return bk


def closed_form_applies(law: str, delay: int, x_e_error: float, k_e_min: float | None = None,
                        params=None) -> bool:
    """Whether the closed-form 1-D model (``stability.sampled``) is the law's
    sampled loop: TMT or the known-stiffness law, no delay, no x_e error, and
    for TMT (given ``k_e_min``, N/m) no stiffness below the law's
    ``min_stiffness`` (``params``, default the law's), where it clips its
    compliance estimate and the closed form's unclipped reference does not
    hold (with contact damping the closed form would call a soft surface
    unstable that the clipped law holds). Otherwise the law's own loop
    (``stability.lawloop``) is needed."""
    if not (law in ("tmt", "known") and delay == 0 and x_e_error == 0.0):
        return False
    if law == "tmt" and k_e_min is not None:
        from ..control.laws import get_law

        floor = getattr(params if params is not None else get_law("tmt").parameters(), "min_stiffness", 0.0)
        return k_e_min >= floor
    return True


def free_axes(scenario) -> list[tuple[str, float, float, float]]:
    """The loop's axes that meet no contact force, ``(name, K_D 1/s, K_P
    1/s^2, spectral radius)`` each: the two tangential task axes (eq. 6's
    gains, ``impedance.kd``/``kp`` or B/M, K/M), on a 6-D task the three
    rotational ones (``impedance.b_rot/m_rot``, ``k_rot/m_rot``), on a
    redundant arm the null-space posture (``robot.posture_kd``,
    ``posture_kp``); each radius of the sampled axis at the scenario's rate,
    computation delay and hold (:func:`.sampled.free_axis_radius`), with
    the gains the arm meets: the controller's model of mass scale
    ``robot.model_mass_scale`` = s turns the command into s times the
    acceleration (review 55: the upper edge 2/Ts of K_D moves to 2/(s Ts)).
    The inner loop is otherwise ideal: joint friction the controller does not
    compensate damps an axis further and is left out (an axis only friction
    holds is not proven stable). None of them depends on k_e, so one above 1
    makes the loop unstable at every stiffness, whatever the normal axis
    does. The gains returned are the settings' (before the scale)."""
    from ..simulation.closedloop import MID_PERIOD
    from ..simulation.simulator import robot_of

    ctl, imp = scenario.controller, scenario.impedance
    task = robot_of(scenario).task
    kd, kp = imp.gains
    gains = [(f"tangential axis {i}", kd[i], kp[i]) for i in (1, 2)]
    if task.rotational:
        gains += [(f"rotational axis {i + 1}", b / m, k / m)
                  for i, (m, b, k) in enumerate(zip(imp.m_rot, imp.b_rot, imp.k_rot))]
    if task.posture:
        gains.append(("null-space posture", scenario.robot.posture_kd, scenario.robot.posture_kp))
    lead, s = (MID_PERIOD if ctl.hold == "mid_period" else 0.0), scenario.robot.model_mass_scale
    return [(name, float(d), float(p), free_axis_radius(s * d, s * p, ctl.Ts, ctl.delay_samples, lead))
            for name, d, p in gains]


def unstable_free_axis(scenario) -> str | None:
    """Why the loop is unstable at every stiffness, naming the first of
    :func:`free_axes` whose sampled loop is unstable (its spectral radius,
    gains and period), or None if every one is stable."""
    for name, kd, kp, rho in free_axes(scenario):
        if not rho < 1.0:
            shown = f"{rho:.6g}" if abs(rho - 1.0) >= 1e-5 else f"1 {'+' if rho >= 1.0 else '-'} {abs(rho - 1.0):.2g}"
            s = scenario.robot.model_mass_scale
            scale = "" if s == 1.0 else f", times robot.model_mass_scale = {s:g} at the arm"
            return (f"unstable at every stiffness: the {name} alone has spectral radius {shown} at Ts = "
                    f"{scenario.controller.Ts:g} s (K_D = {kd:g} 1/s, K_P = {kp:g} 1/s^2{scale}; without delay it "
                    f"needs K_P >= 0 and Ts K_P/2 < K_D < 2/Ts)")
    return None
