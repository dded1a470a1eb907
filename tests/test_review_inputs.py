"""Review of the bad-input and fault paths (issues #27, #32) with cases the first
tests did not write: TOML that is valid but pathological (arrays nested past
the parser's recursion, a dotted key of thousands of parts whose parsing takes
memory quadratic in its length), the ``--set`` syntax, the command-line flags
named in every refusal, and output folders with unusual names.

Every refusal: exit code 2, one line on stderr naming the file, key or flag,
nothing on stdout, nothing written."""
import pytest

from tmtcontrol.cli import main


def _refused(capsys, tmp_path, needle, *args):
    before = sorted(p.name for p in tmp_path.iterdir())
    code = main(list(args))
    cap = capsys.readouterr()
    lines = cap.err.strip().splitlines()
    assert code == 2 and cap.out == "" and len(lines) == 1, (code, cap.out, lines[:3])
    assert needle in lines[0] and "Traceback" not in lines[0], lines[0]
    assert sorted(p.name for p in tmp_path.iterdir()) == before        # nothing written
    return lines[0]


# -- TOML that parses only with unbounded recursion or memory --------------------------

@pytest.mark.parametrize("what", ["scenario", "sweep"])
@pytest.mark.parametrize("body", ["x = " + "[" * 5000 + "]" * 5000,
                                  "x = " + "{a = " * 5000 + "1" + "}" * 5000],
                         ids=["arrays", "inline tables"])
def test_toml_nested_past_the_recursion_limit_is_one_line(capsys, tmp_path, what, body):
    # tomllib parses nested arrays and inline tables recursively: 5,000 levels (a 10 kB file)
    # raised RecursionError, a 3,000-line traceback with exit code 1
    f = tmp_path / "deep.toml"
    f.write_text(body + "\n")
    args = ["simulate", str(f)] if what == "scenario" else ["sweep", str(f)]
    line = _refused(capsys, tmp_path, "nested too deeply", *args, "--out", str(tmp_path / "o"))
    assert str(f) in line


def test_a_dotted_key_of_thousands_of_parts_is_refused_before_parsing(capsys, tmp_path):
    # tomllib keeps every prefix of a dotted key: a key of n parts costs memory ~ n^2 / 2 tuple slots.
    # 10,000 parts (a 20 kB file) took 450 MB, 100,000 parts (200 kB) had the process killed.
    # The bound is on the key's parts (no scenario or sweep key has more than a few), so the
    # refusal comes before tomllib is called: 100,000 parts here, answered at once
    f = tmp_path / "dotted.toml"
    f.write_text("a" + ".a" * 100_000 + " = 1\n")
    line = _refused(capsys, tmp_path, "dotted parts", "simulate", str(f), "--out", str(tmp_path / "o"))
    assert str(f) in line and "line 1" in line


def test_a_dotted_run_inside_strings_and_numbers_is_not_a_key(tmp_path):
    # the bound must not refuse ordinary files: float arrays, dotted names in strings, comments
    from tmtcontrol.simulation.scenario import load_scenario

    f = tmp_path / "ok.toml"
    f.write_text('name = "v1.2.3 of the test.bench.cell"  # see sec. 5.1.2\n'
                 "[environment.stiffness]\nkind = \"piecewise_constant\"\nvalues = [" + ", ".join(["5000.5"] * 2000) + "]\n")
    sc = load_scenario(f)
    assert sc.name == "v1.2.3 of the test.bench.cell" and len(sc.environment.stiffness.values) == 2000


@pytest.mark.parametrize("value", ["[" * 3000 + "]" * 3000, "{" + "a." * 5000 + "a = 1}"],
                         ids=["nested", "dotted"])
def test_set_value_nested_or_dotted_past_the_bound_names_set(capsys, tmp_path, value):
    line = _refused(capsys, tmp_path, "--set", "simulate", "--set", f"controller.f_d={value}",
                    "--out", str(tmp_path / "o"))
    assert "controller.f_d" in line


def test_set_with_an_empty_key_names_set(capsys, tmp_path):
    # was "error: : malformed key" (neither the flag nor what was given)
    line = _refused(capsys, tmp_path, "--set", "simulate", "--set", "=5", "--out", str(tmp_path / "o"))
    assert "'=5'" in line


# -- worker counts ------------------------------------------------------------------------

def test_a_huge_worker_count_is_refused_before_anything_starts(capsys, tmp_path):
    # --workers 1000000 on a 2-case sweep forked processes until the machine ran out of memory
    # (3,400 processes in 30 s; the OOM killer ended it, leaving OUT.partial/ and a staging folder)
    f = tmp_path / "s.toml"
    f.write_text('[grid]\n"controller.f_d" = [1.0, 2.0]\n')
    line = _refused(capsys, tmp_path, "--workers", "sweep", str(f), "--workers", "1000000", "--out",
                    str(tmp_path / "o"))
    assert "1000000" in line and "per CPU" in line


def test_the_local_pool_starts_no_more_workers_than_cases(monkeypatch):
    # a fork pool starts all its workers at the first submit: 6 asked for 2 cases started 6
    import concurrent.futures as cf

    from tmtcontrol.sweep import sweep_from_dict
    from tmtcontrol.sweep.run import run_cases

    asked = []

    class Pool:
        def __init__(self, max_workers, **kw):
            asked.append(max_workers)
            raise RuntimeError("stop here")

    monkeypatch.setattr(cf, "ProcessPoolExecutor", Pool)
    sweep = sweep_from_dict({"grid": {"controller.f_d": [1.0, 2.0]}})
    with pytest.raises(RuntimeError, match="stop here"):
        run_cases(sweep, sweep.cases, lambda rows: None, workers=6)
    assert asked == [2]


# -- every refusal names the flag the user typed -----------------------------------------

_DESIGN = ["design", "--m", "1", "--k", "100", "--ke-min", "2000", "--ke-max", "20000", "--ts", "0.001",
           "--max-overshoot", "5"]


@pytest.mark.parametrize("flag, value", [("--max-overshoot", "nan"), ("--max-overshoot", "-1"),
                                         ("--margin", "nan"), ("--margin", "0"), ("--margin", "0.5"),
                                         ("--mp", "nan"), ("--mp", "-5"), ("--ke-min", "30000"),
                                         # review 13: accepted, then an unnamed overflow, a traceback or a hang
                                         ("--mp", "1e-300"), ("--margin", "1e300"), ("--fd", "1e300"),
                                         ("--k", "1e-300"), ("--max-overshoot", "5000")])
def test_design_refusals_name_the_flag(capsys, tmp_path, flag, value):
    # the messages named the library's fields (max_overshoot, stiffness_margin, m_p, k_e_min)
    args = list(_DESIGN)
    if flag in args:
        args[args.index(flag) + 1] = value
    else:
        args += [flag, value]
    line = _refused(capsys, tmp_path, flag, *args)
    assert line.startswith(f"error: {flag}: "), line


@pytest.mark.parametrize("extra, flag", [(["--ke", "5000", "--ts", "0.001", "--mp", "nan"], "--mp"),
                                         (["--ke", "5000", "--ts", "0.001", "--mp", "0"], "--mp"),
                                         (["--ke-min", "30000", "--ke-max", "20000"], "--ke-min"),
                                         # review 13: an unnamed overflow, or a "stable" verdict on 1e301 N
                                         (["--ke", "5000", "--ts", "0.001", "--mp", "1e-100"], "--mp"),
                                         (["--ke", "5000", "--ts", "0.001", "--mp", "1e308"], "--mp"),
                                         (["--ke", "5000", "--x-e-error", "1e300"], "--x-e-error"),
                                         (["--ke", "5000", "--fd", "1e300"], "--fd"),
                                         (["--ke", "1e-300", "--ts", "0.001"], "--ke")])
def test_analyze_refusals_name_the_flag(capsys, tmp_path, extra, flag):
    line = _refused(capsys, tmp_path, flag, "analyze", "--m", "1", "--b", "60", "--k", "100", *extra)
    assert line.startswith(f"error: {flag}: "), line


def test_robot_negative_seed_names_the_flag(capsys, tmp_path):
    # was "error: expected non-negative integer" (NumPy's words, no flag)
    line = _refused(capsys, tmp_path, "--seed", "robot", "puma560", "--seed", "-1", "--samples", "1")
    assert "-1" in line


# -- output names ----------------------------------------------------------------------------

@pytest.mark.parametrize("name", ["a" * 250, "é" * 127], ids=["250 ASCII", "254 bytes UTF-8"])
def test_a_long_but_legal_output_name_is_written(tmp_path, name):
    # a name of up to 255 bytes is legal; the staging folder beside it (.NAME.tmt-XXXXXXXX, and its
    # .owner record) made every name above 234 bytes fail with 'File name too long'
    from tmtcontrol.files import OutputFolder

    out = tmp_path / name
    with OutputFolder(out, "--out") as folder:
        (folder.path / "a.txt").write_text("x")
        folder.commit()
    assert (out / "a.txt").read_text() == "x"
    assert sorted(p.name for p in tmp_path.iterdir()) == [name]     # no staging folder or record left
    with OutputFolder(out, "--out") as folder:                       # and it is replaced as an output
        (folder.path / "b.txt").write_text("y")
        folder.commit()
    assert sorted(p.name for p in out.iterdir()) == [".tmtcontrol-output.json", "b.txt"]


def test_a_malformed_wide_csv_row_is_quoted_short(capsys, tmp_path):
    # a row of 200,000 fields was quoted whole: a 1 MB error "line"
    (tmp_path / "k.csv").write_text("t, k_e\n" + ",".join(["1"] * 200_000) + "\n")
    (tmp_path / "s.toml").write_text('[environment.stiffness]\nkind = "table"\nfile = "k.csv"\n')
    line = _refused(capsys, tmp_path, "row 2", "simulate", str(tmp_path / "s.toml"), "--out", str(tmp_path / "o"))
    assert len(line) < 400 and "200000 fields" in line, line[:500]


@pytest.mark.parametrize("key, value", [("controller.f_d", "1e308"), ("controller.x_e_error", "1e300"),
                                        ("environment.damping", "1e300"), ("sensor.noise_std", "1e300"),
                                        ("controller.contact_threshold", "1e300"), ("impedance.k", "[1e-300, 1.0, 1.0]"),
                                        ("environment.stiffness.values", "[1e-300]"), ("simulation.tol", "1e-300")])
def test_a_setting_beyond_what_an_arm_means_is_refused_naming_the_key(capsys, tmp_path, key, value):
    """Regression (review 13): these had no upper (or a zero lower) bound: f_d = 1e308 N or an
    x_e_error of 1e300 m ran and 'diverged at t = 0' (exit 1, a verdict on bad input), or overflowed
    an analysis. Now one line naming the key, exit 2, nothing written."""
    line = _refused(capsys, tmp_path, "--set", "simulate", "--set", f"{key}={value}", "--no-plots",
                    "--out", str(tmp_path / "o"))
    assert line.startswith(f"error: {key}") and "(in --set)" in line, line      # a list's element: key[0]


def test_an_astronomical_run_length_is_quoted_with_an_exponent(capsys, tmp_path):
    """Regression (review 13): trajectory.period = 1e300 s was refused with its step count written out
    in 300 digits (a 600-character line). 1e300 s x 4 cycles at 1 kHz is 4e303 steps; a count below
    1e15 keeps its digits (docs/outputs.md quotes 4,000,000)."""
    line = _refused(capsys, tmp_path, "trajectory.cycles", "simulate", "--set", "trajectory.period=1e300",
                    "--out", str(tmp_path / "o"))
    assert "4e+303 control steps" in line and len(line) < 200
    line = _refused(capsys, tmp_path, "trajectory.cycles", "simulate", "--set", "trajectory.cycles=1000",
                    "--out", str(tmp_path / "o"))
    assert "4,000,000 control steps (4000 s at 1000 Hz, about 4.7 GiB)" in line


def test_a_radius_beyond_a_plane_is_refused_naming_the_key(capsys, tmp_path):
    """Regression (review 13): environment.radius = 1e300 m overflowed the chart (r^2) and was refused as
    'sphere: no task frame at ...'. A part flatter than 1e9 m is its tangent plane to 1e-11 m over 10 cm."""
    line = _refused(capsys, tmp_path, "environment.radius", "simulate", "--set", 'environment.shape="sphere"',
                    "--set", "environment.radius=1e300", "--out", str(tmp_path / "o"))
    assert line.startswith("error: environment.radius: must be <= 1e+09")
