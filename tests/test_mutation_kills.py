"""Tests that kill the survivors of the Cosmic Ray mutation run (benchmarks/mutation_tool.py,
docs/testing.md): each names the mutant it kills and the case that tells the bug apart.
Synthetic inputs with hand-computed answers; no simulation."""
import errno
import os
from types import SimpleNamespace

import numpy as np
import pytest

from tmtcontrol import paper_scenario
from tmtcontrol.files import OutputFolder, OutputNotSaved
from tmtcontrol.simulation.metrics import segment_metrics, settling_time


# -- simulation/metrics.py ---------------------------------------------------------------------

def test_settling_time_counts_from_a_segment_start_later_than_the_settling():
    """metrics.py:core/ReplaceBinaryOperator_Sub_Mod:3 (t[last + 1] % t[0]): a segment starting at
    t = 1 s that settles 1.5 s later; the modulo gives 2.5 % 1 = 0.5 s (it agrees only while the
    settling is shorter than the start time, as in the first seconds of the paper's run)."""
    t = 1.0 + 0.5 * np.arange(10)
    err = np.array([5.0, -4.0, 3.0, 0.5, 0.2, 0.0, 0.1, 0.0, 0.0, 0.0])
    assert settling_time(err, 1.0, t) == pytest.approx(1.5, abs=1e-12)    # leaves the band for good at t[3]


def _one_segment(force):
    """A result of the paper scenario's kind holding one segment (constant stiffness) with the
    contact force ``force`` sampled every 1 ms, the tool on its reference."""
    sc = paper_scenario()
    n = force.size
    return SimpleNamespace(scenario=sc, Ts=1e-3, time=1e-3 * np.arange(n), contact_force=force,
                           force_error=force - sc.controller.f_d, stiffness=np.full(n, 5000.0),
                           position_task=np.zeros((3, n)), reference_task=np.zeros((3, n)))


def test_overshoot_of_an_approach_from_below_is_its_peak_over_f_d():
    """metrics.py:core/NumberReplacer:142 (f[1] > f_d picks the direction) and
    core/ReplaceBinaryOperator_Mul_Pow:13 (overshoot / f_d ** 100): the force starts at 0 (below
    f_d = 10 N), jumps to 12 N at the second sample and settles at 10 N; the overshoot is
    (12 - 10) / 10 = 20 %.  Judged by f[1] = 12 N > f_d the segment would count as starting above
    f_d and report no overshoot."""
    f = np.r_[0.0, 12.0, np.linspace(12.0, 10.0, 50), np.full(2000, 10.0)]
    (seg,) = segment_metrics(_one_segment(f))
    assert seg.overshoot_pct == pytest.approx(20.0, abs=1e-9)


def test_overshoot_of_a_segment_starting_above_f_d_is_its_dip_under_f_d():
    """The other direction of the same line: starting at 14 N, dipping to 9 N, settling at 10 N:
    the overshoot is (10 - 9) / 10 = 10 %."""
    f = np.r_[14.0, np.linspace(14.0, 9.0, 40), np.linspace(9.0, 10.0, 40), np.full(2000, 10.0)]
    (seg,) = segment_metrics(_one_segment(f))
    assert seg.overshoot_pct == pytest.approx(10.0, abs=1e-9)



# -- simulation/metrics.py (fourth run, seed 3) -----------------------------------------------------

@pytest.mark.parametrize("force,overshoot", [(12.0, 0.0), (8.0, 0.0)])
def test_a_segment_of_one_sample_is_measured_not_a_crash(force, overshoot):
    """metrics.py:core/ReplaceComparisonOperator_Gt_GtE:15 (`f.size >= 1`): a segment of a single
    sample (a stiffness change at a run's last sample) has no sample after its first, so its
    overshoot is taken over that sample (0 %), not over an empty array (a ValueError); it is
    judged by the tolerance alone, off target at 2 N from f_d = 10 N."""
    (seg,) = segment_metrics(_one_segment(np.array([force])))
    assert seg.overshoot_pct == overshoot
    assert seg.verdict == "off_target" and seg.steady_state_error == pytest.approx(2.0, abs=1e-12)


def test_knots_at_the_start_and_past_the_end_of_a_run_make_no_segment():
    """metrics.py:core/ReplaceBinaryOperator_BitAnd_BitOr:0 (`(idx > 0) | (idx < n)`): a 2 s run at
    1 kHz whose piecewise-linear stiffness has knots at 0, 1 and 5 s (the last one after the run)
    has two segments, [0, 1000) and [1000, 2000); the knot after the run neither opens a segment
    nor stretches the last one past the run's 2000 samples."""
    from tmtcontrol.simulation.metrics import segments
    from tmtcontrol.simulation.scenario import PiecewiseLinearStiffness

    profile = PiecewiseLinearStiffness(times=(0.0, 1.0, 5.0), values=(2e3, 1e4, 1e4))
    run = SimpleNamespace(scenario=SimpleNamespace(environment=SimpleNamespace(stiffness=profile)), Ts=1e-3,
                          stiffness=np.interp(1e-3 * np.arange(2000), profile.times, profile.values))
    assert segments(run) == [(0, 1000), (1000, 2000)]


def test_the_common_period_of_path_and_stiffness_is_tried_first():
    """metrics.py:core/NumberReplacer:73 (`per.insert(-1, lcm)`): a sinusoidal stiffness of
    0.3 s on a 0.2 s circle at 1 kHz: the verdict tries their common period 0.6 s first, then
    the stiffness' and the path's (600, 300, 200 samples), not (300, 600, 200)."""
    sc = SimpleNamespace(environment=SimpleNamespace(stiffness=SimpleNamespace(kind="sinusoidal", period=0.3)),
                         trajectory=SimpleNamespace(radius=0.1, period=0.2))
    from tmtcontrol.simulation.metrics import judging_periods

    assert judging_periods(SimpleNamespace(scenario=sc, Ts=1e-3)) == (600, 300, 200)


def test_the_correlation_time_of_an_ar1_process_is_its_closed_form():
    """metrics.py:core/ReplaceBinaryOperator_Mul_Pow:2 (`f ** conj(f)` in the autocorrelation):
    an AR(1) process x_k = phi x_(k-1) + w_k has integrated autocorrelation time
    (1 + phi) / (1 - phi) = 3 at phi = 0.5; 200,000 samples (seed 1) give it within 6 % (three
    standard errors of Sokal's windowed estimate, sqrt(2 (2M + 1) / n) tau with M ~ 15), and white
    noise gives 1."""
    from scipy.signal import lfilter

    from tmtcontrol.simulation.metrics import correlation_time

    w = np.random.default_rng(1).standard_normal(200_000)
    assert correlation_time(lfilter([1.0], [1.0, -0.5], w)) == pytest.approx(3.0, rel=0.06)
    assert correlation_time(w) == pytest.approx(1.0, abs=0.05)


def test_a_periodic_response_that_repeats_within_a_fifth_of_its_swing_is_forced_not_a_limit_cycle():
    """metrics.py:core/ReplaceBinaryOperator_Mul_Div:13 (`FORCED / a_B`): a 4.1 N peak-to-peak
    response at the forcing period (100 samples) plus a slower 0.25 N one, so two consecutive
    windows differ by 0.16 N, within 0.2 x 4.1 N: the forced response (off target, stable), not
    a limit cycle (0.2 / 4.1 = 0.05 N would call it one)."""
    from tmtcontrol.simulation.metrics import judge_segment

    k = np.arange(4000)
    e = 2.0 * np.sin(2 * np.pi * k / 100) + 0.125 * np.sin(2 * np.pi * k / 310)
    verdict, why = judge_segment(10.0 + e, 10.0, 0.5, 0.3, periods=(100,), Ts=1e-3)
    assert verdict == "off_target" and "periodic forced response" in why



# -- control/laws (fourth run, seed 3) --------------------------------------------------------------

@pytest.mark.parametrize("change", ["missing", "extra", "renamed"])
def test_a_law_whose_next_state_is_not_its_declared_state_is_refused_by_name(change):
    """laws/base.py:core/ReplaceComparisonOperator_NotEq_Gt:1 (`set(nxt) > set(states)`): a law
    declaring states (x_a, dx_a) whose update returns s_next without dx_a, with one more entry,
    or with dx_a renamed, is refused when its Function is built, naming the law and the states
    (the mutant let the missing and renamed ones through to a KeyError)."""
    from tmtcontrol.control.laws import TMT

    def update(y, p, s):
        out = TMT.update(y, p, s)
        nxt = dict(out["s_next"])
        if change == "missing":
            del nxt["dx_a"]
        elif change == "extra":
            nxt["z"] = nxt["x_a"]
        else:
            nxt["v_a"] = nxt.pop("dx_a")
        return {**out, "s_next": nxt}

    with pytest.raises(ValueError, match=r"^law 'tmt': s_next must give exactly the states \('x_a', 'dx_a'\)$"):
        TMT.replace(update=update).function()


# -- files.py ----------------------------------------------------------------------------------

def test_full_disk_elsewhere_names_the_current_folder_for_a_bare_file_name(tmp_path):
    """files.py:core/ReplaceOrWithAnd:15 (dirname(name) and '.'): the disk that filled holds a file
    named without a folder (a path relative to the current folder), outside the output; the
    message names '.' as the full disk, not an empty name."""
    with pytest.raises(OutputNotSaved) as info:
        with OutputFolder(tmp_path / "o"):
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), "scratch.bin")
    assert f"{tmp_path / 'o'} (. is full)" in str(info.value)
    with pytest.raises(OutputNotSaved) as info:
        with OutputFolder(tmp_path / "p"):
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), "/elsewhere/scratch.bin")
    assert f"{tmp_path / 'p'} (/elsewhere is full)" in str(info.value)


# -- simulation/scenario.py --------------------------------------------------------------------

def test_applicable_settings_keep_the_unconditional_keys_with_their_units():
    """scenario.py:core/ReplaceTrueWithFalse in _applies (every key without a rule of its own
    dropped from the report's settings table) and core/ReplaceComparisonOperator_Eq_Lt on
    ``unit == "–"`` (the en dash sorts after ASCII, so ``unit < "–"`` blanks every unit): the
    paper scenario's f_d is 10 N and its stiffness values are in N/m, as in the paper's Table 1."""
    from tmtcontrol.simulation.scenario import applicable_settings

    rows = {r.key: r for r in applicable_settings(paper_scenario())}
    assert (rows["controller.f_d"].value, rows["controller.f_d"].unit) == (10.0, "N")
    assert rows["environment.stiffness.values"].unit == "N/m"
    assert rows["impedance.b"].unit == "N s/m" and rows["controller.rate"].unit == "Hz"


def test_override_of_an_unset_optional_key_is_accepted_and_an_unknown_key_refused():
    """scenario.py:core/ReplaceComparisonOperator_Is_IsNot in _set_dotted (``known is not None or
    ...``): impedance.kd is unset by default (B/M), so it is absent from the scenario's dict; the
    schema knows it, so ``--set impedance.kd=[...]`` must be accepted, while a key the schema does
    not know is still refused in one line naming it."""
    from tmtcontrol import apply_overrides
    from tmtcontrol.simulation.scenario import ScenarioError

    assert apply_overrides(paper_scenario(), ["impedance.kd=[30,20,20]"]).impedance.kd == (30.0, 20.0, 20.0)
    with pytest.raises(ScenarioError, match=r"^impedance\.nonsense: unknown key"):
        apply_overrides(paper_scenario(), ["impedance.nonsense=1"])


# -- sweep/spec.py -----------------------------------------------------------------------------

def test_random_draws_follow_the_documented_recipe_across_blocks():
    """spec.py:core/NumberReplacer on DRAW_BLOCK = 1024 (1025): the manifest documents the draws as
    PCG64([seed, block]) in blocks of 1024, each axis's 1024 values in turn; recomputed here with
    NumPy alone for two axes (the second axis's values shift with the block size) in the first and
    the second block."""
    from tmtcontrol.sweep.spec import Cases

    cases = Cases({}, {"a": {"uniform": [0.0, 1.0]}, "b": {"uniform": [2.0, 3.0]}}, samples=2000, seed=7)
    for sample in (3, 1500):
        block, k = divmod(sample, 1024)
        rng = np.random.default_rng([7, block])
        a, b = rng.uniform(0.0, 1.0, 1024), rng.uniform(2.0, 3.0, 1024)
        assert cases.draw(sample) == {"a": a[k], "b": b[k]}


def test_a_normal_of_zero_spread_is_accepted_at_its_mean_and_refused_outside_its_bounds():
    """spec.py:core/AddNot in _normal_mass (std = 0: mass 1 inside the bounds, 0 outside, negated):
    normal(5, 0) puts all its mass at 5, so it is a valid axis unless the bounds exclude 5."""
    from tmtcontrol.sweep.spec import SweepError, _check_random

    assert _check_random("x", {"normal": [5.0, 0.0]}) == {"normal": [5.0, 0.0]}
    assert _check_random("x", {"normal": [5.0, 0.0], "bounds": [4.0, 6.0]})
    with pytest.raises(SweepError, match=r"^random\.x: bounds \[6, 7\] too far in the tail"):
        _check_random("x", {"normal": [5.0, 0.0], "bounds": [6.0, 7.0]})


# -- model/urdf.py -----------------------------------------------------------------------------

_PENDULUM_WITH_TOOL = """<robot name="pendulum">
  <link name="base"/>
  <link name="arm"><inertial><origin xyz="0 0 -0.3"/><mass value="2"/>
    <inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <link name="tool"><inertial><mass value="1"/>
    <inertia ixx="5" iyy="5" izz="{izz}" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <joint name="hinge" type="revolute"><parent link="base"/><child link="arm"/><axis xyz="0 1 0"/>
    <limit lower="-3" upper="3" effort="10" velocity="2"/></joint>
  <joint name="flange" type="fixed"><parent link="arm"/><child link="tool"/><origin xyz="0 0 -0.5"/></joint>
</robot>"""


def test_fixed_link_inertia_within_rounding_of_semi_definite_is_accepted(tmp_path):
    """urdf.py:core/ReplaceBinaryOperator_Mul_Pow on ``-1e-12 * max(1, |eig|)`` (``-1e-12 ** max``,
    a tolerance of about -1e-60): a fixed tool link whose inertia diag(5, 5, -1e-13) kg m^2 is
    semi-definite up to rounding (1e-13 is below 1e-12 x 5) is accepted; diag(5, 5, -1e-6) is not."""
    from tmtcontrol import URDFError, load_robot

    ok = tmp_path / "ok.urdf"
    ok.write_text(_PENDULUM_WITH_TOOL.format(izz="-1e-13"))
    assert load_robot(ok).n == 1
    bad = tmp_path / "bad.urdf"
    bad.write_text(_PENDULUM_WITH_TOOL.format(izz="-1e-6"))
    with pytest.raises(URDFError, match="link 'tool': inertia is not positive semi-definite"):
        load_robot(bad)


# -- export/sil.py -----------------------------------------------------------------------------

def test_measured_force_vector_has_the_contact_force_as_its_length(paper_result):
    """sil.py:core/ReplaceBinaryOperator_Mul_FloorDiv in measurement_table (``-normal // f``): the
    force the exported controller reads is the contact force along the surface normal (the
    paper's run has no sensor noise), so its length is |f_e| (1e-9 N: float rounding of a
    unit normal) and, the surface tilted about y, its y component is 0."""
    from tmtcontrol.export.sil import measurement_table

    rows, names = measurement_table(paper_result)
    force = rows[:, [names.index(c) for c in ("force_x", "force_y", "force_z")]]
    assert np.allclose(np.linalg.norm(force, axis=1), np.abs(paper_result.contact_force), rtol=0, atol=1e-9)
    assert np.all(force[:, 1] == 0.0) and np.abs(force).max() > 5.0


# -- stability/analysis.py ---------------------------------------------------------------------

def test_the_closed_form_sampled_model_is_used_only_without_delay_or_x_e_error():
    """analysis.py:core/NumberReplacer in closed_form_applies (``delay == 1``): the 1-D closed
    form (stability.sampled) has no delay states, so a loop with a one-sample delay must go to
    the law's own loop, and the undelayed TMT or known-law loop may use the closed form."""
    from tmtcontrol.stability.analysis import closed_form_applies

    assert closed_form_applies("tmt", 0, 0.0) and closed_form_applies("known", 0, 0.0)
    assert not closed_form_applies("tmt", 1, 0.0)
    assert not closed_form_applies("tmt", 0, 1e-3)
    assert not closed_form_applies("integral", 0, 0.0)


# -- stability/sampled.py: stable_band (third run, seed 3) ------------------------------------------

def _edge_from_below(stable, unstable_k, stable_k, rtol=1e-6):
    """The lower edge of a band written out: bisection in log k_e between an unstable stiffness
    and a stable one above it, to rtol; the last stable stiffness found."""
    lo, hi = float(unstable_k), float(stable_k)
    while hi / lo > 1 + rtol:
        mid = np.sqrt(lo * hi)
        lo, hi = (lo, mid) if stable(mid) else (mid, hi)
    return hi


def test_the_band_below_a_scenario_in_a_gap_keeps_its_own_lower_edge():
    """sampled.py:core/ReplaceBinaryOperator_Sub_Add:12 (lower_edge(j + 1, ...) for the band
    below the scenario): a loop stable on [20, 100] and [1e3, 1e5] N/m, the scenario at 300 N/m in
    the gap; the band reported below it is [20, 100], not [100, 100] (the mutant searches the
    lower edge upward from the band's top and finds its upper edge)."""
    from tmtcontrol.stability.sampled import stable_band

    two = lambda ke: 20.0 <= ke <= 100.0 or 1e3 <= ke <= 1e5
    gap = stable_band(two, within=300.0)
    assert gap.lower == pytest.approx(20.0, rel=2e-6) and gap.upper == pytest.approx(100.0, rel=2e-6)
    assert gap.unstable_below


def test_the_band_above_a_scenario_below_every_band_is_bisected_from_its_grid_step():
    """sampled.py:core/ReplaceBinaryOperator_Sub_Mod:13 (the bracket grid[j % 1], the scan's
    start, for grid[j - 1]): a loop stable on [25, 100] N/m, the scenario at 12 N/m below it; the
    band's lower edge is bisected between the grid points around 25 N/m (21.54 and 31.62 on the
    49-point grid from 10 N/m), exactly as the written-out bisection gives it, not from 10 N/m
    (the same edge to rtol but another float, 25.0000178 against 25.0000086, after more
    stability evaluations)."""
    from tmtcontrol.stability.sampled import stable_band

    band = lambda ke: 25.0 <= ke <= 100.0
    grid = np.geomspace(10.0, 1e9, 49)
    assert grid[2] < 25.0 < grid[3]
    below = stable_band(band, within=12.0)
    assert below.limit == 0.0 and below.upper == pytest.approx(100.0, rel=2e-6)
    assert below.lower == _edge_from_below(band, grid[2], grid[3])
    assert below.lower != _edge_from_below(band, grid[0], grid[3])      # the two brackets are told apart


# -- sweep/spec.py (third run, seed 3) -------------------------------------------------------------

@pytest.mark.parametrize("sec,when", [(119.4, "about 119 s"), (120.0, "about 2 min"), (7199.0, "about 120 min"),
                                      (7200.0, "about 2.0 h")])
def test_the_plan_line_changes_unit_at_two_minutes_and_two_hours(monkeypatch, sec, when):
    """spec.py:core/NumberReplacer:30 (`sec < 121`): an estimate of exactly 120 s is printed as
    2 min, as every estimate from 2 minutes on (and from 2 hours on in hours)."""
    import tomllib

    from tmtcontrol.sweep import EXAMPLE, sweep_from_dict

    sweep = sweep_from_dict(tomllib.loads(EXAMPLE))
    monkeypatch.setattr(type(sweep), "estimate_seconds", lambda self, cases=None, workers=1, limits=False: sec)
    assert f"; {when} on 1 worker (estimate)" in sweep.plan()


# -- stability/lawloop.py (third run, seed 3) --------------------------------------------------------

def _tmt_law_loop(delay):
    from tmtcontrol.control.laws import get_law
    from tmtcontrol.stability.lawloop import law_loop

    return law_loop(get_law("tmt"), m=1.0, b=40.0, k=100.0, k_e=5000.0, Ts=1e-3, m_p=3.5, delay=delay)


def test_a_delayed_law_loop_names_each_state_once_oldest_sample_first():
    """lawloop.py:core/NumberReplacer:47 (range(delay, -1, -1)): with a 2-sample delay the state is
    (x, x', f_filt, the law's states, U and f held 2 and 1 samples ago); the mutant adds a pair
    "U[-0]", "f[-0]" that is not in the state, so the names no longer match its entries."""
    loop = _tmt_law_loop(2)
    law_states = loop.states[3:-4]
    assert loop.states == ("x", "dx", "f_filt", *law_states, "U[-2]", "f[-2]", "U[-1]", "f[-1]")
    assert len(loop.states) == loop.z_eq.size == loop.A.shape[0]
    assert _tmt_law_loop(0).states == ("x", "dx", "f_filt", *law_states)


def test_a_law_loop_is_a_frozen_result():
    """lawloop.py:core/ReplaceTrueWithFalse:0 (@dataclass(frozen=False)): the loop, its
    equilibrium and its stability verdict are one computed result; assigning to it raises instead
    of leaving a spectral radius that belongs to another stiffness."""
    import dataclasses

    loop = _tmt_law_loop(0)
    with pytest.raises(dataclasses.FrozenInstanceError):
        loop.k_e = 1e6


# -- model/urdf.py (third run, seed 3) --------------------------------------------------------------

def test_a_urdf_of_exactly_the_size_limit_is_read_whole(tmp_path, monkeypatch):
    """urdf.py:core/ReplaceBinaryOperator_Add_Sub:0 (fh.read(MAX_BYTES - 1)): a file of exactly
    MAX_BYTES bytes is allowed and must be read to its last byte (the mutant cuts the closing '>'
    of </robot>, a parse error on a valid file); one byte more is refused before reading."""
    import tmtcontrol.model.urdf as urdf

    text = ('<robot name="r"><link name="a"/><link name="b"><inertial><mass value="1"/><inertia ixx="1" iyy="1" '
            'izz="1" ixy="0" ixz="0" iyz="0"/></inertial></link><joint name="j" type="revolute"><parent link="a"/>'
            '<child link="b"/><axis xyz="0 0 1"/><limit lower="-1" upper="1" effort="1" velocity="1"/></joint>'
            '</robot>')
    path = tmp_path / "r.urdf"
    path.write_text(text)
    monkeypatch.setattr(urdf, "MAX_BYTES", len(text.encode()))
    assert urdf.read_urdf(path) == text
    path.write_text(text + " ")
    with pytest.raises(urdf.URDFError, match=f"larger than the {len(text)} bytes"):
        urdf.read_urdf(path)


def test_a_settling_run_that_ends_non_finite_falls_back_to_the_static_guess(monkeypatch):
    """lawloop.py:core/NumberReplacer:82 (np.isfinite(Z[-2])): the settling iteration is trusted as
    Newton's start only if its last iterate is finite; one whose last iterate overflows in a law
    state (the one before still finite, x and x' small) must not seed Newton with NaN: the loop then
    starts from the static guess (x = f_d / k_e, f = f_d) and finds the same equilibrium."""
    import tmtcontrol.stability.lawloop as lawloop

    good = _tmt_law_loop(0)
    real = lawloop._iterate

    def overflowing_last_step(step, z0, n):
        Z, F = real(step, z0, n)
        Z = Z.copy()
        Z[-1, 3:] = np.nan          # the law's states
        return Z, F

    monkeypatch.setattr(lawloop, "_iterate", overflowing_last_step)
    loop = _tmt_law_loop(0)
    assert np.all(np.isfinite(loop.z_eq)) and loop.residual < 1e-9
    assert loop.f_eq == pytest.approx(good.f_eq, rel=1e-9)
    assert loop.spectral_radius == pytest.approx(good.spectral_radius, rel=1e-9)


# -- sweep/spec.py's truncated normal ------------------------------------------------------------

def test_a_truncation_holding_exactly_the_smallest_mass_is_accepted(monkeypatch):
    """spec.py:core/ReplaceComparisonOperator_Lt_LtE:5 (`_normal_mass(out) <= 1e-9`): a normal axis
    is refused when its bounds hold less than 1e-9 of the distribution's probability; exactly 1e-9
    is accepted (the mass is set exactly through the module's own function: no float input of
    ndtr lands on 1e-9 itself)."""
    import tmtcontrol.sweep.spec as spec

    axis = {"normal": [1.0, 0.1], "bounds": [0.5, 1.5]}
    monkeypatch.setattr(spec, "_normal_mass", lambda out: 1e-9)
    assert spec._check_random("environment.stiffness.k_e", axis)["normal"] == [1.0, 0.1]
    monkeypatch.setattr(spec, "_normal_mass", lambda out: np.nextafter(1e-9, 0.0))
    with pytest.raises(spec.SweepError, match="too far in the tail"):
        spec._check_random("environment.stiffness.k_e", axis)


def test_two_axes_of_one_section_with_a_cross_field_check_are_validated_together():
    """spec.py:core/AddNot:50 (`not isinstance(ann, type)`: no section's own model validator makes
    a scope): on the UR5 (its plane given by a normal), a grid over tilt_deg = 45 and the normal of
    the 45 deg and 30 deg planes; each value alone is valid against the scenario, the pair (45 deg,
    30 deg normal) is not (the environment section's _unit_normal check), so the sweep is refused
    naming that case instead of failing it at run time."""
    import math

    from tmtcontrol.sweep import SweepError, sweep_from_dict

    s, t = math.sqrt(0.5), math.radians(30.0)
    grid = {"environment.tilt_deg": [45.0], "environment.normal": [[s, 0.0, -s], [math.sin(t), 0.0, -math.cos(t)]]}
    for key, values in grid.items():        # each value alone is accepted
        for v in values:
            assert len(sweep_from_dict({"scenario": "ur5", "grid": {key: [v]}}).cases) == 1
    with pytest.raises(SweepError, match=r"^case 1 \(environment\.tilt_deg = 45\.0, environment\.normal = .*"
                                         r"45 deg is not the plane of normal"):
        sweep_from_dict({"scenario": "ur5", "grid": grid})


# -- files.py (third run, seed 3) ---------------------------------------------------------------------

def test_proc_stat_reads_the_state_letter_and_the_start_time_of_a_process():
    """files.py:core/NumberReplacer:17 (fields[-1] for fields[0]): /proc/PID/stat after the command's
    ')' starts with the state letter (R, S, D, Z, T, ...) and holds the start time in clock ticks as
    its 20th field; for this (running) process the state is R and the start time is an integer no
    later than now (ticks since boot); a process that does not exist gives None."""
    import tmtcontrol.files as files

    state, start = files._proc_stat(os.getpid())
    assert state == "R" and start.isdigit()
    uptime = float(open("/proc/uptime").read().split()[0])
    assert int(start) <= uptime * os.sysconf("SC_CLK_TCK") + 1
    assert files._proc_stat(2 ** 22 + 12345) is None                 # no such process


def test_a_switch_to_the_same_stiffness_predicts_a_constant_force_for_any_inner_loop_gains():
    """sampled.py:core/NumberReplacer:214 (the impedance filter starts with x_a' = 1 m/s): the
    prediction starts from the old equilibrium, at rest; a "switch" to the same stiffness must then
    stay at f_d exactly. With eq. (9)'s gains (kd = b/m, kp = k/m) the filter's state cancels out of
    U and a wrong start cannot show; with kd = 60 s^-1 != b/m = 40 s^-1 it would move the force."""
    from tmtcontrol.stability.sampled import switch_response

    for kd in (None, 60.0):
        r = switch_response(1.0, 40.0, 100.0, 5000.0, 5000.0, 1e-3, 3.5, kd=kd)
        assert np.max(np.abs(r["force"] - 10.0)) < 1e-9, kd


def test_a_stiffness_sequence_with_a_computation_delay_starts_from_contact_at_rest():
    """lawloop.py:core/ReplaceBinaryOperator_Add_Mul:13 (z[3:3 * len(states)] for the law's
    states): with a one-sample delay the state also holds the delayed (U, f) pair after the law's
    states, so the mutant's slice is longer than the law's initial state (an error); without delay
    it is clipped to the same slice. The sequence starts in contact at rest (force 0 N) and settles
    to f_d = 10 N on each surface (within 5 mN after 1 s; the 4x stiffer surface starts at 40 N)."""
    from tmtcontrol.control.laws import get_law
    from tmtcontrol.stability.lawloop import stiffness_sequence

    out = stiffness_sequence(get_law("tmt"), None, [5000.0, 20000.0], 1.0, m=1.0, b=40.0, k=100.0, Ts=1e-3,
                             m_p=3.5, delay=1)
    (first, f1), (second, f2) = out
    assert first.z_eq.size == 3 + 2 + 2 and f1[0] == 0.0
    assert f2[0] == pytest.approx(40.0, rel=1e-6)          # x = f_d / 5000 pressed into a 20,000 N/m surface
    assert abs(f1[-1] - 10.0) < 5e-3 and abs(f2[-1] - 10.0) < 5e-3


@pytest.mark.parametrize("mean,std,lo,hi", [(0.0, 1.0, -1.0, 1.0), (1.0, 0.1, 1.2, 1.5), (1.0, 0.1, -100.0, 0.5)])
def test_the_mass_of_a_truncated_normal_is_the_closed_form(mean, std, lo, hi):
    """spec.py:core/ReplaceBinaryOperator_Sub_FloorDiv:5 (ndtr(b) // ndtr(a) on the branch with the
    lower bound at or below the mean): the probability of [lo, hi] under normal(mean, std) is
    (erf(b / sqrt 2) - erf(a / sqrt 2)) / 2 with a, b the standardised bounds, on both branches (the
    lower bound above the mean, computed from the upper tail); a lower bound 1,010 sigma out (ndtr 0)
    gives the tail mass 2.9e-7, accepted, not a division by zero. Tolerance 1e-12 relative:
    ndtr and erf agree to rounding away from the far tail."""
    import math

    import tmtcontrol.sweep.spec as spec

    a, b = (lo - mean) / std, (hi - mean) / std
    expected = (math.erf(b / math.sqrt(2)) - math.erf(a / math.sqrt(2))) / 2
    if a > 0:                                   # both bounds in the upper tail: the complementary form is exact
        expected = (math.erfc(a / math.sqrt(2)) - math.erfc(b / math.sqrt(2))) / 2
    got = spec._normal_mass({"normal": [mean, std], "bounds": [lo, hi]})
    assert got == pytest.approx(expected, rel=1e-12)
    assert spec._check_random("environment.stiffness.k_e", {"normal": [mean, std], "bounds": [lo, hi]})


@pytest.mark.parametrize("bad", [0, -5, 2.5, True])
def test_a_case_limit_that_is_not_a_positive_integer_is_refused_as_such(bad):
    """spec.py:core/ReplaceComparisonOperator_IsNot_Is:0 (`max_cases is None and ...`): a limit
    of 0 or -5 cases, or 2.5, is refused naming --max-cases and what it must be, not compared
    with the sweep's size (0 would read "more than the limit of 0", 2.5 would pass a 2-case sweep;
    True, a bool and so an int to Python, would be a limit of 1)."""
    import tomllib

    from tmtcontrol.sweep import EXAMPLE, SweepError, sweep_from_dict

    with pytest.raises(SweepError, match=r"^--max-cases: must be an integer >= 1, got "):
        sweep_from_dict(tomllib.loads(EXAMPLE), max_cases=bad)



# -- stability/analysis.py (third run, seed 3) ------------------------------------------------------

@pytest.mark.parametrize("limit,attached", [(0.5, True), (2e4, True), (0.0, 0.0), (-3.0, 0.0),
                                            (float("inf"), False), (float("nan"), False), (None, False)])
def test_any_positive_finite_stiffness_limit_is_attached_to_a_run(monkeypatch, limit, attached):
    """analysis.py:core/NumberReplacer:28 (`limit <= 1`) and ReplaceComparisonOperator_LtE_NotEq:1
    (`limit != 0`): with_stiffness_limit attaches every positive finite limit, however small
    (0.5 N/m); a 1-D figure of 0 or below (unstable at the smallest stiffness) is the limit 0,
    as deciding_limit says (every segment beyond it); no figure, or an infinite one without a
    surface error, leaves the run unchanged."""
    import dataclasses

    import numpy as np

    from tmtcontrol.simulation.scenario import paper_scenario
    from tmtcontrol.stability import limit as limit_module, onedim

    monkeypatch.setattr(onedim, "scenario_stiffness_limit", lambda scenario: limit)
    # a run whose stiffness stays at or below the limit: the 1-D figure itself is attached
    run = dataclasses.make_dataclass("Run", ["scenario", "info", "stiffness"], frozen=True)(
        paper_scenario(), {"kept": 1}, np.zeros(3))
    out = limit_module.with_stiffness_limit(run)
    if attached is True:
        assert out.info == {"kept": 1, "stiffness_limit": limit, "stiffness_limit_from": "1-D small-signal"}
    elif attached is False:
        assert out.info == {"kept": 1}
    else:
        assert out.info == {"kept": 1, "stiffness_limit": 0.0,
                            "stiffness_limit_from": "unstable at the smallest stiffness"}


def test_the_x_e_error_force_is_reported_only_for_an_error_and_a_law_that_states_one():
    """analysis.py:core/ReplaceAndWithOr:4 (`x_e_error != 0.0 or lw.steady_force is not None`):
    without an x_e error no x_e keys are reported, and a law that states no steady-force formula
    (TMT with it removed, as a user's law may be) is analysed without them; the known-stiffness
    law with an error reports eq. (12)'s f_d + k_eff delta when its assumed stiffness is the
    surface's (here 5e3 N/m, its default)."""
    import dataclasses

    from tmtcontrol.control.laws import TMT, register_law
    from tmtcontrol.stability.analysis import analyze

    base = dict(m=1.0, b=60.0, k=100.0, f_d=10.0, k_e=5e3)
    assert "steady_state_force_x_e_error" not in analyze(**base, law="known")
    assert "x_e_error" not in analyze(**base, law="known")
    register_law(dataclasses.replace(TMT, steady_force=None), replace=True)
    try:
        assert "steady_state_force_x_e_error" not in analyze(**base, law="tmt", x_e_error=1e-3)
    finally:
        register_law(TMT, replace=True)
    got = analyze(**base, law="known", x_e_error=1e-3)["steady_state_force_x_e_error"]
    assert got == pytest.approx(10.0 + 100.0 * 5e3 / (100.0 + 5e3) * 1e-3, rel=1e-12)


@pytest.mark.parametrize("band_top,rho,stable", [(1.5e4, 0.5, False), (1e6, 1.2, False), (1e6, 0.5, True)])
def test_the_sampled_verdict_needs_every_grid_point_stable_and_the_range_inside_the_band(monkeypatch, band_top,
                                                                                         rho, stable):
    """analysis.py:core/ReplaceAndWithOr:5 (`rho < 1.0 or hi < limit`): a range 2e3..2e4 N/m whose
    grid points all have spectral radius 0.5 while the stable band ends at 1.5e4 N/m (an unstable
    gap between grid points) is not stable, nor is one inside the band with a grid point at
    radius 1.2; only both together are. The two sampled-model functions are stubbed: what is
    tested is how the verdict combines them."""
    from tmtcontrol.stability import analysis
    from tmtcontrol.stability.sampled import stable_band

    monkeypatch.setattr(analysis, "stiffness_band",
                        lambda *a, within, **kw: stable_band(lambda ke: ke <= band_top, within=within))
    monkeypatch.setattr(analysis, "spectral_radius", lambda *a, **kw: rho)
    out = analysis.analyze(m=1.0, b=60.0, k=100.0, k_e_min=2e3, k_e_max=2e4, Ts=1e-3, m_p=3.3)
    assert out["spectral_radius"] == rho
    assert out["max_stable_stiffness"] == pytest.approx(band_top, rel=1e-5)
    assert out["sampled_stable"] is stable


@pytest.fixture
def frozen_limits(monkeypatch):
    """analyze_scenario(paper, limits=True) with the frozen-point limits stubbed as given and the
    periodic and first-contact searches recorded (each returns what the test sets)."""
    from tmtcontrol.stability import first_contact, periodic, wholeloop

    calls = {}

    def set_limits(frozen, per_point, periodic_at=None, first_at=None):
        monkeypatch.setattr(wholeloop, "whole_loop_limit", lambda *a, **kw: (frozen, per_point))
        monkeypatch.setattr(periodic, "periodic_search", lambda scenario, bracket=None, **kw: calls.setdefault(
            "bracket", bracket) and periodic.PeriodicLimit(periodic_at, "spectral radius", 0.99, 1.0))
        monkeypatch.setattr(first_contact, "first_contact_limit",
                            lambda scenario, bound, **kw: calls.setdefault("bound", bound) and first_at)
        return calls

    return set_limits


def test_the_periodic_search_starts_from_the_frozen_limits_widened_two_percent(frozen_limits):
    """analysis.py:core/ReplaceBinaryOperator_Mul_FloorDiv:0 (`hi // 1.02`): the periodic limit is
    bracketed by the frozen loop's smallest and largest limits along the path, each 2 % outward
    (periodic_limit's own default bracket): (1e4 / 1.02, 1.3e4 * 1.02), not an upper end inside
    the frozen range (1.3e4 // 1.02 = 12745). The first-contact search is bounded by the periodic
    limit, and the smaller of the two decides."""
    from tmtcontrol.stability.analysis import analyze_scenario

    calls = frozen_limits(1e4, [(0.0, 1e4), (2.0, 1.3e4)], periodic_at=1.2e4, first_at=1.5e4)
    out = analyze_scenario(paper_scenario(), limits=True)
    assert calls == {"bracket": (1e4 / 1.02, 1.3e4 * 1.02), "bound": 1.2e4}
    assert (out["limit"], out["limit_from"]) == (1.2e4, "periodic orbit")
    assert out["sampled_stable"] is False                     # the paper's 2e4 N/m is above it


def test_the_deciding_limit_compiles_the_tangent_beside_the_step_and_searches_with_that_model(
        frozen_limits, monkeypatch):
    """Review 35's survivors (results unchanged, only the time): the compile-ahead given too few steps
    (nothing compiled ahead), or its model thrown away (periodic_limit building and compiling its own).
    The tangent step of the model the periodic search gets and the step of the runner the first-contact
    search gets go to compile_together together, for a run longer than COMPILE_AFTER."""
    from tmtcontrol.simulation import rollout
    from tmtcontrol.stability import first_contact, periodic
    from tmtcontrol.stability.analysis import analyze_scenario

    frozen_limits(1e4, [(0.0, 1e4), (2.0, 1.3e4)], periodic_at=1.2e4, first_at=1.5e4)
    seen, models, runners = {}, [], []
    monkeypatch.setattr(rollout, "compile_together",
                        lambda rollouts, steps, threads=2: seen.update(rollouts=list(rollouts), steps=steps))
    monkeypatch.setattr(periodic, "periodic_search", lambda scenario, bracket=None, model=None, **kw: models.append(
        model) or periodic.PeriodicLimit(1.2e4, "spectral radius", 0.99, 1.0))
    monkeypatch.setattr(first_contact, "first_contact_limit",
                        lambda scenario, bound, runner=None, **kw: runners.append(runner) or 1.5e4)
    analyze_scenario(paper_scenario(), limits=True)
    (model,), (runner,) = models, runners
    assert model is not None and seen["steps"] > rollout.COMPILE_AFTER
    assert seen["rollouts"] == [model.rollout, runner.sim.rollout]


def test_compare_laws_compiles_its_loops_together_for_the_runs_length(monkeypatch):
    """Review 35's survivor: compare_laws giving compile_together 0 steps (nothing compiled ahead:
    the laws' loops compiled one after the other as they run). Each law's rollout, for the
    scenario's own number of periods (1,000 at 0.25 cycles of the paper)."""
    from tmtcontrol import apply_overrides
    from tmtcontrol.simulation import rollout
    from tmtcontrol.simulation.compare import compare_laws

    calls = []
    monkeypatch.setattr(rollout, "compile_together", lambda rollouts, steps, threads=2: calls.append(
        (len(list(rollouts)), steps)))
    cmp = compare_laws(apply_overrides(paper_scenario(), ["trajectory.cycles=0.25"]), ["tmt", "known"])
    assert calls == [(2, 1000)] and set(cmp.runs) == {"tmt", "known"}


def test_a_loop_unstable_at_the_smallest_stiffness_has_limit_zero_and_no_path_search(frozen_limits):
    """analysis.py:core/ReplaceComparisonOperator_Gt_GtE:3 (`limit >= 0`): a whole loop unstable at
    the scenario's smallest stiffness (frozen limit 0) has limit 0 "unstable at the smallest
    stiffness", and no periodic or first-contact search is started from a zero bracket."""
    from tmtcontrol.stability.analysis import analyze_scenario

    calls = frozen_limits(0.0, [(0.0, 0.0), (2.0, 0.0)], periodic_at=1.2e4, first_at=1.5e4)
    out = analyze_scenario(paper_scenario(), limits=True)
    assert calls == {}
    assert (out["limit"], out["limit_from"], out["sampled_stable"]) == (0.0, "unstable at the smallest stiffness",
                                                                        False)


def test_the_analysis_table_heads_a_range_and_a_single_stiffness_as_such():
    """analysis.py:core/AddNot:46 (`if not "k_e_min" in d`): the printed table's first row is the
    stiffness range for a range and the single stiffness for one (N/m)."""
    from tmtcontrol.stability.analysis import analyze, format_analysis

    one = format_analysis(analyze(m=1.0, b=60.0, k=100.0, k_e=5e3)).splitlines()[0]
    both = format_analysis(analyze(m=1.0, b=60.0, k=100.0, k_e_min=2e3, k_e_max=2e4)).splitlines()[0]
    assert one == "stiffness            5000 N/m"
    assert both == "stiffness range      2000 .. 20000 N/m (scalars below at k_e_max)"


def test_the_analysis_table_gives_the_x_e_error_in_millimetres():
    """analysis.py:core/NumberReplacer:92 (`* 1001.0`, the sampled row's metres to millimetres): a
    surface 2 mm off (x_e error -0.002 m) reads "-2 mm" in both rows that quote it."""
    from tmtcontrol.stability.analysis import analyze, format_analysis

    rows = format_analysis(analyze(m=1.0, b=60.0, k=100.0, k_e=5e3, Ts=1e-3, m_p=3.3, x_e_error=-2e-3,
                                   law="known")).splitlines()
    assert any(r.startswith("with x_e error       -2 mm: steady-state force ") for r in rows), rows
    assert "sampled at Ts        0.001 s, m_p = 3.3 kg, delay 0 sample(s), x_e error -2 mm" in rows


# -- simulation/scenario.py (fourth run, seed 3) ----------------------------------------------------

@pytest.mark.parametrize("off,accepted", [(1e-6, True), (1.5e-6, False)])
def test_a_normal_and_a_tilt_agreeing_within_exactly_1e_6_are_one_plane(off, accepted):
    """scenario.py:core/ReplaceComparisonOperator_Gt_GtE:3 (`>= 1e-6`): normal (1e-6, 0, -1) with
    tilt_deg = 0 (the plane's normal (0, 0, -1)) differs by exactly 1e-6 in one component, the
    tolerance, inclusive like the unit-length check's: accepted; 1.5e-6 off is refused naming
    tilt_deg (the environment section as a 6-D arm's scenario holds it)."""
    from pydantic import ValidationError

    from tmtcontrol.simulation.scenario import EnvironmentSettings

    given = dict(normal=(off, 0.0, -1.0), tilt_deg=0.0)
    if accepted:
        assert EnvironmentSettings(**given).normal == (off, 0.0, -1.0)
    else:
        with pytest.raises(ValidationError, match="tilt_deg: 0 deg is not the plane of normal"):
            EnvironmentSettings(**given)


def test_an_input_file_is_read_in_mebibyte_chunks(tmp_path, monkeypatch):
    """scenario.py:core/NumberReplacer:447 (`1**20`, one byte per read, for `2**20`): a 2.5 MiB
    table is read whole in three reads of at most 1 MiB and one that meets the end (never one
    16 MiB buffer, never millions of system calls)."""
    from tmtcontrol.simulation import scenario

    path = tmp_path / "big.csv"
    text = ("0.0,1000.0\n" * (5 * 2**19 // 11 + 1))[:5 * 2**19]      # 2.5 MiB of text
    path.write_text(text)
    asked = []
    real = os.read
    monkeypatch.setattr(os, "read", lambda fd, n: asked.append(n) or real(fd, n))
    assert len(text) == 5 * 2**19 and scenario.read_text_file(path) == text
    assert asked == [2**20] * 4          # 1 + 1 + 0.5 MiB, then the end of the file


# -- the fifteenth session's mutation run (seed 8) on model/robot.py: its survivors -------------------

def _ur5_text(**dynamics):
    import importlib.resources
    import re

    text = importlib.resources.files("tmtcontrol.model").joinpath("data", "ur5.urdf").read_text()
    return re.sub(r'damping="0.0" friction="0.0"', 'damping="{damping}" friction="{friction}"'.format(**dynamics),
                  text)


def test_a_urdf_arms_smooth_coulomb_friction_is_tanh_of_dq_over_its_velocity_scale(tmp_path):
    """Mutant robot.py ReplaceBinaryOperator_Div_Sub:0 (``tanh(dq - v)`` for ``tanh(dq / v)``):
    the URDF path's smooth friction against its closed form b dq + f_c tanh(dq / v), with the
    URDF's <dynamics damping="0.5" friction="2.0"> on every joint, v = 0.05 rad/s."""
    from tmtcontrol.model.robot import load_robot

    path = tmp_path / "arm.urdf"
    path.write_text(_ur5_text(damping=0.5, friction=2.0))
    arm = load_robot(str(path), tip="tool0", friction="smooth", coulomb_velocity=0.05, cache=False)
    dq = np.array([0.05, -0.1, 0.01, 0.2, -0.02, 0.0])
    np.testing.assert_allclose(arm.friction(dq), 0.5 * dq + 2.0 * np.tanh(dq / 0.05), rtol=1e-14, atol=1e-15)


def test_a_negative_armature_is_refused_and_zero_is_not():
    """Mutant robot.py ReplaceComparisonOperator_Lt_Eq:2 (``arm == 0`` for ``arm < 0``): a rotor
    inertia below zero is refused in one line naming armature; zeros are valid (no rotor)."""
    from tmtcontrol.model.robot import load_robot
    from tmtcontrol.model.urdf import URDFError

    with pytest.raises(URDFError, match=r"^armature: expected 6 finite values >= 0"):
        load_robot("ur5", armature=[0.1, -0.01, 0.1, 0.1, 0.1, 0.1], cache=False)
    assert load_robot("ur5", armature=[0.0] * 6, cache=False).n == 6


def test_a_cache_folder_name_keeps_letters_digits_dash_and_underscore():
    """Mutant robot.py AddNot:32 (``not c.isalnum()``): the name of an arm's compiled-code folder
    keeps its letters, digits, '-' and '_' and replaces the rest, at most 40 characters."""
    from tmtcontrol.model.robot import _safe

    assert _safe("UR5e arm/v2.1") == "UR5e_arm_v2_1"
    assert _safe("panda-hand_tcp") == "panda-hand_tcp" and _safe("") == "robot" and len(_safe("x" * 99)) == 40


def test_a_compiled_library_is_used_only_with_its_own_checksum(tmp_path):
    """Mutant robot.py ReplaceComparisonOperator_Eq_GtE:6 (``>=`` for ``==``): a stored library is
    read back only when its recorded SHA-256 is its own; a checksum that differs, above or below
    it in string order, makes it unverifiable (rebuilt)."""
    import hashlib

    from tmtcontrol.model.robot import _sidecar, _store, _verified

    lib = tmp_path / "lib.so"
    _store(lib, b"compiled code")
    assert _verified(lib) == b"compiled code"
    own = hashlib.sha256(b"compiled code").hexdigest()
    for other in ("0" * 64, "f" * 64):
        assert other != own
        _sidecar(lib).write_text(other)
        assert _verified(lib) is None


def test_the_scenario_a_design_runs_keeps_its_tangential_impedance():
    """Mutant design.py NumberReplacer:328 of the seed-8 run (an index of the tangential b or k
    moved, e.g. ``imp.b[1]`` for ``imp.b[2]``): every bundled scenario has equal tangential gains,
    so nothing told them apart. The designed scenario runs the design's b and k on the normal axis
    and the scenario's own, unequal here, on the tangential axes, at the design's rate and delay;
    a --filter-hz pole comes back as the cut-off whose pole it is."""
    from tmtcontrol import apply_overrides
    from tmtcontrol.stability.design import designed_scenario

    sc = apply_overrides(paper_scenario(), ["impedance.b=[60.0, 25.0, 35.0]", "impedance.k=[100.0, 150.0, 250.0]"])
    alpha = 0.5
    r = SimpleNamespace(b=193.7, k=120.0, spec=SimpleNamespace(Ts=0.002, delay=1, alpha=alpha))
    out = designed_scenario(sc, r)
    assert list(out.impedance.b) == [193.7, 25.0, 35.0] and list(out.impedance.k) == [120.0, 150.0, 250.0]
    assert out.controller.Ts == pytest.approx(0.002, rel=1e-15) and out.controller.delay_samples == 1
    assert out.sensor.pole(0.002) == pytest.approx(alpha, rel=1e-12)


# -- the seed-8 run's survivors in simulation/simulator.py ------------------------------------------------

def test_the_run_size_refusal_estimates_60_doubles_twice_and_a_csv_row_per_step():
    """Mutant simulator.py ReplaceBinaryOperator_Mul_LShift:0 (``8 << 2 * 60 + 300``): the refusal's
    memory estimate is 8 B x 2 x 60 + 300 B = 1,260 B per control step (its docstring); the paper
    at 1,000 cycles of its 4 s period is 4,000,000 steps at 1 kHz, 4e6 x 1,260 / 2^30 = 4.7 GiB."""
    from tmtcontrol import apply_overrides
    from tmtcontrol.simulation.scenario import ScenarioError
    from tmtcontrol.simulation.simulator import check_run_size

    sc = apply_overrides(paper_scenario(), ["trajectory.cycles=1000"])
    assert 4e6 * 1260 / 2 ** 30 == pytest.approx(4.69, abs=0.01)
    with pytest.raises(ScenarioError, match=r"4,000,000 control steps \(4000 s at 1000 Hz, about 4\.7 GiB\)"):
        check_run_size(sc)
    # under a GiB in MiB (review 59: "about 0.0 GiB"): the paper's 16,000 steps x 1,260 B = 19.2 MiB
    with pytest.raises(ScenarioError, match=r"16,000 control steps \(16 s at 1000 Hz, about 19 MiB\) exceed the "
                                            r"limit of 10;"):
        check_run_size(paper_scenario(), 10)


def test_the_path_check_samples_one_period_evenly():
    """Mutant simulator.py ReplaceBinaryOperator_Mul_FloorDiv:3 (``arange(N) // period``): the path's
    pose check (IK, conditioning) samples one period of the path at N even times, t_i = i T / N,
    so it sees the whole circle, not its first quarter."""
    from tmtcontrol.simulation.posture import PATH_SAMPLES
    from tmtcontrol.simulation.simulator import path_of, robot_of

    sc = paper_scenario()
    path = path_of(robot_of(sc), sc)
    T = sc.trajectory.period
    np.testing.assert_allclose(path.t, np.arange(PATH_SAMPLES) * T / PATH_SAMPLES, rtol=0, atol=1e-15 * T)


# -- the sixteenth session's mutation run (seed 9) on simulation/geometry.py, and review 54 -----------------

@pytest.mark.parametrize("angle", [1e-13, 1e-10, 1e-6, 0.3, 2.0, np.pi - 1e-3, np.pi - 5e-10, np.pi - 1e-13])
def test_the_rotation_vector_is_scipys_at_tiny_angles_and_near_a_half_turn(angle):
    """Seed 9: the small-angle branch's theta/sin(theta) ~ 1 + s^2/6 survived as 2 + s^2/6 (an angle
    below 1e-9 rad read twice its size). Review 54: within 1e-9 rad of pi the sine is below the
    same 1e-9, so that branch ran there too and read pi - 5e-10 as 5e-10 (no correcting torque at a
    half turn). Against SciPy's as_rotvec, 1e-9 relative plus 4e-16 rad absolute (a matrix's
    rounding: tiny angles are read from entries of size 1)."""
    from scipy.spatial.transform import Rotation

    from tmtcontrol.simulation.geometry import rotation_vector

    rng = np.random.default_rng(9)
    for _ in range(20):
        axis = rng.normal(size=3)
        v = angle * axis / np.linalg.norm(axis)
        got = rotation_vector(Rotation.from_rotvec(v).as_matrix())
        assert np.abs(got - v).max() <= 1e-9 * angle + 4e-16, (angle, got, v)


def test_the_rotation_vectors_jacobian_at_the_identity_is_the_identity():
    """d log(exp(e^))/de = I at e = 0, where the loop's linearisations sit on a path held exactly;
    the small-angle branch's constant decides it (2 + s^2/6 gave 2 I)."""
    import casadi as ca

    from tmtcontrol.simulation.geometry import rotation_vector

    e = ca.SX.sym("e", 3)
    J = ca.Function("J", [e], [ca.jacobian(rotation_vector(ca.SX.eye(3) + ca.skew(e)), e)])
    assert np.abs(np.array(J(np.zeros(3))) - np.eye(3)).max() == 0.0


def test_the_model_check_of_the_rotation_vector_covers_a_half_turn(monkeypatch):
    """check's "rotation vector = SciPy's" row drew 30 angles in (1e-6, 3) rad, none near pi
    (review 54): the old small-angle choice fails it now."""
    import casadi as ca

    from tmtcontrol.checks import model
    from tmtcontrol.simulation import geometry

    assert model.rotation_vector_check().passed

    def old(R_e):                                   # the code before review 54's fix
        R_e = ca.DM(R_e)
        v = 0.5 * ca.vertcat(R_e[2, 1] - R_e[1, 2], R_e[0, 2] - R_e[2, 0], R_e[1, 0] - R_e[0, 1])
        s = ca.norm_2(v)
        theta = ca.atan2(s, 0.5 * (R_e[0, 0] + R_e[1, 1] + R_e[2, 2] - 1))
        return np.array(ca.if_else(s > 1e-9, theta / ca.fmax(s, 1e-9), 1 + s * s / 6) * v).ravel()

    monkeypatch.setattr(geometry, "rotation_vector", old)
    assert not model.rotation_vector_check().passed


@pytest.mark.parametrize("at", ["identity", "half turn"])
def test_the_rotation_vectors_mx_jacobian_is_finite_at_a_skew_part_of_exactly_zero(at):
    """Review 55: the loop builds MX, where norm_2's derivative v/|v| was NaN at a skew part of exactly 0
    (R_d equal to R_tool bit for bit: R R^T is exactly symmetric), at the identity and at exactly pi;
    the SX test above did not see it. At the identity the Jacobian is I; at a half turn about z it is
    finite (pi/2 off the diagonal: the log map's derivative there)."""
    import casadi as ca
    from scipy.spatial.transform import Rotation

    from tmtcontrol.simulation.geometry import rotation_vector

    e, R0 = ca.MX.sym("e", 3), ca.MX.sym("R0", 3, 3)
    J = ca.Function("J", [e, R0], [ca.jacobian(rotation_vector(ca.mtimes(ca.MX.eye(3) + ca.skew(e), R0)), e)])
    R = np.eye(3) if at == "identity" else Rotation.from_rotvec([0.0, 0.0, np.pi]).as_matrix()
    got = np.array(J(np.zeros(3), R))
    assert np.all(np.isfinite(got)), got
    if at == "identity":
        assert np.abs(got - np.eye(3)).max() == 0.0
