"""Figures draw long series reduced to their envelope without losing a peak."""
import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from tmtcontrol.simulation.figures import envelope


@settings(max_examples=50, deadline=None)
@given(st.integers(1, 20_000), st.integers(2, 500), st.integers(0, 2**32 - 1))
def test_envelope_keeps_every_extreme(n, buckets, seed):
    rng = np.random.default_rng(seed)
    t = np.arange(n) * 1e-3
    y = np.cumsum(rng.standard_normal(n))
    y[rng.integers(0, n)] = 1e3                      # a one-sample spike
    te, ye = envelope(t, y, buckets)
    assert te.size <= max(n, 2 * buckets)
    assert np.all(np.diff(te) > 0)                   # time order, no duplicates
    assert ye.max() == y.max() and ye.min() == y.min()
    # every output point is a sample of the series
    idx = np.round(te / 1e-3).astype(int)
    assert np.array_equal(ye, y[idx])
    # every bucket's extremes are kept: the max over any bucket equals the envelope's there
    if n > 2 * buckets:
        edges = np.linspace(0, n, buckets + 1).astype(int)
        for a, b in zip(edges[:-1], edges[1:]):
            inside = (idx >= a) & (idx < b)
            assert ye[inside].max() == y[a:b].max() and ye[inside].min() == y[a:b].min()


def test_envelope_skips_nan_and_keeps_empty_buckets_as_gaps():
    t = np.arange(10_000.0)
    y = np.where(t < 5_000, np.nan, t)
    te, ye = envelope(t, y, 100)
    assert np.isnan(ye[te < 5_000]).all() and ye[te >= 5_000].min() == 5_000 and np.nanmax(ye) == 9_999


def test_log_axis_labels_are_matplotlibs_in_plain_text():
    """plain_log_labels keeps matplotlib's choice of labelled ticks and their
    values (10^-4 .. 10^6, minor labels over a short range) and writes
    them without mathtext, a short axis in plain numbers."""
    import matplotlib
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    from tmtcontrol.plotstyle import plain_log_labels

    matplotlib.use("Agg")
    fig = Figure()
    ax = fig.add_subplot()
    ax.loglog([1e-3, 1e5], [2e3, 7e3])

    def labels():
        FigureCanvasAgg(fig).draw()
        return [t.get_text() for t in ax.get_xticklabels() + ax.get_yticklabels() + ax.get_yticklabels(minor=True)
                if t.get_text()]

    before = labels()
    after = labels() if plain_log_labels(fig) is fig else None
    assert len(after) == len(before) and not any("$" in a for a in after)
    sup = str.maketrans("⁰¹²³⁴⁵⁶⁷⁸⁹⁻", "0123456789-")
    as_numbers = [float(a.translate(sup).replace("×10", "e") if "×" in a else "1e" + a[2:].translate(sup)
                        if a.startswith("10") and a[2:] and set(a[2:]) <= set("⁰¹²³⁴⁵⁶⁷⁸⁹⁻") else a.replace(",", ""))
                  for a in after]
    from_mathtext = [float(b.strip("$").removeprefix(r"\mathdefault{").removesuffix("}")
                           .replace(r"\times10^{", "e").replace("10^{", "1e").replace("}", "")) for b in before]
    assert as_numbers == from_mathtext
    # the short y axis (2e3..7e3) in plain numbers (issue 27 item 12: not "6×10³"), the long x axis in powers of ten
    assert "10⁻³" in after and "2,000" in after and not any("×" in a for a in after)


@settings(max_examples=300, deadline=None)
@given(st.floats(min_value=1e-3, max_value=9e8) | st.floats(min_value=-9e8, max_value=-1e-3))
def test_numbers_for_labels_keep_three_significant_digits_without_exponent(value):
    from tmtcontrol.fmt import num

    text = num(value)
    assert "e" not in text and "×" not in text          # plain digits between 1e-3 and 1e9
    # 3 significant digits: within half a unit of the third digit (relative 5e-3), rounding included
    assert abs(float(text.replace(",", "").replace("−", "-")) - value) <= 5e-3 * abs(value) * (1 + 1e-12)


def test_stability_legends_read_stiffness_without_exponent():
    from tmtcontrol.stability.figures import root_locus_figure, step_figure

    labels = [t.get_text() for fig in (root_locus_figure(1.0, 60.0, 100.0, 200.0, 2e5),
                                       step_figure(1.0, 60.0, 100.0, [2e3, 2e4]))
              for t in (fig.axes[0].get_legend() or fig.legends[0]).get_texts()]   # in the axes or under them
    assert labels == ["k_e = 200 N/m", "k_e = 200,000 N/m", "k_e = 2,000 N/m", "k_e = 20,000 N/m"]


def test_the_path_figures_legend_covers_neither_its_title_nor_its_axes(paper_result):
    """Review 65's low: the 3-D path figure's legend, in the axes' top corner, was drawn over its title.
    It sits under the axes now: its box overlaps neither the title's nor the axes'."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    from tmtcontrol.simulation.figures import path_figure

    fig = path_figure(paper_result)
    FigureCanvasAgg(fig).draw()
    r = fig.canvas.get_renderer()
    (ax,) = fig.axes
    (leg,) = fig.legends + ([ax.get_legend()] if ax.get_legend() else [])
    box = leg.get_window_extent(r)
    assert not box.overlaps(ax.title.get_window_extent(r)) and not box.overlaps(ax.get_window_extent(r))
    assert box.y0 >= 0 and box.y1 <= fig.bbox.height                # inside the figure


def test_a_run_that_never_touches_draws_its_force_figures_without_a_warning():
    """Review 72: the force figure took its y range from the largest contact force alone, so a run
    that never reaches the part set ylim(0, 0) and matplotlib's warning ("identical low and high
    ylims") reached simulate's and report's output; the range now holds f_d too (a guarded approach
    too short to reach the part)."""
    import warnings

    from tmtcontrol import apply_overrides, paper_scenario, Simulator
    from tmtcontrol.simulation.compare import compare_laws
    from tmtcontrol.simulation.figures import force_figure, save_comparison_figures

    sc = apply_overrides(paper_scenario(), ["trajectory.approach_gap=0.1", "trajectory.cycles=0.25"])
    res = Simulator(sc).run()
    assert not np.any(res.contact_force > 0)                     # the premise: no touch
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        low, high = force_figure(res).axes[0].get_ylim()
        assert (low, high) == (-0.05, 1.08)                          # 1 N where no force is drawn
        import tempfile

        with tempfile.TemporaryDirectory() as d:
            save_comparison_figures(compare_laws(sc, ["tmt"]), d)
