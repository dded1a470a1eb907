"""One call for the CLI and the report: a scenario's normal-axis parameters
and the whole analysis (continuous eq. 22/25 and sampled data) as plain values."""

from __future__ import annotations

import math

import numpy as np

from .continuous import AnalysisError, _check, _pos, analyze_continuous, analyze_range
from .limit import WHOLE_LOOP_RTOL, ScenarioLimit, deciding_limit, periodic_note, with_stiffness_limit
from .onedim import (closed_form_applies, free_axes, normal_masses, scenario_parameters, scenario_stiffness_limit,
                     scheduled_damping, unstable_free_axis)
from .sampled import sampled_closed_loop, spectral_radius, stable_band, stiffness_band

__all__ = ["normal_masses", "scenario_stiffness_limit", "with_stiffness_limit", "deciding_limit", "ScenarioLimit",
           "periodic_note", "scenario_parameters", "paper_effective_mass", "analyze", "analysis_kwargs",
           "analyze_scenario", "format_analysis", "closed_form_applies", "WHOLE_LOOP_RTOL",
           "check_linear_verdict"]





def paper_effective_mass(worst: bool = False) -> float:
    """Effective normal mass along the paper scenario's path, kg: the
    smallest, or with ``worst`` the largest (the sampled stiffness limit
    falls as m_p grows, so the largest mass is the worst case)."""
    from ..simulation.scenario import paper_scenario

    return scenario_parameters(paper_scenario())["m_p_max" if worst else "m_p_min"]


def _band_dict(bands) -> dict:
    """The stable band of k_e common to the masses' bands (``StiffnessBand``)
    as plain values (N/m; None where no stiffness of the scan is stable)."""
    lower, upper = max(bd.lower for bd in bands), min(bd.upper for bd in bands)
    if not (lower <= upper):            # NaN: no stable band found
        return {"lower": None, "upper": None, "unstable_below": True, "scan_from": bands[0].scan_from}
    return {"lower": float(lower), "upper": float(upper), "unstable_below": bool(lower > bands[0].scan_from),
            "scan_from": bands[0].scan_from}


def analyze(m, b, k, f_d=10.0, k_e=None, k_e_min=None, k_e_max=None, Ts=None, m_p=None,
            kd=None, kp=None, alpha=0.0, d_e=0.0, law="tmt", delay=0, x_e_error=0.0, law_params=None,
            damping=None) -> dict:
    """Everything ``tmtcontrol analyze`` reports, as a dict of plain values
    (the python-control objects under ``"systems"``).

    Give either ``k_e`` or ``k_e_min`` and ``k_e_max`` (N/m). With ``Ts`` (s)
    the sampled-data analysis is added; ``m_p`` (kg) is the robot's effective
    normal mass, a number or a (min, max) pair (default: both extremes along
    the paper path; the limit falls as m_p grows). ``delay`` (samples) and
    ``x_e_error`` (m, surface estimate minus true surface) enter the sampled
    loop and the steady state; with either, or a law other than ``tmt`` and
    ``known``, the loop is the law's own update (``stability.lawloop``),
    else the closed-form 1-D model (``stability.sampled``), which agree to
    5e-4 where both apply.

    ``damping``: a scheduled normal damping, a function ``k_e -> b`` (N s/m;
    ``stability.wholeloop.equilibrium_damping``): every stiffness is then
    analysed with its own b and K_D = b/m (the continuous part with the b of
    the largest stiffness), and ``b`` is only its fallback."""
    from ..control.laws import get_law

    _check(m, b, k, None, f_d)
    if not isinstance(delay, (int, np.integer)) or delay < 0:
        raise AnalysisError(f"delay: expected an integer >= 0 samples, got {delay!r}")
    if not np.isfinite(x_e_error):
        raise AnalysisError(f"x_e_error: must be finite, got {x_e_error!r}")
    if (k_e is None) == (k_e_min is None and k_e_max is None):
        raise AnalysisError("k_e: give either k_e or both k_e_min and k_e_max")
    if Ts is not None:                  # checked before any analysis (python-control's import takes ~1 s)
        _pos("Ts", Ts)
        if m_p is not None:
            m_p = tuple(m_p) if isinstance(m_p, (tuple, list)) else (m_p,)
            for v in m_p:
                _pos("m_p", v)
    if damping is not None:             # the continuous part at the damping of the stiffest surface
        b = float(damping(k_e if k_e is not None else k_e_max))
        _check(m, b, k, None, f_d)
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
    lw = get_law(law)
    params = lw.parameters() if law_params is None else law_params
    if lw.steady_force is not None and np.isfinite(out["steady_state_force"]):
        # the law as implemented (its clips, its assumed stiffness, the x_e error), at the worst end of the range;
        # eq. (22)'s own claim (f_d) stays under steady_state_force_eq22; an unstable loop has no steady force
        worst = max((lw.steady_force(params, f_d, k, ke, x_e_error) for ke in (lo, hi)),
                    key=lambda f: abs(f - f_d))
        out.update({"steady_state_force_eq22": out["steady_state_force"], "steady_state_force": float(worst)})
        if x_e_error != 0.0:
            out.update({"x_e_error": x_e_error, "steady_state_force_x_e_error": float(worst)})
        if not worst > 0.0:
            # review 34: the tool stays off the surface (x_e error beyond the reference's reach): the verdicts
            # below linearise a contact that does not exist, and the command exited 0
            out["in_contact"] = False
    out.update(_law_continuous(lw, params, m, b, k, hi, f_d, x_e_error, kd, kp))
    if Ts is not None:
        masses = m_p if m_p is not None else (paper_effective_mass(), paper_effective_mass(worst=True))
        grid = np.geomspace(lo, hi, 25) if hi > lo else np.array([lo])   # ends included exactly
        if damping is not None:
            bk = lambda ke: {"b": float(damping(ke)), "kd": float(damping(ke)) / m}   # K_D = b/m (eq. 9)
        if closed_form_applies(law, delay, x_e_error, lo, params):
            kw = {"kd": kd, "kp": kp, "alpha": alpha, "d_e": d_e, "law": law}
            if damping is None:
                bands = [stiffness_band(m, b, k, Ts, mp, within=lo, **kw) for mp in masses]
                rho = max(spectral_radius(m, b, k, ke, Ts, mp, **kw) for ke in grid for mp in masses)
            else:
                radius = lambda ke, mp: spectral_radius(m, k=k, k_e=ke, Ts=Ts, m_p=mp, **{**kw, **bk(ke)})
                bands = [stable_band(lambda ke: radius(ke, mp) < 1.0, rtol=1e-6, within=lo, resonance=(mp, Ts))
                         for mp in masses]
                rho = max(radius(ke, mp) for ke in grid for mp in masses)
                b, kw["kd"] = bk(hi)["b"], bk(hi)["kd"]
            out["systems"]["sampled"] = sampled_closed_loop(m, b, k, hi, Ts, max(masses), **kw).sys
            model = "closed-form 1-D (stability.sampled)"
        else:
            from .lawloop import law_loop, law_stiffness_band

            if not lw.linear_analysis:
                raise AnalysisError(f"law: {law!r} has no linear stability verdict (a continuum of equilibria)")
            kw = dict(m=m, b=b, k=k, Ts=Ts, f_d=f_d, kd=kd, kp=kp, alpha=alpha, d_e=d_e, delta=x_e_error,
                      delay=delay)
            if damping is None:
                bands = [law_stiffness_band(lw, params, m_p=mp, within=lo, **kw) for mp in masses]
                radius = lambda ke, mp: law_loop(lw, params, k_e=ke, m_p=mp, **kw).spectral_radius
            else:
                radius = lambda ke, mp: law_loop(lw, params, k_e=ke, m_p=mp, **{**kw, **bk(ke)}).spectral_radius
                bands = [stable_band(lambda ke: radius(ke, mp) < 1.0, within=lo, resonance=(mp, Ts))
                         for mp in masses]
            rho = max(radius(ke, mp) for ke in grid[::3] for mp in masses)
            model = "the law's 1-D loop (stability.lawloop)"
        if damping is not None:
            model += ", scheduled damping b(k_e)"
        limit = min(bd.limit for bd in bands)
        # within the band search's tolerance of its upper edge the spectral radius at the stiffness itself (rho
        # includes it) decides (review 34: the law loop's band, anchored at k_e = 163,410 N/m, ended at that very
        # stiffness, 6 N/m below the true limit, and a stable loop, radius 0.999999, read "NO")
        out.update({"Ts": Ts, "m_p": list(masses), "delay": delay, "x_e_error": x_e_error, "alpha": float(alpha),
                    "sampled_model": model, "max_stable_stiffness": limit, "stable_band": _band_dict(bands),
                    "spectral_radius": rho,
                    "sampled_stable": bool(rho < 1.0 and hi <= limit * (1.0 + BAND_RTOL))})
    return out


BAND_RTOL = 1e-4
"""The relative tolerance of the law loop's stiffness-band search
(``stability.lawloop.law_stiffness_band``; the closed form's is finer):
within it of the band's upper edge the sampled verdict is the spectral
radius at the stiffness itself."""


def _law_continuous(lw, params, m, b, k, k_e, f_d, delta, kd=None, kp=None) -> dict:
    """The law's own continuous loop at ``k_e`` as it runs, where it is not
    eq. (22)'s (review 16: ``analyze`` gave the integral and adaptive-damping
    laws eq. (22)'s poles, damping and overshoot as if they were theirs): the
    eigenvalues and least damping ratio of its linearisation with the inner
    loop of eq. (6) (``stability.lawloop.implemented_limit``; review 34: the
    polynomial the law declares, ``Law.characteristic_polynomial``, is its
    ideal-inner-loop (x = x_c) model, which scaled TMT's mass and damping by
    (1 - c) under an x_e error and made the integral law overdamped, damping
    ratio 1 where the running loop has 0.12), or ``law_poles = None`` for a
    law that declares no continuous model. Nothing where the loop is eq.
    (22)'s times the inner loop's ``s^2 + K_D s + K_P``."""
    from .lawloop import implemented_limit

    if lw.characteristic_polynomial is None:
        return {"law": lw.name, "law_poles": None}
    kd = b / m if kd is None else kd
    kp = k / m if kp is None else kp
    A, _ = implemented_limit(lw, params, m=m, b=b, k=k, k_e=k_e, f_d=f_d, delta=delta, kd=kd, kp=kp)
    roots = np.linalg.eigvals(A)
    eq22 = np.r_[np.roots([m, b, k + k_e]), np.roots([1.0, kd, kp])]
    order = lambda r: np.sort_complex(np.round(r, 9))
    if roots.size == eq22.size and np.allclose(order(roots), order(eq22), rtol=1e-7, atol=1e-9):
        return {}
    zeta = [float(-r.real / abs(r)) for r in roots if abs(r) > 0]
    return {"law": lw.name, "law_poles": [[float(r.real), float(r.imag)] for r in sorted(roots, key=lambda r: -r.real)],
            "law_damping_ratio": min(zeta) if zeta else 1.0, "law_stable": bool(np.all(roots.real < 0)),
            "law_model": "the loop as it runs: the law's update with the inner loop of eq. (6), K_D = "
                         f"{kd:.4g} 1/s, K_P = {kp:.4g} 1/s^2, exact model"}


def analysis_kwargs(p: dict) -> dict:
    """:func:`analyze` keywords for a scenario's :func:`scenario_parameters`:
    its normal axis, stiffness range (a single k_e if constant), Ts, gains,
    force filter, delay, x_e error and the path's effective masses."""
    kw = dict(m=p["m"], b=p["b"], k=p["k"], f_d=p["f_d"], Ts=p["Ts"], kd=p["kd"], kp=p["kp"],
              alpha=p["alpha"], d_e=p["d_e"], law=p["law"], m_p=(p["m_p_min"], p["m_p_max"]),
              delay=p["delay"], x_e_error=p["x_e_error"])
    if p["k_e_min"] == p["k_e_max"]:
        kw["k_e"] = p["k_e_min"]
    else:
        kw.update(k_e_min=p["k_e_min"], k_e_max=p["k_e_max"])
    return kw


def check_linear_verdict(scenario) -> None:
    """Raise :class:`AnalysisError`, naming ``controller.law.kind``, if the
    scenario's law has no linear stability verdict (``rls``: a continuum of
    equilibria), which ``analyze --scenario`` and the report need (review
    71: the refusal named the function's argument ``law``; review 72: the
    report met it after four stages)."""
    from ..control.laws import get_law

    kind = scenario.controller.law.kind
    if not get_law(kind).linear_analysis:
        raise AnalysisError(f"controller.law.kind: {kind!r} has no linear stability verdict (a continuum of "
                            "equilibria); simulate, compare and sweep run it and judge its runs")


def analyze_scenario(scenario, points: int = 8, limits: bool = False) -> dict:
    """:func:`analyze` for a scenario (its law parameters included), plus
    the whole-loop linearisation (``stability.wholeloop``): the limit at
    ``points`` path points, whose minimum decides the sampled verdict (the
    1-D limit stays as the closed-form explanation).

    With ``limits`` (``tmtcontrol analyze --scenario``), the limit that
    decides the verdict, as every command quotes it
    (``stability.limit.deciding_limit``): the smaller of the limit along the
    moving path (``periodic_limit``, N/m; the monodromy,
    ``stability.periodic``) and the large-signal limit from the scenario's
    own start (``first_contact_limit``, N/m; ``stability.first_contact``),
    the frozen-point minimum staying as the conservative bound. Every arm runs
    the same loop (its task declared by the robot), the 1-D model with the
    arm's effective normal mass along the path."""
    from ..simulation.environment import has_approach

    check_linear_verdict(scenario)
    p = scenario_parameters(scenario)
    bk = scheduled_damping(scenario, p["m"])
    out = analyze(**analysis_kwargs(p), law_params=scenario.controller.law,
                  damping=None if bk is None else (lambda ke: bk(ke)["b"]))
    out["hold"] = scenario.controller.hold
    # the 1-D model has no mid-period hold: its figure is for reference only (review 59: the JSON said nothing)
    out["one_d_applies"] = scenario.controller.hold != "mid_period"
    if has_approach(scenario):
        # review 22: the x_e error printed is not only the user's (simulation.environment.surface_error)
        out["x_e_error_from"] = ("the guarded approach's estimate, set where the measured force reaches the "
                                 "detection threshold f_c (f_c/k_e inside the surface, deeper behind a force "
                                 "filter), plus controller.x_e_error")
    free = free_axes(scenario)
    out["free_axes"] = [{"axis": name, "kd": kd, "kp": kp, "spectral_radius": rho} for name, kd, kp, rho in free]
    out["free_axes_stable"] = all(rho < 1.0 for *_, rho in free)
    out["free_axes_note"] = unstable_free_axis(scenario)
    lim = deciding_limit(scenario, points=points, along_path=limits)
    if lim is not None:
        k_max = out.get("k_e_max", out.get("k_e"))
        # the 1-D model has no mid-period hold: with it the whole loop's verdict stands alone
        one_d = scenario.controller.hold != "mid_period"
        out.update({"whole_loop_limit": lim.whole_loop, "whole_loop_bracket": list(lim.whole_loop_bracket),
                    "whole_loop_points": [{"path_time": t, "limit": l} for t, l in lim.whole_loop_points],
                    "whole_loop_clipped": list(lim.whole_loop_clipped),
                    "sampled_stable": bool((out["sampled_stable"] or not one_d) and k_max < lim.whole_loop)})
        if lim.whole_loop_clipped:
            from ..simulation.simulator import robot_of

            names = robot_of(scenario).joint_names
            out["whole_loop_note"] = clipped_note([(j, names[j - 1]) for j in lim.whole_loop_clipped],
                                                  limits and lim.periodic_note is None)
        if limits and lim.limit == 0.0:         # unstable at the smallest stiffness, or a free axis at every one
            out.update({"limit": 0.0, "limit_from": lim.limit_from, "sampled_stable": False})
        elif limits:
            if lim.periodic_note is not None:
                out["periodic_note"] = lim.periodic_note
            if lim.periodic_set_by is not None:
                out.update({"periodic_set_by": lim.periodic_set_by, "periodic_radius": lim.periodic_radius,
                            "periodic_growth": lim.periodic_growth})
            out.update({"periodic_limit": lim.periodic, "first_contact_limit": lim.first_contact,
                        "limit": lim.limit, "limit_from": lim.limit_from,
                        "sampled_stable": bool(k_max < lim.limit)})
    if not out["free_axes_stable"]:         # review 54: whatever the normal axis does
        out["sampled_stable"] = False
    return out


def clipped_note(joints, moving: bool) -> str:
    """What a frozen-point minimum set where ``joints`` ((1-based number, name) pairs) reach the
    drive's torque clip (``ScenarioLimit.whole_loop_clipped``) means; ``moving``: the limits along
    the path and from first contact were computed (else the frozen minimum stands alone)."""
    named = ", ".join(f"{j} ({name})" for j, name in joints)
    which = f"the torque of joint {named} reaches" if len(joints) == 1 else f"the torques of joints {named} reach"
    return (f"at the path point that sets the frozen-point minimum, {which} the drive's clip (robot.saturate): the "
            "frozen arm holds no f_d there, so that minimum is the clip's, not the loop's"
            + ("; the limits along the path and from first contact follow the moving loop" if moving else ""))


def _set_by_rows(d: dict) -> list[str]:
    """What ends the periodic search, when it is not the spectral radius
    crossing 1 (then the radius just below the limit is no margin), and
    what that means for sensor noise (review 39: 5 mN of noise cost 22.7 N
    of force error at 0.9 x such a limit, where the noise-free run held 3 mN)."""
    how, rho, growth = d.get("periodic_set_by"), d.get("periodic_radius"), d.get("periodic_growth")
    if how not in ("transient growth", "orbit lost"):
        return []
    noise = (f"noise                the analysis is of the noise-free loop: near this limit it amplifies "
             f"perturbations, sensor noise among them, up to {growth:.3g}-fold within a period; simulate with "
             "sensor.noise_std over several periods (trajectory.cycles >= 5) before relying on a margin")
    if how == "transient growth":
        from .periodic import GROWTH_BOUND

        return [f"set by               transient growth: above it a perturbation grows more than "
                f"{GROWTH_BOUND:.0e}-fold within a period (spectral radius {rho:.3g}, growth {growth:.3g} "
                "just below: the radius is no margin)", noise]
    return [f"set by               the orbit is lost above it (spectral radius {rho:.3g}, transient growth "
            f"{growth:.3g} just below: the radius is no margin)", noise]


def _pole(re: float, im: float) -> str:
    """A pole to 4 significant digits, without the parts the digits cannot show: a real or imaginary
    part below 1e-6 of its modulus is rounding (review 52: a critically damped loop's double pole
    printed "-45.83-5.865e-07j", an undamped one's "-0-45.83j")."""
    size = math.hypot(re, im)
    re, im = (0.0 if abs(v) <= 1e-6 * size else v for v in (re, im))
    return f"{re + 0.0:.4g}" if im == 0.0 else f"{re + 0.0:.4g}{im:+.4g}j"


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
        "poles (eq. 22)       " + ", ".join(_pole(re, im) for re, im in d["poles"]),
        f"natural frequency    {d['natural_frequency']:.4g} rad/s",
        f"damping ratio        {d['damping_ratio']:.4g}",
        f"BIBO stable          {yes(d['bibo_stable'])}",
        (f"steady-state force   {d['steady_state_force']:.6g} N (eqs. 23-24: f_e = f_d)"
         # to rounding (review 15: eq. (22)'s DC gain gave 9.999999999999998 N beside the law's 10.0, and the line
         # said f_e = f_d "does not hold" of a law that holds it)
         if math.isclose(d.get("steady_state_force_eq22", d["steady_state_force"]), d["steady_state_force"],
                         rel_tol=1e-9) else
         f"steady-state force   {d['steady_state_force']:.6g} N (the law as implemented, worst end of the "
         f"range; eqs. 23-24's f_e = f_d does not hold here)"),
        f"critical damping     b >= {d['critical_damping']:.4g} N s/m (eq. 25)",
        f"step: overshoot      {d['overshoot_pct']:.3g} %, settling (2 %) {d['settling_time']:.4g} s",
    ]
    if "law_poles" in d:        # the law's own loop is not eq. (22): the lines above are the impedance filter's
        at = "at k_e_max" if "k_e_min" in d else "at k_e"
        rows.append(f"law {d['law']}: the lines above are eq. (22), the impedance filter on a known k_e; "
                    + ("the law declares no continuous-time model: its verdict is the sampled loop's below"
                       if d["law_poles"] is None else
                       f"its own loop ({at}, with the inner loop of eq. (6)): poles "
                       + ", ".join(_pole(re, im) for re, im in d["law_poles"])
                       + f", least damping ratio {d['law_damping_ratio']:.4g}, "
                       + ("stable" if d["law_stable"] else "UNSTABLE")))
    if "worst_damping_ratio" in d:
        rows += [f"worst damping ratio  {d['worst_damping_ratio']:.4g} (at k_e_max)",
                 f"stable for all k_e   {yes(d['stable_for_all'])}",
                 f"b for zeta >= 1      {d['b_for_critical_damping_over_range']:.4g} N s/m over the range; "
                 f"then settling at k_e_min {d['slowest_settling_with_that_b']:.4g} s"]
    if "steady_state_force_x_e_error" in d:
        rows.append(f"with x_e error       {d['x_e_error'] * 1e3:+.4g} mm: steady-state force "
                    f"{d['steady_state_force_x_e_error']:.6g} N (worst end of the range)")
    if d.get("in_contact") is False:
        rows.append("contact              NONE: the tool stays off the surface (steady-state force "
                    f"{d['steady_state_force']:.6g} N); the stability lines linearise a contact that does not exist")
    if "x_e_error_from" in d:
        rows.append(f"x_e error            {d['x_e_error_from']}")
    if "Ts" in d:
        a = d.get("alpha", 0.0)
        # review 22: the filter was modelled but never named (a limit falling 9x with no stated cause)
        filt = (f", force filter pole {a:.4g} (cut-off {-math.log(a) / (2 * math.pi * d['Ts']):.4g} Hz)"
                if a > 0 else "")
        ref = ("; the 1-D model has no mid-period hold: for reference only, the loop's own limit below decides"
               if d.get("one_d_applies") is False or d.get("hold") == "mid_period" else "")
        rows += [f"sampled at Ts        {d['Ts']:g} s, m_p = {', '.join(f'{v:.4g}' for v in d['m_p'])} kg, "
                 f"delay {d['delay']} sample(s), x_e error {d['x_e_error'] * 1e3:+.4g} mm{filt}",
                 (f"max stable k_e       {d['max_stable_stiffness']:.6g} N/m ({d['sampled_model']}{ref})"
                  if not ("limit" in d and d["limit"] < d["max_stable_stiffness"]) else
                  f"small-signal k_e     {d['max_stable_stiffness']:.6g} N/m ({d['sampled_model']}; not a safe "
                  f"limit: the loop's own limit below is lower)"),
                 f"spectral radius      {d['spectral_radius']:.6f}"]
        band = d.get("stable_band")
        if band is not None and band["unstable_below"]:     # an unstable band of soft surfaces (contact damping)
            smallest = d.get("k_e_min", d.get("k_e"))
            if band["lower"] is None:
                rows.append(f"stable band          none: unstable at every k_e scanned from {band['scan_from']:.6g} N/m")
            else:
                rows.append(f"stable band          k_e in [{band['lower']:.6g}, {band['upper']:.6g}] N/m (unstable "
                            f"from {band['scan_from']:.6g} N/m up to {band['lower']:.6g} N/m)")
            if band["lower"] is None or smallest < band["lower"]:
                rows.append(f"below the band       the smallest stiffness {smallest:.6g} N/m: unstable, so the "
                            "limit is below it (max stable k_e 0)")
        if "whole_loop_limit" in d:
            pts = d["whole_loop_points"]
            lo, hi = d.get("whole_loop_bracket", (d["whole_loop_limit"], None))
            rows.append("whole loop           not searched: unstable at every stiffness (free axes below)" if not pts
                        else f"whole loop           {lo:.6g} N/m (" + (f"stable there, unstable {hi / lo - 1:.0e} "
                                                                        "above; " if hi is not None and hi > lo else "")
                        + f"smallest over {len(pts)} path points; largest {max(p['limit'] for p in pts):.6g} N/m)")
            if "whole_loop_note" in d:
                rows.append(f"note                 {d['whole_loop_note']}")
        if "periodic_note" in d:
            rows += [f"along the path       {d['periodic_limit']:.6g} N/m (the frozen-point minimum; "
                     "no periodic analysis)", f"note                 {d['periodic_note']}"]
        elif "periodic_limit" in d:
            below = d["periodic_limit"] < d["whole_loop_limit"]
            # a minimum set on the torque clip is the clip's (the note above), no bound of the loop's
            frozen = ("the frozen-point minimum above is the clip's, not a bound" if d.get("whole_loop_clipped")
                      else "the frozen-point minimum above is the conservative bound")
            rows += [f"along the path       {d['periodic_limit']:.6g} N/m (periodic orbit: monodromy "
                     "over one period; " + ("below the frozen-point minimum: the moving path lowers it)" if below
                                            else frozen + ")")]
            rows += _set_by_rows(d)
        if "periodic_limit" in d:
            # the search stops at the periodic limit: a start that settles all the way up to it has a first-contact
            # limit at or above it, not equal to it (review 21; the report's ">=")
            rows += [(f"from first contact   >= {d['first_contact_limit']:.6g} N/m (the scenario's own start "
                      "settles up to the periodic limit, where the search stops)"
                      if d["first_contact_limit"] >= d["periodic_limit"] else
                      f"from first contact   {d['first_contact_limit']:.6g} N/m (the scenario's own start "
                      "settles below it, else a contact limit cycle)"),
                     f"limit                {d['limit']:.6g} N/m (the smaller: {d['limit_from']}; "
                     "decides the verdict)"]
        elif "limit" in d and d.get("limit_from") != d.get("free_axes_note"):
            # limit 0 without the searches' rows (a free axis says why in its own row)
            rows.append(f"limit                {d['limit']:.6g} N/m ({d['limit_from']})")
        if "free_axes" in d:
            rows.append(_free_axes_row(d))
        rows.append(f"sampled stable       {yes(d['sampled_stable'])}")
    return "\n".join(rows)


def _free_axes_row(d: dict) -> str:
    """The row of the axes without contact force (``onedim.free_axes``): stable with the largest
    spectral radius among them, or the first unstable one."""
    if not d["free_axes_stable"]:
        return f"free axes            NO: {d['free_axes_note']}"
    worst = max(d["free_axes"], key=lambda a: a["spectral_radius"])
    kinds = list(dict.fromkeys(a["axis"].removesuffix(" axis 1").removesuffix(" axis 2").removesuffix(" axis 3")
                               for a in d["free_axes"]))         # tangential, rotational, null-space posture
    named = kinds[0] if len(kinds) == 1 else f"{', '.join(kinds[:-1])} and {kinds[-1]}"
    return (f"free axes            stable ({len(d['free_axes'])} without contact force: the {named} axes; largest "
            f"spectral radius {worst['spectral_radius']:.6f}, the {worst['axis']})")
