"""Mutation score of the test suite: does a deliberate one-line bug fail a test?

Each mutation below replaces one exact piece of source (it must occur exactly
once in its file) by a plausible bug that some input can reveal (no
equivalent mutants: e.g. any() for all() over eq. (22)'s stiffness grid is
not one, since its poles are stable for every k_e > 0 or for none): a flipped sign, a dropped term, any()
for all(), an off-by-one, a deleted validation, a verdict forced to pass.
For each, the script copies the tracked files of this checkout into a
scratch folder, applies the mutation there (your checkout is never
modified), and runs the tests that target the mutated module. A mutation is
*killed* if those tests fail, and *survives* if they pass. The score is
killed / total; the survivors are printed with the reason the mutation is a
bug, so each one is a missing test.

Slow (a few minutes to half an hour on 2 cores, mostly the compiled
simulations the tests run), so it is kept out of CI:

    python benchmarks/mutation_score.py                 # all mutations
    python benchmarks/mutation_score.py --list          # ids, files, tests
    python benchmarks/mutation_score.py --only tmt-smoothstep metrics-settling-off-by-one
    python benchmarks/mutation_score.py --check         # every mutation applies (fast)
    python benchmarks/mutation_score.py --json score.json

docs/speed.md states the last measured score.
"""

from __future__ import annotations

import argparse
import json
import os
import pathlib
import shutil
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass

ROOT = pathlib.Path(__file__).resolve().parents[1]


@dataclass(frozen=True)
class Mutation:
    id: str
    file: str
    old: str
    new: str
    tests: tuple[str, ...]
    why: str


def M(id, file, old, new, tests, why):
    return Mutation(id, f"tmtcontrol/{file}", old, new, tuple(tests.split()), why)


MUTATIONS = [
    # -- model (eq. 1) -------------------------------------------------------------
    M("model-gravity-sign", "model/puma560.py", "GRAVITY = 9.81", "GRAVITY = -9.81",
      "tests/test_robot.py", "gravity pulls up"),
    M("model-friction-viscous", "model/puma560.py", "abs(link.G) * (link.B * abs(link.G) * dq[i] + coulomb)",
      "abs(link.G) * (link.B * dq[i] + coulomb)", "tests/test_robot.py", "viscous friction not reflected through the gear"),
    M("model-armature-gear", "model/puma560.py", "M += ca.diag(ca.vertcat(*[l.G ** 2 * l.Jm for l in self.links]))",
      "M += ca.diag(ca.vertcat(*[l.G * l.Jm for l in self.links]))", "tests/test_robot.py",
      "rotor inertia reflected by G instead of G^2"),
    # -- impedance (eqs. 2-6) -------------------------------------------------------
    M("impedance-torque-force-term", "control/impedance.py",
      '"symbolicqr")) + n_hat + ca.mtimes(J.T, F_e)', '"symbolicqr")) + n_hat - ca.mtimes(J.T, F_e)',
      "tests/test_robot.py tests/test_simulate.py", "eq. (5)'s F_e enters with the wrong sign"),
    M("impedance-filter-rk-weight", "control/impedance.py",
      "h / 6 * (k1[0] + 2 * k2[0] + 2 * k3[0] + k4[0])", "h / 6 * (k1[0] + 2 * k2[0] + k3[0] + k4[0])",
      "tests/test_laws.py tests/test_derivations.py", "the filter's RK4 drops a stage weight"),
    M("impedance-filter-damping", "control/impedance.py", "return (F_e - b * dX_a - k * X_a) / m",
      "return (F_e + b * dX_a - k * X_a) / m", "tests/test_laws.py tests/test_derivations.py",
      "eq. (2) with negative damping"),
    # -- laws -------------------------------------------------------------------------
    M("tmt-smoothstep", "control/laws/tmt.py", "w = w * w * (3 - 2 * w)", "w = w",
      "tests/test_laws.py tests/test_derivations.py", "the C1 blend of eq. (18) near f_e = 0 becomes a kink"),
    M("tmt-clip-lower", "control/laws/tmt.py", "c = ca.fmin(ca.fmax((x - x_e) / f_safe, 0), 1 / min_stiffness)",
      "c = ca.fmin((x - x_e) / f_safe, 1 / min_stiffness)",
      "tests/test_laws.py tests/test_derivations.py", "negative compliance (a spring pulling) is allowed"),
    M("tmt-clip-upper", "control/laws/tmt.py", "c = ca.fmin(ca.fmax((x - x_e) / f_safe, 0), 1 / min_stiffness)",
      "c = ca.fmin(ca.fmax((x - x_e) / f_safe, 0), 10 / min_stiffness)",
      "tests/test_laws.py tests/test_derivations.py", "the stiffness estimate's lower bound is 10x too small"),
    M("tmt-threshold-double", "control/laws/tmt.py", "ratio = (f_e - force_threshold) / force_threshold",
      "ratio = (f_e - 2 * force_threshold) / force_threshold",
      "tests/test_laws.py tests/test_derivations.py", "the blend starts at twice the documented threshold"),
    M("known-keff", "control/laws/tmt.py", "return x_e + f_d / k_eff(k, k_e)", "return x_e + f_d / k",
      "tests/test_laws.py tests/test_derivations.py", "eq. (11) without the series stiffness of eq. (12)"),
    M("integral-sign", "control/laws/integral.py", 'e_f = y["f_d"] - y["f_m"]', 'e_f = y["f_m"] - y["f_d"]',
      "tests/test_laws.py", "positive feedback of the force error"),
    M("integral-feedforward", "control/laws/integral.py", 'dx_r = p["k_i"] * e_f', "dx_r = 0",
      "tests/test_laws.py", "the reference velocity of the integral drops out of eq. (4)"),
    M("adaptive-rate", "control/laws/adaptive_damping.py", 'p["sigma"] * e_f / y["b"]',
      'p["sigma"] * e_f * y["b"]', "tests/test_laws.py", "Phi's update is scaled by b^2 (Jung-Hsia-Bonitz divide by b)"),
    M("adaptive-bound", "control/laws/adaptive_damping.py", "return b * Ts / m", "return b * Ts",
      "tests/test_laws.py", "the documented sigma bound loses the mass"),
    M("rls-forgetting", "control/laws/rls.py", 'P_new = (P_use - ca.mtimes(g, Pphi.T)) / p["forgetting"]',
      "P_new = P_use - ca.mtimes(g, Pphi.T)", "tests/test_laws.py", "no forgetting: the covariance collapses"),
    M("rls-reset", "control/laws/rls.py", 'ca.fabs(e) > p["reset_error"]', "ca.fabs(e) > 1e9",
      "tests/test_laws.py", "no covariance reset at a stiffness switch"),
    M("rls-reference", "control/laws/rls.py", '+ y["f_d"] / y["k"] + y["f_d"] / k_hat', '+ y["f_d"] / k_hat',
      "tests/test_laws.py", "eq. (12)'s 1/k term is dropped from the RLS reference"),
    # -- closed loop -------------------------------------------------------------------
    M("loop-noise", "simulation/closedloop.py", '(f_true + U_in["noise"])', "(f_true)",
      "tests/test_simulate.py", "the force-sensor noise never reaches the controller"),
    M("loop-friction-compensation", "simulation/closedloop.py",
      "ca.mtimes(R, U), ca.mtimes(R, F_e)) + model.friction(dq)", "ca.mtimes(R, U), ca.mtimes(R, F_e))",
      "tests/test_simulate.py", "compensate_friction does nothing"),
    M("loop-filter-pole", "simulation/closedloop.py",
      'f_m = P["alpha"] * S["f_filt"] + (1 - P["alpha"]) * (f_true',
      'f_m = (1 - P["alpha"]) * S["f_filt"] + P["alpha"] * (f_true',
      "tests/test_simulate.py tests/test_verdicts.py", "the force filter's pole and gain are swapped"),
    M("loop-tangential-velocity", "simulation/closedloop.py", 'ca.vertcat(dx_c, U_in["vel_t"])',
      "ca.vertcat(dx_c, 0 * U_in[\"vel_t\"])", "tests/test_simulate.py", "the circle's velocity feedforward is zero"),
    M("loop-delay-order", "simulation/closedloop.py", "tau, tau_wait = queue[:3], queue[3:]",
      "tau, tau_wait = queue[-3:], queue[:-3]", "tests/test_verdicts.py", "the delay queue applies the newest torque"),
    M("loop-refine-dt", "simulation/closedloop.py", "p_sub = zm, ca.vertcat(pm[:-1], pm[-1] / n)",
      "p_sub = zm, ca.vertcat(pm[:-1], pm[-1])", "tests/test_simulate.py",
      "a refined period integrates n periods instead of one"),
    M("loop-schedule-zeta", "simulation/closedloop.py", '2 * P["zeta"] * ca.sqrt(m * (k + k_hat))',
      'P["zeta"] * ca.sqrt(m * (k + k_hat))', "tests/test_simulate.py tests/test_design.py",
      "the scheduled damping is half of eq. (25)"),
    M("loop-approach-estimate", "simulation/closedloop.py", 'ca.if_else(detect, X[0] + P["x_e_hat"], S["x_e_hat"])',
      'ca.if_else(detect, X[0], S["x_e_hat"])', "tests/test_simulate.py",
      "the configured x_e error is ignored after a guarded approach"),
    M("environment-damping", "simulation/environment.py", "f = k_e * pen + damping * dx", "f = k_e * pen",
      "tests/test_simulate.py", "environment.damping has no effect"),
    M("trajectory-velocity", "simulation/trajectory.py", "vel = radius * w * np.vstack([-s, c])",
      "vel = 0 * radius * w * np.vstack([-s, c])", "tests/test_simulate.py", "the reference's tangential velocity is zero"),
    # -- metrics -----------------------------------------------------------------------
    M("metrics-settling-off-by-one", "simulation/metrics.py", "return float(t[last + 1] - t[0]) if",
      "return float(t[last] - t[0]) if", "tests/test_simulate.py tests/test_verdicts.py",
      "the settling time ends one sample early"),
    M("metrics-contact-lost-all", "simulation/metrics.py", "contact_lost_steady=bool(np.any(f[ss] <= 0.0))",
      "contact_lost_steady=bool(np.all(f[ss] <= 0.0))", "tests/test_simulate.py tests/test_verdicts.py",
      "a steady state that loses contact now and then counts as in contact"),
    M("metrics-overshoot-direction", "simulation/metrics.py",
      "overshoot = (max(0.0, f_d - float(after.min())) if f[0] > f_d else",
      "overshoot = (max(0.0, float(after.max()) - f_d) if f[0] > f_d else",
      "tests/test_simulate.py tests/test_verdicts.py", "after a downward switch jump the jump is called overshoot"),
    M("metrics-limit-cycle", "simulation/metrics.py", "if a_B > band and a_B >= SUSTAINED * a_A and not forced:",
      "if a_B > 10 * band and a_B >= SUSTAINED * a_A and not forced:",
      "tests/test_simulate.py tests/test_verdicts.py tests/test_verdicts_wave3.py",
      "a sustained oscillation is called converged"),
    M("metrics-steady-window", "simulation/metrics.py", "ss_err = float(np.abs(err[ss]).max())",
      "ss_err = float(np.abs(err[ss]).mean())", "tests/test_simulate.py tests/test_laws.py",
      "the steady-state error is a mean, not the worst value"),
    # -- stability ----------------------------------------------------------------------
    M("continuous-range-at-min", "stability/continuous.py", "return zeta * critical_damping(m, k, k_e_max)",
      "return zeta * critical_damping(m, k, k_e_min)", "tests/test_stability.py",
      "the damping for a stiffness range is set at its softest end (underdamped at the stiffest)"),
    M("continuous-bibo-margin", "stability/continuous.py",
      "else bool(np.all(eig.real < 0.0))", "else bool(np.all(eig.real <= 0.0))",
      "tests/test_stability.py", "a marginally stable loop (poles on the axis) is called BIBO stable"),
    M("sampled-ignores-whole-loop", "stability/analysis.py",
      '"sampled_stable": bool(out["sampled_stable"] and k_max < limit)})',
      '"sampled_stable": bool(out["sampled_stable"])})', "tests/test_stability.py tests/test_verdicts.py",
      "the scenario's sampled verdict ignores the whole-loop stiffness limit"),
    M("wholeloop-dynamic-states", "stability/wholeloop.py", "A = A_full[np.ix_(d, d)]",
      "A = A_full[:d.size, :d.size]", "tests/test_verdicts.py",
      "the whole loop's A taken over the first states, not the dynamic ones (bookkeeping included)"),
    M("sampled-bisection", "stability/sampled.py",
      "if spectral_radius(m, b, k, mid, Ts, m_p, **kw) < 1.0:\n            lo = mid",
      "if spectral_radius(m, b, k, mid, Ts, m_p, **kw) > 1.0:\n            lo = mid",
      "tests/test_stability.py", "the limit bisection walks the wrong way"),
    M("sampled-zoh-euler", "stability/sampled.py", "E = expm(M * Ts)", "E = np.eye(n + mi) + M * Ts",
      "tests/test_stability.py", "the sampled model discretised by Euler, not the exact ZOH"),
    # -- design ---------------------------------------------------------------------------
    M("design-weight-term", "stability/design.py", "(1 + (k_e / self.k_e_min - 1) ** 2 + (k_e / self.k_e_max - 1) ** 2)",
      "(1 + (k_e / self.k_e_min - 1) ** 2)", "tests/test_design.py", "a design event weight term is dropped"),
    M("design-objective-max", "stability/design.py", "return max(float(w) * float(_ISE(b, k, ke, spec.m))",
      "return min(float(w) * float(_ISE(b, k, ke, spec.m))", "tests/test_design.py",
      "the worst case becomes the best case"),
    # -- schema ---------------------------------------------------------------------------
    M("schema-b-min-max", "simulation/scenario.py", "if self.b_min > self.b_max:", "if False:",
      "tests/test_scenario.py", "b_min > b_max is accepted"),
    M("schema-amplitude", "simulation/scenario.py", "if self.amplitude >= self.mean:", "if False:",
      "tests/test_scenario.py", "a sinusoid that makes k_e negative is accepted"),
    M("schema-bool-strict", "simulation/scenario.py",
      'compensate_friction: StrictBool = Field(False', 'compensate_friction: bool = Field(False',
      "tests/test_scenario.py", "compensate_friction = 1 (or \"yes\") is accepted as a boolean"),
    M("schema-knots-increasing", "simulation/scenario.py", "if any(b <= a for a, b in zip(self.times, self.times[1:])):",
      "if any(b < a for a, b in zip(self.times, self.times[1:])):", "tests/test_scenario.py",
      "repeated knot times are accepted"),
    M("schema-table-positive", "simulation/scenario.py", 'raise ValueError(f"file: stiffness must be > 0 in',
      'pass  # raise ValueError(f"file: stiffness must be > 0 in', "tests/test_scenario.py",
      "a stiffness table with k_e <= 0 is accepted"),
    # -- outputs ----------------------------------------------------------------------------
    M("files-foreign-file", "files.py", "    if foreign:\n", "    if False:\n", "tests/test_outputs.py",
      "a user's file inside an old output folder is deleted"),
    M("csv-row-format", "simulation/output.py", 'row = ",".join(["%.9g"] * data.shape[1])',
      'row = ",".join(["%.6g"] * data.shape[1])', "tests/test_outputs.py",
      "timeseries.csv keeps 6 significant digits, not the documented 9"),
    M("csv-forked-half-lost", "simulation/output.py", "return text if status == 0 else here()", "return text",
      "tests/test_outputs.py", "if the forked process dies, timeseries.csv silently lacks the second half of its rows"),
    M("csv-forked-half-left-running", "simulation/output.py", "os.kill(pid, signal.SIGKILL)", "pass",
      "tests/test_outputs.py", "after an error or Ctrl-C the forked CSV process runs on"),
    M("drawing-stop-one-process", "drawing.py", "os.killpg(self._pid, signal.SIGKILL)",
      "os.kill(self._pid, signal.SIGKILL)", "tests/test_drawing.py",
      "stopping the figure workers kills the first only: the second keeps writing into the folder"),
    M("drawing-traces-frame", "simulation/simulator.py", "surface_frame=task_frame(sc.environment.tilt_deg)",
      "surface_frame=task_frame(0.0)", "tests/test_drawing.py",
      "the figure workers draw the path on a level plane, not the scenario's tilted one"),
    M("slimsvg-rule-over-attribute", "report/slimsvg.py", "for name, value in {**rule, **own}.items():",
      "for name, value in {**own, **rule}.items():", "tests/test_slimsvg.py",
      "the stylesheet rule overrides an element's own style in the slimmed SVG"),
    M("slimsvg-flatten-transform", "report/slimsvg.py",
      'and all(k == "id" or rule.get(k) == v for k, v in child.attrib.items()))',
      'and all(k != "style" for k in child.attrib))', "tests/test_slimsvg.py",
      "groups with a transform or clip path are flattened away"),
    # -- report verdicts --------------------------------------------------------------------
    M("report-checks-always-pass", "report/document.py", '"Derivation checks pass", n_ok == len(checks)',
      '"Derivation checks pass", True', "tests/test_report.py", "a failed derivation check passes the report"),
    M("report-force-tolerance", "report/document.py", "FORCE_TOLERANCE = 0.01", "FORCE_TOLERANCE = 1.0",
      "tests/test_report.py", "the report's force tolerance is 100x the documented 0.01 N"),
    M("report-sampled-verdict", "report/document.py",
      'f"Stable in the sampled implementation (Ts = {fmt.qty(Ts, \'s\')})", bool(a["sampled_stable"])',
      'f"Stable in the sampled implementation (Ts = {fmt.qty(Ts, \'s\')})", True',
      "tests/test_report.py", "an unstable sampled loop passes the report"),
    M("report-continuous-verdict", "report/document.py",
      "stable = bool(rng.stable_for_all and all(a.bibo_stable for a in per_k))", "stable = True",
      "tests/test_report.py", "an unstable continuous loop passes the report"),
    M("report-claim-floor", "report/document.py", "if first >= end or (last and end - 1 < floor):",
      "if first >= end:", "tests/test_report.py",
      "this process takes the python-control tasks too (and pays ~0.8 s importing it)"),
    M("report-verdict-order", "report/document.py",
      "for stage in sorted(verdicts, key=_VERDICT_ORDER.index)", "for stage in verdicts",
      "tests/test_report.py", "the verdict summary in the order the processes happened to finish"),
    M("metrics-contact-lost-from-start", "simulation/metrics.py",
      "lost = np.count_nonzero(f[touching[0]:] <= 0.0) if touching.size else f.size",
      "lost = np.count_nonzero(f <= 0.0)", "tests/test_simulate.py",
      "the approach before first contact counts as a contact lost"),
    M("continuous-import-before-check", "stability/continuous.py",
      "    _check(m, b, k, k_e, f_d)       # before importing python-control (~1 s): bad input is refused at once\n"
      "    import control as ct\n", "    import control as ct\n    _check(m, b, k, k_e, f_d)\n",
      "tests/test_stability.py", "a typo in analyze's input waits for python-control's 1 s import before its error"),
    M("stability-margin-sign", "stability/sampled.py",
      "margin = np.log10(limits[None, :] / np.asarray(k_e_grid, float)[:, None])",
      "margin = np.log10(np.asarray(k_e_grid, float)[:, None] / limits[None, :])", "tests/test_stability.py",
      "the stability chart colours the unstable side as the stable margin"),
    M("sweep-map-units", "sweep/figures.py", 'return f"{key} ({unit})" if unit else key', "return key",
      "tests/test_sweep.py", "the sweep map's axes lose their units"),
    M("law-note-filter-pole", "checks/laws.py", "if abs(rho - slow) < 1e-9 else", "if abs(rho - slow) < -1.0 else",
      "tests/test_laws.py", "the tracking check's radius reads as a stiffness margin though it is the filter pole"),
    M("report-comparison-tolerance", "report/document.py",
      '"yes" if worst <= FORCE_TOLERANCE else "no"', '"yes"', "tests/test_report.py",
      "the law comparison says a biased law (known, wrong k_e) tracks f_d within the tolerance"),
    M("report-renderer-traceback", "report/render.py", "except (ImportError, OSError) as exc:",
      "except ImportError as exc:", "tests/test_report.py",
      "a machine without Pango gets a traceback from report --format pdf instead of one line, exit 2"),
    # -- issue 27.17 and 28.3: verdicts, first contact, laws ---------------------------------
    M("metrics-ripple-band-doubled", "simulation/metrics.py", "band = RIPPLE_BAND * f_d + noise",
      "band = 2 * RIPPLE_BAND * f_d + noise", "tests/test_verdicts_wave3.py", "the settled-ripple band is twice the documented 1 % of f_d"),
    M("metrics-band-ignores-noise", "simulation/metrics.py", "band = RIPPLE_BAND * f_d + noise",
      "band = RIPPLE_BAND * f_d", "tests/test_verdicts_wave3.py", "sensor noise alone is called a limit cycle"),
    M("metrics-tolerance-ignores-noise", "simulation/metrics.py", "tol = sc.controller.force_tolerance + noise",
      "tol = sc.controller.force_tolerance", "tests/test_verdicts_wave3.py", "sensor noise alone makes a tracking run off target"),
    M("metrics-bounces-samples", "simulation/metrics.py", "int(np.count_nonzero(w[:-1] & ~w[1:]))",
      "int(np.count_nonzero(~w))", "tests/test_verdicts_wave3.py", "first-contact bounces count samples out of contact, not losses of contact"),
    M("metrics-first-contact-window", "simulation/metrics.py",
      "end = min(segments(result)[0][1], i0 + int(round(window / result.Ts)) + 1)",
      "end = i0 + int(round(window / result.Ts)) + 1", "tests/test_verdicts_wave3.py",
      "the first-contact window runs into the next segment (a switch's peak counted as the contact's)"),
    M("metrics-inside-never-settles", "simulation/metrics.py",
      "    if outside.size == 0:\n        return 0.0", "    if outside.size == 0:\n        return float(\"nan\")",
      "tests/test_verdicts_wave3.py", "a response always inside the band is reported as never settling"),
    M("metrics-knots-per-period", "simulation/metrics.py", "if idx.size <= MAX_KNOT_SEGMENTS:", "if idx.size < 0:",
      "tests/test_verdicts_wave3.py", "a piecewise-linear or table profile is cut per path period instead of at its steps"),
    M("metrics-stiffness-first-sample", "simulation/metrics.py", "stiffness=float(np.mean(result.stiffness[i0:i1]))",
      "stiffness=float(result.stiffness[i0])", "tests/test_verdicts_wave3.py", "a segment's stiffness is its first sample, not its mean"),
    M("metrics-rms-whole-segment", "simulation/metrics.py",
      "steady_rms_error=float(np.sqrt(np.mean(err[ss] ** 2)))", "steady_rms_error=float(np.sqrt(np.mean(err ** 2)))",
      "tests/test_verdicts_wave3.py", "the steady RMS error is taken over the whole segment, not its last quarter"),
    M("metrics-forced-is-limit-cycle", "simulation/metrics.py",
      "forced = P is not None and float(np.max(np.abs(e_B - e_A))) <= FORCED * a_B", "forced = False",
      "tests/test_verdicts_wave3.py", "the stable forced response to a sinusoidal stiffness is called a limit cycle"),
    M("metrics-growth-half-windows", "simulation/metrics.py",
      "P = next((p for p in periods if n >= 2 * p), None)", "P = None", "tests/test_verdicts_wave3.py",
      "growth judged on two halves of the last quarter, not whole path periods (phase read as growth)"),
    M("contact-threshold-ignores-noise", "simulation/simulator.py",
      "return threshold + CONTACT_NOISE_SIGMAS * noise_std", "return threshold + 0 * noise_std",
      "tests/test_verdicts_wave3.py", "sensor noise alone ends the guarded approach early (a hit at 2.6 f_d)"),
    M("design-intersample-correction", "stability/design.py", "A[j - 1] = Phi_j[0] - g_j[0] * (g @ Phi) / gg",
      "A[j - 1] = Phi_j[0]", "tests/test_design_wave3.py",
      "the force between samples ignores the held command (the overshoot bound misses the intersample peak)"),
    M("design-boundaries-on-the-grid", "stability/design.py",
      "b_os = bs[j_os] if j_os == 0 else _bisect(meets(resps[i], k), bs[j_os - 1], bs[j_os])", "b_os = bs[j_os]",
      "tests/test_design_wave3.py", "a feasible window narrower than the 7 % scan grid is called infeasible"),
    M("report-tolerance-not-the-scenarios", "report/document.py", "tol = sc.controller.force_tolerance",
      "tol = FORCE_TOLERANCE", "tests/test_verdicts_wave3.py",
      "the report's tracking verdict ignores the scenario's controller.force_tolerance"),
    M("integral-backward-euler", "control/laws/integral.py",
      'x_r = y["x_e_hat"] + y["f_d"] / y["k"] + p["k_i"] * s["I"]',
      'x_r = y["x_e_hat"] + y["f_d"] / y["k"] + p["k_i"] * (s["I"] + y["Ts"] * e_f)', "tests/test_verdicts_wave3.py",
      "the integral law uses the integral after its update (backward, not the documented forward Euler)"),
    M("rls-covariance-bound-dropped", "control/laws/rls.py",
      'P_new = P_new * ca.fmin(1, p["covariance_bound"] / ca.trace(P_new))', "P_new = P_new", "tests/test_verdicts_wave3.py",
      "the RLS covariance winds up without its documented trace bound"),
    M("rls-threshold-1x", "control/laws/rls.py", 'on = y["f_m"] > 2 * p["force_threshold"]',
      'on = y["f_m"] > p["force_threshold"]', "tests/test_verdicts_wave3.py",
      "the RLS update starts at 1x instead of the documented 2x force threshold"),
    # -- issue 28.7: the analysis-vs-simulation check beyond the paper (checks/loop.check_extensions) ----------
    M("check-delay-order", "simulation/closedloop.py", "tau, tau_wait = queue[:3], queue[3:]",
      "tau, tau_wait = queue[-3:], queue[:-3]", "tests/test_limits.py",
      "the delay buffer is read in the wrong order (the newest torque applied: limit +72 % at 2 samples)"),
    M("check-filter-gain", "simulation/closedloop.py",
      'f_m = P["alpha"] * S["f_filt"] + (1 - P["alpha"]) * f_sensor',
      'f_m = P["alpha"] * S["f_filt"] + f_sensor', "tests/test_limits.py",
      "the force filter's input gain is 1, not 1 - alpha (a DC gain of 1/(1 - alpha))"),
    M("check-kd-default", "simulation/scenario.py", "kd = self.kd or tuple(b / m for b, m in zip(self.b, self.m))",
      "kd = self.kd or tuple(b for b, m in zip(self.b, self.m))", "tests/test_limits.py",
      "the default K_D is B, not B/M (eq. 9; invisible at m = 1)"),
    M("check-true-force-feedforward", "simulation/closedloop.py", "F_e = ca.vertcat(f_m, 0, 0)",
      "F_e = ca.vertcat(f_sensor, 0, 0)", "tests/test_limits.py",
      "eq. (5) feeds forward the raw contact force (the true one without noise), not the measured (filtered) one"),
    M("check-damping-ratio", "stability/continuous.py", "return 2.0 * math.sqrt(m * (k + k_e))",
      "return 2.0 * math.sqrt(k + k_e)", "tests/test_limits.py tests/test_stability.py",
      "eq. (25)'s critical damping (and the damping ratio) without the mass (invisible at m = 1)"),
    M("check-schedule-mass", "simulation/closedloop.py", '2 * P["zeta"] * ca.sqrt(m * (k + k_hat))',
      '2 * P["zeta"] * ca.sqrt(k + k_hat)', "tests/test_limits.py",
      "the scheduled damping of eq. (25) drops the impedance mass (invisible at m = 1)"),
    # -- issue 33: stability survivors ------------------------------------------------------------
    M("analyze-scenario-drops-x-e-error", "stability/analysis.py", '"x_e_error": sc.controller.x_e_error}',
      '"x_e_error": 0.0}', "tests/test_limits.py", "analyze --scenario ignores the scenario's x_e error"),
    M("analyze-worst-force-largest", "stability/analysis.py",
      "worst = max((lw.steady_force(params, f_d, k, ke, x_e_error) for ke in (lo, hi)),\n"
      "                    key=lambda f: abs(f - f_d))",
      "worst = max((lw.steady_force(params, f_d, k, ke, x_e_error) for ke in (lo, hi)))", "tests/test_limits.py",
      "the worst steady force under an x_e error is the largest, not the farthest from f_d"),
    M("lawloop-kd-default-b", "stability/lawloop.py", "kd = b / m if kd is None else kd",
      "kd = b if kd is None else kd", "tests/test_limits.py", "the law loop's default K_D is B, not B/M (eq. 9)"),
    M("margin-nepers", "stability/sampled.py",
      "margin = np.log10(limits[None, :] / np.asarray(k_e_grid, float)[:, None])",
      "margin = np.log(limits[None, :] / np.asarray(k_e_grid, float)[:, None])", "tests/test_limits.py",
      "the stiffness margin in nepers where the docs say decades"),
]


def _copy_checkout(dest: pathlib.Path) -> None:
    files = subprocess.run(["git", "ls-files", "-z"], cwd=ROOT, capture_output=True, check=True).stdout
    for name in filter(None, files.decode().split("\0")):
        src = ROOT / name
        if src.is_file():
            (dest / name).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(src, dest / name)


def _apply(m: Mutation, root: pathlib.Path) -> str:
    """Apply ``m`` under ``root``; returns the original text."""
    path = root / m.file
    text = path.read_text()
    n = text.count(m.old)
    if n != 1:
        raise SystemExit(f"mutation {m.id}: its text occurs {n} times in {m.file} (expected once)")
    path.write_text(text.replace(m.old, m.new))
    return text


def _pytest(root: pathlib.Path, tests, env, timeout) -> tuple[int, str, float]:
    t0 = time.perf_counter()
    try:
        p = subprocess.run([sys.executable, "-m", "pytest", "-x", "-q", "-p", "no:cacheprovider",
                            "-n", "2", "--dist", "loadfile", *tests], cwd=root, env=env,
                           capture_output=True, text=True, timeout=timeout)
        code, out = p.returncode, p.stdout + p.stderr
    except subprocess.TimeoutExpired:
        code, out = -1, "timeout"
    return code, out, time.perf_counter() - t0


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--only", nargs="+", metavar="ID", help="run these mutations only")
    ap.add_argument("--list", action="store_true", help="list the mutations and exit")
    ap.add_argument("--check", action="store_true", help="check that every mutation applies, run nothing")
    ap.add_argument("--json", type=pathlib.Path, help="also write the results as JSON")
    ap.add_argument("--timeout", type=float, default=900, help="per mutation, s (a timeout counts as killed)")
    a = ap.parse_args(argv)
    chosen = MUTATIONS
    if a.only:
        unknown = sorted(set(a.only) - {m.id for m in MUTATIONS})
        if unknown:
            print(f"--only: unknown mutation id(s) {', '.join(unknown)}", file=sys.stderr)
            return 2
        chosen = [m for m in MUTATIONS if m.id in a.only]
    if a.list:
        for m in chosen:
            print(f"{m.id:32} {m.file:40} {' '.join(m.tests)}")
        return 0
    ids = [m.id for m in MUTATIONS]
    assert len(set(ids)) == len(ids), "duplicate mutation ids"
    with tempfile.TemporaryDirectory(prefix="tmt-mutants-") as tmp:
        root = pathlib.Path(tmp) / "checkout"
        _copy_checkout(root)
        for m in chosen:                                   # every mutation must apply (and be undone)
            (root / m.file).write_text(_apply(m, root))
        if a.check:
            print(f"{len(chosen)} mutations apply to {len({m.file for m in chosen})} files")
            return 0
        env = dict(os.environ, PYTHONPATH=str(root), MPLBACKEND="Agg", PYTHONDONTWRITEBYTECODE="1")
        where = subprocess.run([sys.executable, "-c", "import tmtcontrol; print(tmtcontrol.__file__)"],
                               cwd=root, env=env, capture_output=True, text=True).stdout.strip()
        if not where.startswith(str(root)):
            print(f"the scratch copy is not the one imported ({where}); is tmtcontrol installed non-editable "
                  "with a path that wins over PYTHONPATH?", file=sys.stderr)
            return 1
        # the unmutated tests must pass, or a "kill" means nothing
        base = sorted({t for m in chosen for t in m.tests})
        code, out, dt = _pytest(root, base, env, a.timeout * 2)
        if code != 0:
            print(out[-3000:])
            print(f"the unmutated tests fail (exit {code}); fix them first", file=sys.stderr)
            return 1
        print(f"baseline: {len(base)} test files pass unmutated ({dt:.0f} s)")
        results = []
        for i, m in enumerate(chosen, 1):
            original = _apply(m, root)
            try:
                code, out, dt = _pytest(root, m.tests, env, a.timeout)
            finally:
                (root / m.file).write_text(original)
            killed = code != 0
            failing = [ln.split(" ", 1)[1].split(" - ")[0] for ln in out.splitlines() if ln.startswith("FAILED ")]
            results.append({"id": m.id, "file": m.file, "killed": killed, "exit": code, "seconds": round(dt, 1),
                            "killed_by": failing[:3], "why": m.why})
            print(f"[{i:>2}/{len(chosen)}] {m.id:32} {'killed' if killed else 'SURVIVED':8} {dt:6.1f} s"
                  + (f"  by {failing[0]}" if failing else ""), flush=True)
    killed = sum(r["killed"] for r in results)
    print(f"\nmutation score: {killed}/{len(results)} killed ({100 * killed / len(results):.0f} %)")
    for r in results:
        if not r["killed"]:
            print(f"  survived: {r['id']} ({r['file']}): {r['why']}")
    if a.json:
        a.json.write_text(json.dumps({"killed": killed, "total": len(results), "mutations": results}, indent=1))
    return 0 if killed == len(results) else 1


if __name__ == "__main__":
    sys.exit(main())
