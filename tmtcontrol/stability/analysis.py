"""One call for the CLI and the report: a scenario's normal-axis parameters
and the whole analysis (continuous eq. 22/25 and sampled data) as plain values."""

from __future__ import annotations

import numpy as np

from .continuous import AnalysisError, _check, _pos, analyze_continuous, analyze_range
from .sampled import effective_mass, max_stable_stiffness, sampled_closed_loop, spectral_radius

__all__ = ["scenario_stiffness_limit", "scenario_parameters", "paper_effective_mass", "analyze", "analysis_kwargs", "format_analysis"]



def scenario_parameters(scenario) -> dict:
    """Normal-axis parameters of a scenario for the analysis: m, b, k, f_d, the
    stiffness range of its profile, Ts, the inner-loop gains, the force filter
    pole, and the robot's effective normal mass along the path (min and max)."""
    from ..simulation.environment import stiffness_samples, task_frame
    from ..model import Puma560
    from ..simulation.simulator import check_path

    sc = scenario
    robot = Puma560(armature=sc.robot.armature, friction=False)
    path = check_path(robot, sc, n=73)
    n = task_frame(sc.environment.tilt_deg)[:, 0]
    masses = [effective_mass(np.asarray(robot.cartesian_inertia(q)), n) for q in path.q.T]
    t = np.arange(0.0, sc.duration, sc.controller.Ts)
    k_e = stiffness_samples(sc.environment.stiffness, t, sc.trajectory.period)
    kd, kp = sc.impedance.gains
    fc = sc.sensor.filter_cutoff
    return {"m": sc.impedance.m[0], "b": sc.impedance.b[0], "k": sc.impedance.k[0],
            "f_d": sc.controller.f_d, "k_e_min": float(k_e.min()), "k_e_max": float(k_e.max()),
            "k_e_values": sorted({float(v) for v in k_e}) if len(set(k_e)) <= 20 else [],
            "Ts": sc.controller.Ts, "kd": kd[0], "kp": kp[0],
            "alpha": float(np.exp(-2 * np.pi * fc * sc.controller.Ts)) if fc > 0 else 0.0,
            "d_e": sc.environment.damping, "m_p_min": min(masses), "m_p_max": max(masses),
            "law": sc.controller.law.kind}


def scenario_stiffness_limit(scenario, params: dict | None = None) -> float | None:
    """The largest stable constant k_e (N/m) predicted for a scenario by the
    sampled normal-axis loop of its law (``stability.lawloop``), the worse
    of the path's two extreme effective masses, with the scenario's x_e
    error, force filter, contact damping and inner-loop gains. ``None`` for
    a law without a linear verdict (``Law.linear_analysis``)."""
    from ..control.laws import get_law
    from .lawloop import law_stiffness_limit

    p = scenario_parameters(scenario) if params is None else params
    law = get_law(scenario.controller.law.kind)
    if not law.linear_analysis:
        return None
    kw = dict(m=p["m"], b=p["b"], k=p["k"], Ts=p["Ts"], f_d=p["f_d"], kd=p["kd"], kp=p["kp"], alpha=p["alpha"],
              d_e=p["d_e"], delta=scenario.controller.x_e_error)
    return min(law_stiffness_limit(law, scenario.controller.law, m_p=mp, **kw)
               for mp in (p["m_p_min"], p["m_p_max"]))


def paper_effective_mass(worst: bool = False) -> float:
    """Effective normal mass along the paper scenario's path, kg: the
    smallest, or with ``worst`` the largest (the sampled stiffness limit
    falls as m_p grows, so the largest mass is the worst case)."""
    from ..simulation.scenario import paper_scenario

    return scenario_parameters(paper_scenario())["m_p_max" if worst else "m_p_min"]


def analyze(m, b, k, f_d=10.0, k_e=None, k_e_min=None, k_e_max=None, Ts=None, m_p=None,
            kd=None, kp=None, alpha=0.0, d_e=0.0, law="tmt") -> dict:
    """Everything ``tmtcontrol analyze`` reports, as a dict of plain values
    (the python-control objects under ``"systems"``).

    Give either ``k_e`` or ``k_e_min`` and ``k_e_max`` (N/m). With ``Ts`` (s)
    the sampled-data analysis is added; ``m_p`` (kg) is the robot's effective
    normal mass, a number or a (min, max) pair (default: the paper path's
    minimum)."""
    _check(m, b, k, None, f_d)
    if (k_e is None) == (k_e_min is None and k_e_max is None):
        raise AnalysisError("k_e: give either k_e or both k_e_min and k_e_max")
    if k_e is not None:
        cont = analyze_continuous(m, b, k, k_e, f_d)
        out = cont.as_dict()
        out["systems"] = {"tf": cont.tf, "ss": cont.ss}
        lo = hi = k_e
    else:
        if k_e_min is None or k_e_max is None:
            raise AnalysisError("k_e_min/k_e_max: give both ends of the stiffness range")
        rng = analyze_range(m, b, k, k_e_min, k_e_max, f_d)
        out = rng.as_dict()
        out["systems"] = {"tf": rng.at_max.tf, "ss": rng.at_max.ss, "tf_min": rng.at_min.tf}
        lo, hi = k_e_min, k_e_max
    if Ts is not None:
        _pos("Ts", Ts)
        if m_p is None:
            m_p = paper_effective_mass()
        masses = tuple(m_p) if isinstance(m_p, (tuple, list)) else (m_p,)
        for v in masses:
            _pos("m_p", v)
        kw = {"kd": kd, "kp": kp, "alpha": alpha, "d_e": d_e, "law": law}
        limit = min(max_stable_stiffness(m, b, k, Ts, mp, **kw) for mp in masses)
        grid = np.geomspace(lo, hi, 25) if hi > lo else np.array([lo])   # ends included exactly
        rho = max(spectral_radius(m, b, k, ke, Ts, mp, **kw) for ke in grid for mp in masses)
        out.update({"Ts": Ts, "m_p": list(masses), "max_stable_stiffness": limit,
                    "spectral_radius": rho, "sampled_stable": bool(rho < 1.0 and hi < limit)})
        out["systems"]["sampled"] = sampled_closed_loop(m, b, k, hi, Ts, min(masses), **kw).sys
    return out


def analysis_kwargs(p: dict) -> dict:
    """:func:`analyze` keywords for a scenario's :func:`scenario_parameters`:
    its normal axis, stiffness range (a single k_e if constant), Ts, gains,
    force filter and the path's effective masses."""
    kw = dict(m=p["m"], b=p["b"], k=p["k"], f_d=p["f_d"], Ts=p["Ts"], kd=p["kd"], kp=p["kp"],
              alpha=p["alpha"], d_e=p["d_e"], law=p["law"], m_p=(p["m_p_min"], p["m_p_max"]))
    if p["k_e_min"] == p["k_e_max"]:
        kw["k_e"] = p["k_e_min"]
    else:
        kw.update(k_e_min=p["k_e_min"], k_e_max=p["k_e_max"])
    return kw


def format_analysis(d: dict) -> str:
    """The analysis as a readable table."""
    yes = lambda v: "yes" if v else "NO"
    rows = []
    if "k_e_min" in d:
        rows.append(f"stiffness range      {d['k_e_min']:.6g} .. {d['k_e_max']:.6g} N/m "
                    "(scalars below at k_e_max)")
    else:
        rows.append(f"stiffness            {d['k_e']:.6g} N/m")
    rows += [
        f"impedance            m = {d['m']:g} kg, b = {d['b']:g} N s/m, k = {d['k']:g} N/m, f_d = {d['f_d']:g} N",
        "poles (eq. 22)       " + ", ".join(f"{re:.4g}{im:+.4g}j" for re, im in d["poles"]),
        f"natural frequency    {d['natural_frequency']:.4g} rad/s",
        f"damping ratio        {d['damping_ratio']:.4g}",
        f"BIBO stable          {yes(d['bibo_stable'])}",
        f"steady-state force   {d['steady_state_force']:.6g} N (eqs. 23-24: f_e = f_d)",
        f"critical damping     b >= {d['critical_damping']:.4g} N s/m (eq. 25)",
        f"step: overshoot      {d['overshoot_pct']:.3g} %, settling (2 %) {d['settling_time']:.4g} s",
    ]
    if "worst_damping_ratio" in d:
        rows += [f"worst damping ratio  {d['worst_damping_ratio']:.4g} (at k_e_max)",
                 f"stable for all k_e   {yes(d['stable_for_all'])}",
                 f"b for zeta >= 1      {d['b_for_critical_damping_over_range']:.4g} N s/m over the range; "
                 f"then settling at k_e_min {d['slowest_settling_with_that_b']:.4g} s"]
    if "Ts" in d:
        rows += [f"sampled at Ts        {d['Ts']:g} s, m_p = {', '.join(f'{v:.4g}' for v in d['m_p'])} kg",
                 f"max stable k_e       {d['max_stable_stiffness']:.6g} N/m",
                 f"spectral radius      {d['spectral_radius']:.6f}",
                 f"sampled stable       {yes(d['sampled_stable'])}"]
    return "\n".join(rows)
