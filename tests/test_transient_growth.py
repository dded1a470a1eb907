"""The periodic limit where the spectral radius is no margin (stability.periodic's
transient growth; docs/theory.md, "Transient growth"), on review 37's 4-joint arm:
the limit is checked against runs of the simulator, and the page's table against
analysis/transient_growth.py."""
import importlib.util
import pathlib
import re

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[1]
THEORY = ROOT / "docs" / "theory.md"


def _script():
    spec = importlib.util.spec_from_file_location("transient_growth", ROOT / "analysis" / "transient_growth.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _cells(line: str) -> list[str]:
    return [c.strip() for c in line.strip().strip("|").split("|")]


def _numbers(line: str) -> list[float]:
    return [float(v.replace(",", "")) for v in re.findall(r"-?\d[\d,]*\.?\d*(?:e[+-]?\d+)?", line)]


@pytest.fixture(scope="module")
def summary():
    script = _script()
    from tmtcontrol import load_scenario

    return script, script.rows_for(load_scenario(str(script.SCENARIO)), 5.0)


@pytest.mark.heavy   # two periodic searches on the arm and twelve runs: about 15 s
def test_a_limit_set_by_transient_growth_holds_in_the_simulator_where_the_orbit_loss_edge_does_not(summary):
    """Review 37: the search without the growth bound ended where the orbit is lost (7.4e5 N/m, the
    radius 0.03-0.15 below it), and constant-k_e runs below that missed the 10 mN tolerance. With
    the bound the limit is set by transient growth, and the simulator (noise-free, 5 periods, the
    last judged) holds the force within the scenario's tolerance at 0.99 and 1.13 of it and misses
    it by orders of magnitude at the edge. With 5 mN of sensor noise the arm's error is
    newtons at 0.8 of its limit while the paper's at 0.95 of its own stays below 0.1 N (the page's
    claims)."""
    _, s = summary
    rows = {r["where"]: r for r in s["rows"]}
    tol = s["force_tolerance"]
    assert s["set_by"] == "transient growth" and s["edge_set_by"] == "orbit lost"
    assert s["edge"] > 1.3 * s["limit"]
    assert rows["0.99 x limit"]["worst_error"] < tol and rows["1.13 x limit"]["worst_error"] < tol
    assert rows["edge"]["worst_error"] > 100 * tol
    assert all(r["spectral_radius"] < 0.2 for r in s["rows"])               # the radius says nothing here
    assert rows["0.99 x limit"]["transient_growth"] < s["growth_bound"] < rows["1.13 x limit"]["transient_growth"]
    assert rows["0.8 x limit"]["worst_error_noise"] > 1.0
    (paper,) = [r for r in s["rows"] if r["scenario"] == "paper"]
    assert paper["worst_error_noise"] < 0.1 and paper["transient_growth"] < 50


@pytest.mark.heavy
def test_the_pages_table_is_what_the_script_prints(summary):
    """docs/theory.md's transient-growth block is analysis/transient_growth.py's table. Cells to 2 %
    relative (3-4 significant digits printed) where the loop amplifies little (growth below 1e4);
    where it amplifies a perturbation 1e4-fold or more, a change of k_e in the sixth digit (the
    search's xtol) moves the runs' errors by more (2.18 and 1.93 mN at 1.13 x the limit in two
    runs), so those are compared within a factor of 2 and on the same side of the tolerance. The
    orbit-loss edge moves by a few percent with the Newton starts its search is given (744,267 and
    761,513 N/m, two runs whose first search differed in the last digit; the page says so): the
    edge within 5 %, its row's measures within a factor of 10, its errors only above the
    tolerance."""
    script, s = summary
    page = THEORY.read_text().split("<!-- transient_growth -->\n", 1)[1].split("<!-- end transient_growth -->")[0]
    want = [ln for ln in script.table(s).splitlines() if ln.strip()]
    got = [ln for ln in page.splitlines() if ln.strip()]
    assert len(got) == len(want)
    tol_mN = 1e3 * s["force_tolerance"]
    for g, w in zip(got, want):
        assert re.sub(r"[-\d.,e+]+", "#", g) == re.sub(r"[-\d.,e+]+", "#", w), (g, w)
        ng, nw = _numbers(g), _numbers(w)
        if g.startswith("Periodic limit"):          # limit, bound, edge, periods
            assert ng[:2] == pytest.approx(nw[:2], rel=1e-4) and ng[3:] == nw[3:], (g, w)
            assert ng[2] == pytest.approx(nw[2], rel=0.05), (g, w)
        elif w.startswith("| ") and not w.startswith("| scenario"):
            cg, cw = _cells(g), _cells(w)                  # k_e, radius, growth, error, error with noise
            assert cg[0] == cw[0] and cg[2] == cw[2], (g, w)                # scenario and where
            (kg, rg, gg, eg, ng_), (kw, rw, gw, ew, nw_) = _numbers(cg[1] + " " + " ".join(cg[3:])), _numbers(
                cw[1] + " " + " ".join(cw[3:]))
            if cw[2] == "edge":
                # the radius too within a factor of 10: 0.0323 at the 734,200 N/m edge, 0.145 at 761,500 (the
                # fast mode grows near the edge; 2026-12-07, when the tests around it moved, CI's run found the
                # first where the page quotes the second: rel=0.2 had held only while runs found one edge)
                assert kg == pytest.approx(kw, rel=0.05) and 0.1 < rg / rw < 10, (g, w)
                assert 0.1 < gg / gw < 10 and min(eg, ew) > 100 * tol_mN, (g, w)      # orders of magnitude off
                assert 0.1 < ng_ / nw_ < 10, (g, w)         # review 64: the noise column went unchecked here
            elif gw < 1e4:
                assert [kg, rg, gg, eg, ng_] == pytest.approx([kw, rw, gw, ew, nw_], rel=2e-2), (g, w)
            else:
                assert [kg, rg, gg] == pytest.approx([kw, rw, gw], rel=2e-2), (g, w)
                assert 0.5 < eg / ew < 2 and (eg < tol_mN) == (ew < tol_mN) and 0.5 < ng_ / nw_ < 2, (g, w)
        else:
            assert g == w


@pytest.mark.heavy
def test_analyze_names_what_sets_the_arms_periodic_limit():
    """`analyze --scenario` on the arm: the "set by" row (transient growth, the radius and growth
    below the limit), and the page's quoted frozen-point minimum (247,683 N/m)."""
    from tmtcontrol import load_scenario
    from tmtcontrol.stability.analysis import analyze_scenario, format_analysis

    a = analyze_scenario(load_scenario(str(ROOT / "analysis" / "data" / "arm4_plane.toml")), limits=True)
    text = format_analysis(a)
    assert a["periodic_set_by"] == "transient growth" and a["limit"] == a["periodic_limit"]
    from tmtcontrol.stability.periodic import GROWTH_BOUND

    assert a["periodic_radius"] < 0.1 and GROWTH_BOUND / 10 < a["periodic_growth"] <= GROWTH_BOUND
    assert ("set by               transient growth: above it a perturbation grows more than "
            f"{GROWTH_BOUND:.0e}-fold") in text
    # review 39: the page's runs with 5 mN of sensor noise miss by newtons below the limit; the output says so
    # (review 40: over several periods: a one-cycle run at 0.9 x the limit converged where five cycles lost contact)
    assert ("noise                the analysis is of the noise-free loop: near this limit it amplifies perturbations, "
            f"sensor noise among them, up to {a['periodic_growth']:.3g}-fold within a period; simulate with "
            "sensor.noise_std over several periods (trajectory.cycles >= 5)") in text
    assert f"{a['whole_loop_limit']:,.0f} N/m" in " ".join(THEORY.read_text().split())


@pytest.mark.heavy
def test_the_reports_verdict_says_the_radius_is_no_margin():
    """The report's sampled-data verdict on the arm names what sets the limit along the path (review
    37: it showed "margin 36.7x" from the orbit-loss edge with nothing to say the radius there was
    0.03), and its margin is the limit's, now set by transient growth."""
    from tmtcontrol import load_scenario
    from tmtcontrol.report.document import Report, _sampled
    from tmtcontrol.stability import scenario_parameters
    from tmtcontrol.stability.analysis import analyze_scenario

    sc = load_scenario(str(ROOT / "analysis" / "data" / "arm4_plane.toml"))
    rep = Report(sc, "")
    p = scenario_parameters(sc)
    _sampled(rep, sc, p)
    (v,) = [v for v in rep.verdicts if v.name.startswith("Stable in the sampled implementation")]
    from tmtcontrol.stability.periodic import GROWTH_BOUND

    assert (f"the limit along the path is where a perturbation grows more than {GROWTH_BOUND:.0e}-fold within a "
            "period") in v.check
    assert "the radius is no margin" in v.check
    assert "The analysis is of the noise-free loop: near this limit the loop amplifies perturbations" in v.check
    assert v.check.endswith("(simulate with the sensor's noise over several periods to see that)")
    assert "the margin is one of stability, not of the force's accuracy under noise" in v.check
    limit = analyze_scenario(sc, limits=True)["limit"]
    assert f"{limit / p['k_e_max']:.3g}" in v.value.replace("×", "")


@pytest.mark.heavy   # two periodic searches on the arm: about 10 s
def test_the_growth_limit_does_not_depend_on_which_end_of_a_line_the_period_starts_at():
    """Review 38: the same line drawn from either end (direction 135 deg and -45 deg: the one path half a
    period apart) had limits 731,719 and 818,217 N/m, one "set by transient growth", the other "orbit lost"
    with a growth of 1.0 (measured from path time 0 only, where a 7.5e6-fold growth started later in the
    period); the simulator treats the two alike (errors 8.0 and 6.8 mN at 8.15e5 N/m, both missing at 9e5).
    Now both are set by the growth and agree to 1e-4 (both searches' xtol, 1e-5, apart from the pieces'
    starts falling on the same samples of the path either way)."""
    from tmtcontrol import apply_overrides, load_scenario
    from tmtcontrol.stability.periodic import periodic_search

    base = load_scenario(str(ROOT / "analysis" / "data" / "arm4_plane.toml"))
    one, other = (periodic_search(apply_overrides(base, ['trajectory.path="line"', f"trajectory.direction_deg={d}"]))
                  for d in (135.0, -45.0))
    assert one.set_by == other.set_by == "transient growth"
    assert one.k_e == pytest.approx(other.k_e, rel=1e-4)
    assert one.k_e < 8.15e5                            # inside the simulated limit (runs hold 10 mN there)
