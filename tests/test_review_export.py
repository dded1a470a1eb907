"""Review of the exported C controller (issue 31) as a robot's real-time code:
cases its author's tests did not cover.

Default suite: ``replay``'s CSV reading (a malformed file is one error line and
exit 2, CRLF is read like LF) and a non-finite measurement (``tmt_step``
refuses the period and keeps its state, instead of returning 0 with a state
that is NaN for good). Heavy: every scenario structure exported and compiled
warning-free by gcc and clang at -O0/-O2/-O3, under AddressSanitizer and
UndefinedBehaviorSanitizer and valgrind; the header alone (C99 and C++); the
Makefile from a copy; replay from ``tmt_init`` (the guarded approach's initial
state included, which the software-in-the-loop run sets from Python) equal to
the simulation.

Tolerance of the equality checks: 1e-9 relative to each signal's largest
magnitude (the issue's acceptance; measured about 1e-15).
"""
import ctypes
import shutil
import subprocess

import numpy as np
import pytest

from tmtcontrol import Simulator, apply_overrides, paper_scenario
from tmtcontrol.export.generate import MEASUREMENT_FIELDS, export_controller
from tmtcontrol.export.sil import CompiledController, read_commands, write_measurements

RTOL = 1e-9
STRICT = ["-std=c99", "-Wall", "-Wextra", "-Werror", "-pedantic"]
HEADER = "t," + ",".join(c for f in MEASUREMENT_FIELDS for c in f.columns)
N_MEAS = sum(f.size for f in MEASUREMENT_FIELDS)
ROW = "0.001," + ",".join(["0.1", "-0.5", "0.8"] + ["0"] * (N_MEAS - 3))


def rel_err(a, b):
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    return float(np.max(np.abs(a - b)) / max(np.max(np.abs(b)), 1e-300))


def _run(cmd, cwd):
    r = subprocess.run(cmd, cwd=cwd, capture_output=True, text=True)
    assert r.returncode == 0, (cmd, r.stderr)
    return r


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    """The paper controller with the inner loop, replay and a shared library, at -O0 (cheap to compile)."""
    folder = tmp_path_factory.mktemp("review")
    export_controller(paper_scenario(), folder, True)
    _run(["gcc", *STRICT, "-O0", "replay.c", "tmt_controller.c", "-lm", "-o", "replay"], folder)
    _run(["gcc", "-std=c99", "-O0", "-fPIC", "-shared", "tmt_controller.c", "-o", "libtmt.so", "-lm"], folder)
    return folder, CompiledController(folder, library=folder / "libtmt.so")


# -- replay's CSV ----------------------------------------------------------------------------------

@pytest.mark.parametrize("name, text, says", [
    ("empty", "", "empty file"),
    ("header only", HEADER + "\n", "no measurement rows"),
    ("missing column", HEADER + "\n" + ROW.rsplit(",", 1)[0] + "\n", "row 2"),
    ("extra column", HEADER + ",extra\n" + ROW + ",7\n", "row 1"),
    ("extra value", HEADER + "\n" + ROW + ",7\n", "row 2"),
    ("columns reordered", HEADER.replace("q1,q2", "q2,q1") + "\n" + ROW + "\n", "row 1"),
    ("not a number", HEADER + "\n" + ROW[:-1] + "abc\n", "row 2"),
    ("semicolons", HEADER + "\n" + ROW.replace(",", ";") + "\n", "row 2"),
])
def test_replay_refuses_a_malformed_csv_in_one_line(built, name, text, says):
    folder, _ = built
    (folder / "bad.csv").write_text(text, newline="")
    out = folder / "bad_out.csv"
    r = subprocess.run(["./replay", "bad.csv", "bad_out.csv"], cwd=folder, capture_output=True, text=True)
    assert r.returncode == 2, (name, r.returncode, r.stderr)
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and "bad.csv" in lines[0] and says in lines[0], (name, r.stderr)
    assert not out.exists()                      # nothing written


def test_replay_on_a_full_disk_exits_3_and_leaves_no_partial_file(built):
    """A write that fails (here the file size limit RLIMIT_FSIZE = 4 KiB, SIGXFSZ
    ignored, so write() fails with EFBIG as on a full disk) ends replay with
    one line and exit 3, the partial output removed (issue 43: it exited 0
    having written 21 of 1,000 rows)."""
    import resource
    import signal

    folder, _ = built
    (folder / "many.csv").write_text(HEADER + "\n" + (ROW + "\n") * 1000, newline="")
    out = folder / "many_out.csv"

    def limit():
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
        resource.setrlimit(resource.RLIMIT_FSIZE, (4096, 4096))

    r = subprocess.run(["./replay", "many.csv", "many_out.csv"], cwd=folder, capture_output=True, text=True,
                       preexec_fn=limit)
    assert r.returncode == 3, (r.returncode, r.stderr)
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and "writing many_out.csv failed" in lines[0] and "removed" in lines[0], r.stderr
    assert not out.exists()
    # the same run without the limit writes every row
    ok = subprocess.run(["./replay", "many.csv", "many_out.csv"], cwd=folder, capture_output=True, text=True)
    assert ok.returncode == 0 and len(out.read_text().splitlines()) == 1001
    out.unlink()


def test_replay_reads_crlf_and_a_missing_final_newline_as_lf(built):
    folder, _ = built
    rows = [ROW, ROW.replace("0.001,", "0.002,", 1)]
    (folder / "lf.csv").write_text(HEADER + "\n" + "\n".join(rows) + "\n", newline="")
    (folder / "crlf.csv").write_text(HEADER + "\r\n" + "\r\n".join(rows), newline="")
    for name in ("lf", "crlf"):
        _run(["./replay", f"{name}.csv", f"{name}_out.csv"], folder)
    lf, crlf = (folder / "lf_out.csv").read_text(), (folder / "crlf_out.csv").read_text()
    assert lf == crlf and len(lf.splitlines()) == 3


# -- a non-finite measurement ------------------------------------------------------------------------

def _steps(ctl, forces):
    """tmt_step over a constant posture with the normal force ``forces[k]`` (N); the return codes,
    the last command and the final state as bytes."""
    p = ctl.default_params()
    s, m, c = ctl.new_state(p), ctl.Measurement(), ctl.Command()
    m.q[0], m.q[1], m.q[2] = 0.0, -0.5, 0.8
    normal = np.array(p.R[:]).reshape(3, 3, order="F")[:, 0]
    codes, before = [], None
    for f in forces:
        force = -normal * f if np.isfinite(f) else np.where(np.arange(3) == np.argmax(np.abs(normal)), f, 0.0)
        m.force[0], m.force[1], m.force[2] = force.tolist()
        before = bytes(c)
        codes.append(ctl.step(p, s, m, c))
    return codes, bytes(c), bytes(s.s), before


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_a_non_finite_force_is_refused_and_does_not_poison_the_state(built, bad):
    """A NaN or infinite force sample (a sensor glitch) made tmt_step return 0 with NaN commands, and
    every later period NaN too. Now that period returns TMT_E_NONFINITE (-1), leaves the command and
    state as they were, and the run continues as if the sample had not come (bit for bit)."""
    _, ctl = built
    forces = [10.0] * 300
    codes, cmd, state, _ = _steps(ctl, forces[:150] + [bad] + forces[150:])
    assert codes[150] == -1 and codes.count(0) == 300
    _, cmd_at, _, before = _steps(ctl, forces[:150] + [bad])
    assert cmd_at == before                          # the command of the refused period is the last good one
    ref_codes, ref_cmd, ref_state, _ = _steps(ctl, forces)
    assert set(ref_codes) == {0} and state == ref_state and cmd == ref_cmd
    out = np.frombuffer(cmd, dtype=float)
    assert np.all(np.isfinite(out))


def test_replay_stops_at_a_non_finite_row_naming_it(built):
    folder, _ = built
    values = ROW.replace("0.001,", "0.002,", 1).split(",")
    values[1 + 6 + 2] = "nan"                    # t, q (3), dq (3), then the force's z component
    nan_row = ",".join(values)
    (folder / "nan.csv").write_text(HEADER + "\n" + ROW + "\n" + nan_row + "\n")
    r = subprocess.run(["./replay", "nan.csv", "nan_out.csv"], cwd=folder, capture_output=True, text=True)
    assert r.returncode == 1 and "row 3" in r.stderr and "non-finite" in r.stderr, r.stderr


# -- tmt_init from edited parameters -------------------------------------------------------------------

EDITED = ["controller.x_e_error=0.002", "impedance.b=[100.0, 20.0, 20.0]", "controller.law.initial_stiffness=5000.0"]


def test_parameters_edited_before_tmt_init_start_the_controller_as_their_export(tmp_path):
    """The README's pattern: tmt_default_params, edit fields, tmt_init. tmt_init ignored params and started
    from the exported scenario's state (its surface estimate x_e_hat, scheduled damping b_n and the RLS
    law's initial estimates), so a controller with x_e_hat edited to 2 mm commanded up to 2 m away from
    one exported with that value. Now both run bit for bit alike: the exported library with edited
    parameters against the library exported from the scenario with those values."""
    base = ["controller.law=rls", "controller.damping_schedule.kind='zeta'"]
    ctl = {}
    for name, sets in (("exported", base), ("edited", base + EDITED)):
        folder = tmp_path / name
        folder.mkdir()
        export_controller(apply_overrides(paper_scenario(), sets), folder, True)
        _run(["gcc", "-std=c99", "-O0", "-fPIC", "-shared", "tmt_controller.c", "-o", "lib.so", "-lm"], folder)
        ctl[name] = CompiledController(folder, library=folder / "lib.so")
    want = ctl["edited"].default_params()
    edited = ctl["exported"].Params.from_buffer_copy(bytes(want))
    assert bytes(edited) != bytes(ctl["exported"].default_params())        # the edit changes parameters
    runs = []
    for c, p in ((ctl["exported"], edited), (ctl["edited"], want)):
        s, m, cmd = c.new_state(p), c.Measurement(), c.Command()
        first = bytes(s.s)
        m.q[1], m.q[2] = -0.5, 0.8
        for k in range(300):
            m.force[0] = -5.0 if k > 100 else 0.0
            assert c.step(p, s, m, cmd) == 0
        runs.append((first, bytes(cmd), bytes(s.s)))
    assert runs[0] == runs[1]


# -- heavy: compilers, sanitizers, valgrind, the header, the Makefile, replay of every structure --------

VARIANTS = {
    "tmt": [], "known": ["controller.law=known"], "integral": ["controller.law=integral"],
    "adaptive_damping": ["controller.law=adaptive_damping"], "rls": ["controller.law=rls"],
    "delay 1": ["controller.delay_samples=1"], "delay 2": ["controller.delay_samples=2"],
    "delay 20": ["controller.delay_samples=20", "controller.law=rls"],
    "force filter": ["sensor.filter_cutoff=50.0"], "damping schedule": ["controller.damping_schedule.kind='zeta'"],
    "model mismatch": ["robot.model_mass_scale=1.1"], "x_e error": ["controller.x_e_error=0.001"],
    "guarded approach": ["trajectory.approach_gap=0.002", "controller.damping_schedule.kind='zeta'"],
}


def _compilers():
    return [cc for cc in ("gcc", "clang") if shutil.which(cc)]


@pytest.mark.heavy
@pytest.mark.parametrize("variant", list(VARIANTS))
def test_replay_from_tmt_init_equals_the_simulation_for_every_structure(tmp_path, variant):
    """replay starts from tmt_init's state (the software-in-the-loop run copies the simulator's initial
    state in, so only replay tests the exported initial state, e.g. in the guarded approach)."""
    sc = apply_overrides(paper_scenario(), ["trajectory.cycles=0.5", *VARIANTS[variant]])
    res = Simulator(sc).run()
    write_measurements(res, tmp_path / "measurements.csv")
    for inner in (True, False):
        folder = tmp_path / f"c{int(inner)}"
        folder.mkdir()
        export_controller(sc, folder, inner)
        _run(["gcc", *STRICT, "-O2", "-ffp-contract=off", "replay.c", "tmt_controller.c", "-lm", "-o", "replay"],
             folder)
        _run(["./replay", "../measurements.csv", "commands.csv"], folder)
        cmd = read_commands(folder / "commands.csv")
        checks = {("x_c1", "x_c2", "x_c3"): res.command_task, ("x_r1", "x_r2", "x_r3"): res.reference_task,
                  ("f_m",): res.measured_force[None], ("b_n",): res.damping[None],
                  ("f_d",): res.desired_force[None]}
        if inner:
            checks[("tau1", "tau2", "tau3")] = res.tau
        for cols, logged in checks.items():
            assert rel_err(np.vstack([cmd[c] for c in cols]), logged) < RTOL, (variant, inner, cols)


@pytest.mark.heavy
@pytest.mark.parametrize("variant", ["tmt", "delay 20", "guarded approach"])
@pytest.mark.parametrize("inner", [False, True])
def test_compiles_warning_free_at_every_optimisation_level(tmp_path, variant, inner):
    sc = apply_overrides(paper_scenario(), VARIANTS[variant])
    export_controller(sc, tmp_path, inner)
    assert "gcc" in _compilers()
    for cc in _compilers():
        for opt in ("-O0", "-O2", "-O3"):
            for src in ("replay.c", "example_loop.c"):
                r = _run([cc, *STRICT, opt, src, "tmt_controller.c", "-lm", "-o", "a.out"], tmp_path)
                assert r.stderr == "", (cc, opt, src, r.stderr)


@pytest.mark.heavy
@pytest.mark.parametrize("variant", ["tmt", "delay 20", "guarded approach"])
def test_replay_is_clean_under_the_sanitizers_and_valgrind(tmp_path, variant):
    sc = apply_overrides(paper_scenario(), ["trajectory.cycles=0.25", *VARIANTS[variant]])
    write_measurements(Simulator(sc).run(), tmp_path / "measurements.csv")
    folder = tmp_path / "c"
    folder.mkdir()
    export_controller(sc, folder, True)
    san = ["-g", "-O1", "-fsanitize=address,undefined", "-fno-sanitize-recover=all", "-fno-omit-frame-pointer"]
    for cc in _compilers():
        _run([cc, *STRICT, *san, "replay.c", "tmt_controller.c", "-lm", "-o", f"replay_{cc}"], folder)
        r = _run([f"./replay_{cc}", "../measurements.csv", f"commands_{cc}.csv"], folder)
        assert "runtime error" not in r.stderr and "Sanitizer" not in r.stderr, r.stderr
        # a malformed file goes through the error paths (their frees) too
        (folder / "bad.csv").write_text(HEADER + "\n" + ROW + ",1\n")
        r = subprocess.run([f"./replay_{cc}", "bad.csv", "x.csv"], cwd=folder, capture_output=True, text=True)
        assert r.returncode == 2 and "Sanitizer" not in r.stderr and len(r.stderr.splitlines()) == 1, r.stderr
    if shutil.which("valgrind"):
        _run(["gcc", *STRICT, "-g", "-O0", "replay.c", "tmt_controller.c", "-lm", "-o", "replay_vg"], folder)
        for args in (["../measurements.csv", "commands_vg.csv"], ["bad.csv", "x.csv"]):
            r = subprocess.run(["valgrind", "--error-exitcode=99", "--leak-check=full", "--errors-for-leak-kinds=all",
                                "./replay_vg", *args], cwd=folder, capture_output=True, text=True)
            assert r.returncode in (0, 2) and "ERROR SUMMARY: 0 errors" in r.stderr, r.stderr[-2000:]
        assert (folder / "commands_vg.csv").read_text() == (folder / "commands_gcc.csv").read_text()


CXX_USER = r"""
#include "tmt_controller.h"
#include <cstdio>
int main()
{
    static tmt_params params;
    static tmt_state a, b;
    tmt_measurement meas = {};
    tmt_command cmd;
    tmt_default_params(&params);
    tmt_init(&params, &a);
    tmt_init(&params, &b);
    meas.q[1] = -0.5;
    meas.q[2] = 0.8;
    int rc = tmt_step(&params, &a, &meas, &cmd);
    std::printf("%d %.17g\n", rc, cmd.x_c[0]);
    return rc;
}
"""

C_HEADER_ONLY = '#include "tmt_controller.h"\nint tmt_user_size(void) { return (int)sizeof(tmt_state); }\n'


@pytest.mark.heavy
@pytest.mark.parametrize("inner", [False, True])
def test_the_header_is_self_contained_and_links_from_cpp(tmp_path, inner):
    export_controller(paper_scenario(), tmp_path, inner)
    (tmp_path / "only.c").write_text(C_HEADER_ONLY)
    (tmp_path / "user.cpp").write_text(CXX_USER)
    for cc in _compilers():
        r = _run([cc, *STRICT, "-c", "only.c", "-o", "only.o"], tmp_path)
        assert r.stderr == ""
    _run(["gcc", *STRICT, "-O2", "-c", "tmt_controller.c", "-o", "tmt.o"], tmp_path)
    if shutil.which("g++"):
        r = _run(["g++", "-std=c++11", "-Wall", "-Wextra", "-Werror", "-pedantic", "user.cpp", "tmt.o", "-lm",
                  "-o", "user"], tmp_path)
        out = _run(["./user"], tmp_path).stdout.split()
        assert out[0] == "0" and np.isfinite(float(out[1]))
    syms = _run(["nm", "tmt.o"], tmp_path).stdout
    kinds = {line.split()[-2] for line in syms.splitlines() if len(line.split()) >= 2}
    assert not kinds & set("DdBbCG"), syms      # no writable global data


@pytest.mark.heavy
def test_the_makefile_builds_from_a_copy_twice_and_cleans(tmp_path):
    export_controller(paper_scenario(), tmp_path / "orig", False)
    copy = tmp_path / "elsewhere" / "copy"
    shutil.copytree(tmp_path / "orig", copy)
    exported = {p.name for p in copy.iterdir()}
    _run(["make"], copy)
    built = {p.name for p in copy.iterdir()} - exported
    assert {"libtmt_controller.a", "replay", "example_loop", "tmt_controller.o"} <= built
    assert "Nothing to be done" in _run(["make"], copy).stdout
    _run(["./example_loop", "5"], copy)
    _run(["make", "clean"], copy)
    assert {p.name for p in copy.iterdir()} == exported


@pytest.mark.parametrize("edit", ["kd[0]=nan", "kp[0]=nan", "kp[0]=inf", "tau_max[0]=nan", "tau_max[1]=-5.0",
                                  "dq[1]=nan", "dq[1]=1e160", "dq[0]=-1e200"])
def test_a_bad_input_behind_the_torque_clip_is_refused(built, edit):
    """Regression (review 11): with the torque clip on, a NaN or infinite gain made every torque NaN,
    which the clip's fmin/fmax turned into +-tau_max: full reverse torque on joint 2 with return code 0
    (a NaN tau_max removed the clip, a negative one pinned the torque). The inputs are checked now:
    that period returns TMT_E_NONFINITE (-1) and leaves the command as it was. The same edit without
    the bad value (the clip at [5, 18, 10] N m, engaged) steps with 0 and a torque within the clip. Review 14:
    a finite but huge measurement (a corrupt encoder word: dq = 1e160 rad/s) overflows to a NaN torque inside
    the law, which the clip turned into +-tau_max too: the clip now passes a NaN or infinite torque on."""
    _, ctl = built
    p = ctl.default_params()
    s, m, c = ctl.new_state(p), ctl.Measurement(), ctl.Command()
    m.q[0], m.q[1], m.q[2] = 0.0, -0.5, 0.8
    normal = np.array(p.R[:]).reshape(3, 3, order="F")[:, 0]
    m.force[0], m.force[1], m.force[2] = (-normal * 10.0).tolist()
    p.tau_max[0], p.tau_max[1], p.tau_max[2] = 5.0, 18.0, 10.0
    assert ctl.step(p, s, m, c) == 0
    tau = np.array(c.tau[:])
    assert np.all(np.abs(tau) <= [5.0, 18.0, 10.0]) and np.any(np.abs(tau) == [5.0, 18.0, 10.0])  # it engaged
    field, value = edit.split("=")
    name, index = field[:-3], int(field[-2])
    getattr(m if name == "dq" else p, name)[index] = float(value)
    before = bytes(c)
    # a finite limit <= 0 is out of its range (review 25: -5 returned -1, as if non-finite); a NaN is non-finite
    assert ctl.step(p, s, m, c) == (-2 if edit == "tau_max[1]=-5.0" else -1)
    assert bytes(c) == before


def test_tmt_init_refuses_a_non_finite_parameter(built):
    """Regression (review 14): tmt_init returned 0 with x_e_hat NaN and built a NaN state, so every later
    tmt_step returned -1 even after the parameter was corrected (until tmt_init was called again), the
    'last good command' being whatever the caller had zeroed. Now tmt_init returns TMT_E_NONFINITE; with
    the parameter corrected it returns 0 and the controller steps."""
    _, ctl = built
    p = ctl.default_params()
    s = ctl.State()
    p.x_e_hat = float("nan")
    assert ctl._init(ctypes.byref(p), ctypes.byref(s)) == -1
    p.x_e_hat = float("inf")
    assert ctl._init(ctypes.byref(p), ctypes.byref(s)) == -1
    p.x_e_hat = 0.0
    assert ctl._init(ctypes.byref(p), ctypes.byref(s)) == 0
    m, c = ctl.Measurement(), ctl.Command()
    m.q[0], m.q[1], m.q[2] = 0.0, -0.5, 0.8
    assert ctl.step(p, s, m, c) == 0


# -- a finite parameter outside its range (review 24) --------------------------------------------------

def _sheared(p):
    p.R[1] += 0.01           # column 1 no longer a unit vector orthogonal to the others


def _scaled(p):
    for i in range(9):
        p.R[i] *= 2.0


def _mirrored(p):            # orthonormal columns, determinant -1: a reflection, not a rotation
    for i in range(3):
        p.R[6 + i] = -p.R[6 + i]


@pytest.mark.parametrize("change", [
    lambda p: setattr(p, "alpha", 1.5), lambda p: setattr(p, "alpha", -0.1), lambda p: setattr(p, "Ts", -1e-3),
    lambda p: p.m.__setitem__(0, -1.0), lambda p: setattr(p, "f_d", -10.0),
    lambda p: setattr(p, "law_min_stiffness", -100.0), lambda p: setattr(p, "sched", 0.5),
    lambda p: setattr(p, "b_max", 0.5), lambda p: setattr(p, "k_hat_min", 2e7), _sheared, _scaled, _mirrored,
    lambda p: p.tau_max.__setitem__(0, 0.0)],
    ids=["alpha 1.5", "alpha -0.1", "Ts < 0", "m < 0", "f_d < 0", "law min_stiffness < 0", "sched 0.5",
         "b_max < b_min", "k_hat_min > k_hat_max", "R sheared", "R scaled", "R mirrored", "tau_max 0"])
def test_a_parameter_outside_its_range_is_refused(built, change):
    """Review 24: tmt_step checked only that parameters are finite, so alpha = 1.5 commanded 4e99 m,
    Ts < 0 or a negative mass 1e12-1e13 m, a scaled R a wrong depth, all with return code 0. A
    finite parameter outside its valid range now makes tmt_init and tmt_step return TMT_E_RANGE
    (-2), the step leaving state and command as they were; the exported defaults pass."""
    _, ctl = built
    p = ctl.default_params()
    s, m, c = ctl.new_state(p), ctl.Measurement(), ctl.Command()
    assert ctl._init(ctypes.byref(p), ctypes.byref(s)) == 0
    m.q[0], m.q[1], m.q[2] = 0.0, -0.5, 0.8
    normal = np.array(p.R[:]).reshape(3, 3, order="F")[:, 0]
    m.force[0], m.force[1], m.force[2] = (-10.0 * normal).tolist()
    assert [ctl.step(p, s, m, c) for _ in range(3)] == [0, 0, 0]
    state, cmd = bytes(s.s), bytes(c)
    change(p)
    assert ctl.step(p, s, m, c) == -2
    assert bytes(s.s) == state and bytes(c) == cmd
    assert ctl._init(ctypes.byref(p), ctypes.byref(ctl.State())) == -2
    header = (built[0] / "tmt_controller.h").read_text()
    assert "#define TMT_E_RANGE (-2)" in header and "(0: no filter); valid [0, 1) [1; -]" in header


def test_the_schedule_switched_on_at_run_time_schedules_as_its_export(built, tmp_path):
    """Review 24: an export without the damping schedule wrote placeholders for its bounds (b_min 0,
    b_max 1, k_hat 1): setting sched = 1 at run time, as the header allows, held the normal damping
    at 1 N s/m (a damping ratio of 0.007). Its defaults are now the schema's, so the schedule
    switched on in the paper's export runs bit for bit as the export of the scenario with
    damping_schedule.kind = "zeta" (its b_n, command and state over 300 periods)."""
    _, plain = built
    folder = tmp_path / "sched"
    folder.mkdir()
    export_controller(apply_overrides(paper_scenario(), ["controller.damping_schedule.kind='zeta'"]), folder, True)
    _run(["gcc", "-std=c99", "-O0", "-fPIC", "-shared", "tmt_controller.c", "-o", "libtmt.so", "-lm"], folder)
    sched = CompiledController(folder, library=folder / "libtmt.so")
    runs = []
    for ctl, on in ((plain, True), (sched, False)):
        p = ctl.default_params()
        if on:
            assert p.sched == 0.0
            p.sched = 1.0
        s, m, c = ctl.new_state(p), ctl.Measurement(), ctl.Command()
        m.q[0], m.q[1], m.q[2] = 0.0, -0.5, 0.8
        normal = np.array(p.R[:]).reshape(3, 3, order="F")[:, 0]
        b_n = []
        for k in range(300):
            m.force[0], m.force[1], m.force[2] = (-min(10.0, 0.1 * k) * normal).tolist()
            assert ctl.step(p, s, m, c) == 0
            b_n.append(c.b_n)
        runs.append((b_n, bytes(c), bytes(s.s)))
    assert runs[0] == runs[1]
    assert max(runs[0][0]) > 20.0         # scheduled: eq. (25) raised the damping far above b_min = 1


def test_an_rls_range_with_its_ends_swapped_is_refused(tmp_path):
    """Review 25: the RLS law's schema refuses min_stiffness > max_stiffness, the C accepted it
    (tmt_init 0). A law parameter max_X is held >= its min_X in the C too."""
    folder = tmp_path / "rls"
    export_controller(apply_overrides(paper_scenario(), ["controller.law=rls"]), folder, True)
    _run(["gcc", "-std=c99", "-O0", "-fPIC", "-shared", "tmt_controller.c", "-o", "libtmt.so", "-lm"], folder)
    ctl = CompiledController(folder, library=folder / "libtmt.so")
    p = ctl.default_params()
    assert ctl._init(ctypes.byref(p), ctypes.byref(ctl.State())) == 0
    p.law_min_stiffness = 2.0 * p.law_max_stiffness
    assert ctl._init(ctypes.byref(p), ctypes.byref(ctl.State())) == -2


@pytest.mark.heavy      # compiles the paper's exported controller five times (~5 s)
def test_fast_math_which_would_delete_the_nan_checks_is_refused_at_compile_time(tmp_path):
    """Review 66: built with -Ofast (or -ffast-math, -ffinite-math-only) the compiler may assume every value
    finite and deleted tmt_step's isfinite() checks: a NaN force returned 0 and left the state NaN for good.
    The wrapper refuses to compile under those flags, naming them; the Makefile's flags compile."""
    export_controller(paper_scenario(), tmp_path, True)
    for cc in _compilers():
        for flags in (["-Ofast"], ["-O2", "-ffast-math"], ["-O2", "-ffinite-math-only"]):
            r = subprocess.run([cc, "-std=c99", *flags, "-c", "tmt_controller.c", "-o", "t.o"], cwd=tmp_path,
                               capture_output=True, text=True)
            assert r.returncode != 0 and "build it without -ffast-math" in r.stderr, (cc, flags, r.stderr)
        _run([cc, *STRICT, "-O2", "-ffp-contract=off", "-c", "tmt_controller.c", "-o", "t.o"], tmp_path)


@pytest.mark.heavy      # the Panda's controller compiled at -O0 (~10 s)
def test_bench_counts_the_calls_the_controller_refused(built, tmp_path):
    """Review 66: `replay --bench` without a measurement CSV timed the Panda's tmt_step on all-zero
    measurements, which it refuses every time (a degenerate frame), and printed a median as if the law ran.
    It now counts the refused calls, says so and exits 1; the paper's accepted calls still exit 0."""
    from tmtcontrol import load_scenario

    export_controller(load_scenario("panda"), tmp_path, True)
    _run(["gcc", *STRICT, "-O0", "replay.c", "tmt_controller.c", "-lm", "-o", "replay"], tmp_path)
    r = subprocess.run(["./replay", "--bench", "100"], cwd=tmp_path, capture_output=True, text=True)
    assert r.returncode == 1 and "median" in r.stdout, (r.stdout, r.stderr)
    assert r.stderr.startswith("replay: --bench: 100 of 100 calls returned an error"), r.stderr
    folder, _ = built
    r = subprocess.run(["./replay", "--bench", "100"], cwd=folder, capture_output=True, text=True)
    assert (r.returncode, r.stderr) == (0, ""), r.stderr
