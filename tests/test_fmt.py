"""Number formatting (tmtcontrol.fmt) against values written out by hand: the
scientific form's digits and its carry into the next decade, and the residue
floor of a table column, relative to the column's largest magnitude. Found by
the mutation tool's first run on fmt.py (the thirteenth session, seed 7)."""
import pytest

from tmtcontrol import fmt

NBSP = "\u00a0"


@pytest.mark.parametrize("v, sig, shown", [
    (3.14159e-5, 2, "3.1 × 10⁻⁵"),
    (-2.71828e-7, 3, "−2.72 × 10⁻⁷"),
    (6.02214076e23, 4, "6.022 × 10²³"),
    (9.9996e-5, 3, "1 × 10⁻⁴"),            # 9.9996 rounds to 10.0: carried into the next decade, not "10 × 10⁻⁵"
    (1.25e9, 3, "1.25 × 10⁹"),
])
def test_the_scientific_form_shows_sig_significant_digits(v, sig, shown):
    assert fmt.num(v, sig).replace(NBSP, " ") == shown


def test_a_column_keeps_trailing_zeros_in_the_scientific_form():
    _, cells = fmt.column([3.1e-5, 2.0e-5], "1")
    assert [c.replace(NBSP, " ") for c in cells] == ["3.10 × 10⁻⁵", "2.00 × 10⁻⁵"]


def test_the_residue_floor_is_relative_to_the_columns_largest_magnitude():
    """fmt.RESIDUE (1e-9) times the largest magnitude: beside 3e6 N/m, 1e-4 N/m
    is residue and prints 0; a column of values all near 1e-12 keeps them (an
    absolute floor of 1e-9 would blank a column of nanometre-scale values)."""
    _, cells = fmt.column([3.0e6, 1.0e-4], "N/m")
    assert cells[1] == "0" and cells[0] != "0"
    _, cells = fmt.column([2.0e-12, 1.5e-12], "1")
    assert [c.replace(NBSP, " ") for c in cells] == ["2.00 × 10⁻¹²", "1.50 × 10⁻¹²"]
    _, cells = fmt.column([1.0e-4], "N/m", reference=3.0e6)      # residue alone, sized by the reference
    assert cells == ["0"]


def test_a_text_table_right_aligns_numbers_and_left_aligns_the_last_column_by_default():
    t = fmt.text_table([("k_e", ["5,000", "20,000"]), ("error", ["1.2", "0.45"]), ("verdict", ["converged", "off"])])
    assert t.splitlines() == ["   k_e  error  verdict",
                              "-" * 22,
                              " 5,000    1.2  converged",
                              "20,000   0.45  off"]


def test_digits_apart_is_the_fewest_digits_that_print_the_value_unlike_its_bound():
    """The helper behind fmt.against and the orientation verdict's angles: from sig up while the two
    print alike; sig when nothing can tell them apart (equal, missing, not finite); at most `most`."""
    assert fmt.digits_apart(2.0, 3.0) == 3                       # apart at once
    assert fmt.digits_apart(4.995, 5.0) == 4                     # 5.00 and 5.00 at 3 digits, 4.995 and 5.000 at 4
    assert fmt.digits_apart(5.0, 5.0) == 3 and fmt.digits_apart(5.0, 5.0, sig=2) == 2
    assert fmt.digits_apart(None, 5.0) == 3 and fmt.digits_apart(float("nan"), 5.0) == 3
    assert fmt.digits_apart(float("inf"), 5.0) == 3 and fmt.digits_apart(5.0, None) == 3
    assert fmt.digits_apart(1.0000001, 1.0) == 6 and fmt.digits_apart(1.0000001, 1.0, most=4) == 4
    assert fmt.digits_apart(1.00001, 1.0) == 6                   # 1.00001 against 1.00000 at 6
    assert fmt.against(4.995, 5.0) == "4.995"


def test_the_orientation_verdicts_angles_take_the_digits_that_tell_the_error_from_its_tolerance():
    from tmtcontrol.simulation.metrics import _angles

    assert _angles([2.62e-4], 2.62e-4) == (["262 µrad"], "262 µrad")
    assert _angles([2.6201e-4], 2.62e-4) == (["262.01 µrad"], "262 µrad")     # 5 digits; num drops the zeros
