"""Outputs never destroy a user's files; unwritable targets, interrupts and huge
runs fail with one line; the compile cache survives damage."""
import json
import os
import signal
import subprocess
import sys
import time

import pytest

from tmtcontrol.cli import main
from tmtcontrol.files import MANIFEST

CLI = [sys.executable, "-m", "tmtcontrol.cli"]
SHORT = ["--set", "trajectory.cycles=0.1", "--no-plots"]


def run(args, **kw):
    return subprocess.run(CLI + args, capture_output=True, text=True, **kw)


def one_line(stderr):
    lines = stderr.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in stderr, stderr
    return lines[0]


def hidden_litter(folder):
    return [p.name for p in folder.iterdir() if p.name.startswith(".") and "tmt-" in p.name or ".old-" in p.name]


@pytest.mark.parametrize("args,flag", [
    (["simulate", *SHORT], "--out"),
    (["report"], "--out"),
    (["analyze", "--m", "1", "--b", "60", "--k", "100", "--ke", "5000"], "--plot"),
    (["design", "--m", "1", "--k", "100", "--ke-min", "2000", "--ke-max", "20000", "--ts", "0.001",
      "--max-overshoot", "5", "--mp", "3.3"], "--plot"),
])
def test_user_folder_is_never_touched(tmp_path, args, flag):
    user = tmp_path / "mine"
    user.mkdir()
    (user / "thesis.tex").write_text("precious")
    r = run([*args, flag, str(user)])
    assert r.returncode == 2
    line = one_line(r.stderr)
    assert flag in line and "did not write" in line
    assert (user / "thesis.tex").read_text() == "precious"
    assert sorted(p.name for p in user.iterdir()) == ["thesis.tex"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["mine"]
    if args[0] == "report":     # refused before anything is computed: no stage reported (no timing here)
        assert "[1/" not in r.stderr


def test_out_dot_and_empty_are_refused(tmp_path):
    (tmp_path / "notes.txt").write_text("keep")
    r = run(["simulate", *SHORT, "--out", "."], cwd=tmp_path)
    assert r.returncode == 2 and "--out" in one_line(r.stderr)
    assert (tmp_path / "notes.txt").read_text() == "keep"
    r = run(["simulate", *SHORT, "--out", ""], cwd=tmp_path)
    assert r.returncode == 2 and "--out: empty path" in one_line(r.stderr)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["notes.txt"]


@pytest.mark.parametrize("target", ["/proc/tmt-x", "{file}/below", "/sys/tmt-x"])
def test_unwritable_target_is_one_line(tmp_path, target):
    (tmp_path / "f").write_text("x")
    r = run(["simulate", *SHORT, "--out", target.format(file=tmp_path / "f")])
    assert r.returncode == 2
    assert one_line(r.stderr).startswith("error: --out: cannot write")


def test_previous_output_is_replaced_but_not_foreign_files(tmp_path):
    out = tmp_path / "o"
    assert main(["simulate", *SHORT, "--out", str(out)]) == 0
    manifest = json.loads((out / MANIFEST).read_text())
    assert manifest["written_by"] == "tmtcontrol" and set(manifest["files"]) == {"timeseries.csv", "summary.json"}
    first = (out / "summary.json").stat().st_mtime_ns
    assert main(["simulate", *SHORT, "--out", str(out)]) == 0      # a previous output: replaced whole
    assert (out / "summary.json").stat().st_mtime_ns != first
    (out / "my-notes.txt").write_text("mine")                     # now it holds a user's file
    assert main(["simulate", *SHORT, "--out", str(out)]) == 2
    assert (out / "my-notes.txt").read_text() == "mine"
    # a failing run leaves the previous output untouched
    (out / "my-notes.txt").unlink()
    assert main(["simulate", "--out", str(out), "--set", "controller.f_d=0"]) == 2
    assert (out / "summary.json").exists() and hidden_litter(tmp_path) == []


@pytest.mark.heavy
def test_huge_run_is_refused_with_estimate_and_limit_can_be_raised(tmp_path):
    r = run(["simulate", "--set", "trajectory.cycles=1000", "--set", "controller.rate=1e4",
             "--out", str(tmp_path / "o")])
    assert r.returncode == 2
    line = one_line(r.stderr)
    assert "40,000,000 control steps" in line and "GiB" in line and "--max-steps" in line
    assert not (tmp_path / "o").exists()
    r = run(["simulate", "--set", "trajectory.cycles=0.5", "--max-steps", "1000", "--no-plots",
             "--out", str(tmp_path / "o")])
    assert r.returncode == 2 and "2,000 control steps" in one_line(r.stderr)
    r = run(["simulate", "--set", "trajectory.cycles=0.5", "--max-steps", "2000", "--no-plots",
             "--out", str(tmp_path / "o")])
    assert r.returncode == 0, r.stderr


def _wait_for_staging(p, folder):
    """Block until the program has made its staging folder in ``folder`` (it computes after that),
    whatever the machine's speed or load; fail if it exits first."""
    while not any(folder.iterdir()):
        if p.poll() is not None:
            pytest.fail(f"exited ({p.returncode}) before making its staging folder: {p.stderr.read()}")
        time.sleep(0.01)


@pytest.mark.heavy          # 2-3 s each on the 2026-12-07 machine (the README's command stays under 3 min)
@pytest.mark.parametrize("sig,code", [(signal.SIGINT, 130), (signal.SIGTERM, 143)])
def test_interrupt_exits_cleanly_and_leaves_nothing(tmp_path, sig, code):
    out = tmp_path / "o"
    p = subprocess.Popen(CLI + ["simulate", "--set", "trajectory.cycles=200", "--no-plots", "--out", str(out)],
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    _wait_for_staging(p, tmp_path)          # computing now: the run has seconds of work left
    p.send_signal(sig)
    _, err = p.communicate(timeout=60)
    assert p.returncode == code, err
    assert "interrupted" in one_line(err)
    assert list(tmp_path.iterdir()) == []


def test_interrupt_during_design_is_not_a_result(tmp_path):
    p = subprocess.Popen(CLI + ["design", "--m", "1", "--k", "100", "--ke-min", "2000", "--ke-max", "20000",
                                "--ts", "0.001", "--max-overshoot", "5", "--mp", "3.3", "--optimize-k",
                                "--plot", str(tmp_path / "p")],
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    _wait_for_staging(p, tmp_path)          # the design computes from here (several seconds: scan, then IPOPT)
    p.send_signal(signal.SIGINT)
    out, err = p.communicate(timeout=60)
    assert p.returncode == 130 and out == "" and "interrupted" in one_line(err), (p.returncode, out, err)
    assert list(tmp_path.iterdir()) == []


@pytest.mark.heavy
def test_parallel_writers_leave_one_valid_folder(tmp_path):
    out = tmp_path / "o"
    procs = [subprocess.Popen(CLI + ["simulate", *SHORT, "--out", str(out)], stdout=subprocess.PIPE,
                              stderr=subprocess.PIPE, text=True) for _ in range(3)]
    results = [(p.wait(timeout=120), p.stderr.read()) for p in procs]
    for code, err in results:
        assert code == 0 and "Traceback" not in err, err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["o"]
    assert set(json.loads((out / MANIFEST).read_text())["files"]) == {"timeseries.csv", "summary.json"}


def test_timeseries_csv_is_what_numpy_savetxt_writes(paper_result, tmp_path):
    """write_timeseries formats all rows in one call; np.savetxt with the same
    format and header is the independent reference (byte for byte), and the
    file reads back within the 9 significant digits it keeps."""
    import numpy as np

    from tmtcontrol.simulation.output import TIMESERIES_COLUMNS, write_timeseries

    r = paper_result
    write_timeseries(r, tmp_path / "ours.csv")
    data = np.column_stack([r.time, r.contact_force, r.measured_force, r.desired_force, r.stiffness,
                            r.stiffness_estimate, r.position.T, r.reference_position.T,
                            r.command_position.T, r.q.T, r.dq.T, r.tau.T])
    np.savetxt(tmp_path / "ref.csv", data, fmt="%.9g", delimiter=",", header=",".join(TIMESERIES_COLUMNS),
               comments="")
    assert (tmp_path / "ours.csv").read_bytes() == (tmp_path / "ref.csv").read_bytes()
    back = np.loadtxt(tmp_path / "ours.csv", delimiter=",", skiprows=1)
    np.testing.assert_allclose(back, data, rtol=1e-8, atol=0)         # '%.9g': relative 5e-9


def _children(ignore: set[int] = frozenset()) -> list[int]:
    """This process' children, less ``ignore`` (those alive before the code
    under test ran, such as multiprocessing's resource tracker that an
    earlier test in this worker started and that lives as long as it)."""
    import os
    import pathlib

    me = str(os.getpid())
    out = []
    for stat in pathlib.Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        if fields[1] == me and int(stat.parent.name) not in ignore:      # the parent pid
            out.append(int(stat.parent.name))
    return out


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="the forked half is Linux-only (else: one process)")
def test_timeseries_in_two_processes_is_the_same_file(paper_result, tmp_path, monkeypatch):
    """processes=2 (the second half of the rows formatted by a forked
    process) writes the same bytes as one process, also when the fork fails
    or the forked process dies (its half is then formatted here), and
    leaves no process behind."""
    import os

    import tmtcontrol.drawing
    from tmtcontrol.simulation.output import write_timeseries

    before = set(_children())
    write_timeseries(paper_result, tmp_path / "one.csv")
    one = (tmp_path / "one.csv").read_bytes()
    forks, fork = [], os.fork
    monkeypatch.setattr(os, "fork", lambda: forks.append(1) or fork())
    write_timeseries(paper_result, tmp_path / "two.csv", processes=2)
    assert (tmp_path / "two.csv").read_bytes() == one
    assert _children(before) == []
    assert forks == [1]                     # the second half really was formatted elsewhere (mutation run 13)
    # one row has no second half to hand over: formatted here, the same file (a split of it wrote an empty line)
    import types

    fields = ("time", "contact_force", "measured_force", "desired_force", "stiffness", "stiffness_estimate")
    arrays = ("position", "reference_position", "command_position", "q", "dq", "tau")
    row1 = types.SimpleNamespace(**{f: getattr(paper_result, f)[:1] for f in fields},
                                 **{a: getattr(paper_result, a)[:, :1] for a in arrays}, orientation_error=None)
    write_timeseries(row1, tmp_path / "row1.csv")
    write_timeseries(row1, tmp_path / "row2.csv", processes=2)
    assert (tmp_path / "row2.csv").read_bytes() == (tmp_path / "row1.csv").read_bytes() and forks == [1]
    assert (tmp_path / "row1.csv").read_bytes().count(b"\n") == 2             # the header and the row
    monkeypatch.setattr(os, "fork", fork)

    def dies(fd, data):                       # what the forked process calls to hand its half back
        os._exit(3)

    monkeypatch.setattr(tmtcontrol.drawing, "write_all", dies)
    write_timeseries(paper_result, tmp_path / "died.csv", processes=2)
    assert (tmp_path / "died.csv").read_bytes() == one

    def no_fork():
        raise OSError("no process to spare")

    monkeypatch.setattr(os, "fork", no_fork)
    write_timeseries(paper_result, tmp_path / "unforked.csv", processes=2)
    assert (tmp_path / "unforked.csv").read_bytes() == one
    with pytest.raises(ValueError, match="processes: 1 or 2, got 3"):
        write_timeseries(paper_result, tmp_path / "x.csv", processes=3)


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="the forked half is Linux-only")
def test_forked_half_is_killed_when_the_writer_stops_early(tmp_path, monkeypatch):
    """An error (or Ctrl-C) in this process while the forked half is being
    formatted kills that process (it is not waited for) and reaps it. The
    forked process here formats forever; a watchdog kills it after 20 s if
    the writer waited for it instead."""
    import os
    import threading

    import tmtcontrol.simulation.output as output

    started = tmp_path / "pid"

    def forever(data, row):                   # what the forked process formats with
        started.write_text(str(os.getpid()))
        while True:
            signal.pause()

    monkeypatch.setattr(output, "_rows", forever)
    waited = []

    def watchdog():
        waited.append(True)
        os.kill(int(started.read_text()), signal.SIGKILL)

    timer = threading.Timer(20.0, watchdog)
    before = set(_children())
    with pytest.raises(RuntimeError, match="stopped"):
        with output._formatted_elsewhere(None, "%.9g"):
            for _ in range(2000):             # until the forked process is formatting (at most 20 s)
                if started.exists() and started.read_text():
                    break
                time.sleep(0.01)
            assert len(_children(before)) == 1
            timer.start()
            raise RuntimeError("stopped")
    timer.cancel()
    assert not waited, "the writer waited for the forked process instead of killing it"
    assert _children(before) == []


def test_a_signal_raised_inside_a_c_extension_is_an_interruption_not_a_traceback(monkeypatch, capsys):
    """CI saw Ctrl-C during `design` end in a traceback: the handler's exception, raised while CasADi's C code
    ran, came back as "SystemError: <method 'get' of 'dict' objects> returned a result with an exception set"
    (its cause the signal's exception). That is an interruption: one line, exit 130."""
    from tmtcontrol import cli
    from tmtcontrol.files import Interrupted

    def c_call_interrupted(args):
        try:
            raise Interrupted(2)
        except Interrupted as exc:
            raise SystemError("<method 'get' of 'dict' objects> returned a result with an exception set") from exc

    monkeypatch.setattr(cli, "_cache", c_call_interrupted)
    assert cli.main(["cache"]) == 130
    assert one_line(capsys.readouterr().err).startswith("interrupted (Ctrl-C)")

    def a_real_system_error(args):
        raise SystemError("a bug, not a signal")

    monkeypatch.setattr(cli, "_cache", a_real_system_error)
    with pytest.raises(SystemError, match="a bug"):
        cli.main(["cache"])


@pytest.mark.heavy
def test_a_ctrl_c_after_the_commit_says_what_was_written(tmp_path, capsys, monkeypatch):
    """Regression (review 13): simulate commits its folder, then prints the results; a Ctrl-C during
    that printing said "nothing was written" (exit 130) of a folder it had just written, replacing
    the previous output. Now the line names the folder, written in full (a commit is atomic); a
    Ctrl-C before the commit still says nothing was written, and the target is as it was."""
    import tmtcontrol.simulation.metrics as metrics
    from tmtcontrol.cli import main
    from tmtcontrol.files import MANIFEST

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    out = tmp_path / "o"
    run = ["simulate", "--no-plots", "--set", "trajectory.cycles=0.05", "--out", str(out)]
    monkeypatch.setattr(metrics, "format_table", interrupted)          # printed after the commit
    assert main(run) == 130
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [f"interrupted (Ctrl-C): {out} had been written in full before it"]
    assert (out / MANIFEST).is_file()
    before = (out / MANIFEST).read_bytes()
    monkeypatch.setattr(metrics, "segment_metrics", interrupted)      # the limit's check runs before the commit
    assert main(run) == 130
    assert capsys.readouterr().err.strip().splitlines() == ["interrupted (Ctrl-C): nothing was written"]
    assert (out / MANIFEST).read_bytes() == before


@pytest.mark.skipif(not __import__("os").path.exists("/dev/full"), reason="needs Linux's /dev/full")
@pytest.mark.parametrize("args", [["scenario", "paper"], ["cache", "--info"],
                                  # argparse's own output (review 13 left them: argparse swallowed the error, exit 0)
                                  ["--help"], ["--version"], ["simulate", "--help"], []])
def test_a_full_standard_output_is_one_line_and_exit_3(args):
    """Regression (review 13): ``tmtcontrol scenario paper > my.toml`` on a full disk ended in an
    OSError traceback, exit 1. Now one line on stderr and exit 3 (the code of an output not saved)."""
    with open("/dev/full", "w") as full:
        r = subprocess.run([sys.executable, "-m", "tmtcontrol.cli", *args], stdout=full, stderr=subprocess.PIPE,
                           text=True)
    assert r.returncode == 3
    assert r.stderr.strip().splitlines() == ["error: writing the standard output: No space left on device; "
                                             "what it shows is incomplete"]


@pytest.mark.parametrize("args", [["scenario", "paper"],
                                  # heavy (docs/testing.md's 2 s rule): 2.1 s on 2026-12-07's machine
                                  pytest.param(["analyze", "--m", "1", "--b", "60", "--k", "100", "--ke", "2000"],
                                               marks=pytest.mark.heavy)])
def test_a_standard_output_whose_reader_has_gone_is_one_line_and_exit_3(args):
    """Review 51: ``tmtcontrol simulate ... | head -1`` (and analyze, design, compare, sweep, robot,
    report) ended in a BrokenPipeError traceback, exit 1, the code of a failed verdict. A pipe whose
    read end is closed before the command writes: one line on stderr, exit 3, as for a full disk."""
    import os

    r_end, w_end = os.pipe()
    os.close(r_end)
    try:
        r = subprocess.run([sys.executable, "-m", "tmtcontrol.cli", *args], stdout=w_end, stderr=subprocess.PIPE,
                           text=True)
    finally:
        os.close(w_end)
    assert r.returncode == 3, r.stderr
    assert r.stderr.strip().splitlines() == ["error: writing the standard output: Broken pipe; what it shows is "
                                             "incomplete"]


def test_a_cvodes_run_that_fails_is_one_line_and_exit_1(tmp_path, capfd):
    """Regression (review 13): a run whose CVODES integrator stopped (here a reference f_d/k = 1e7 m
    deep on a 1e8 N/m surface: the state runs away and CVODES gives up) ended in a RuntimeError
    traceback after ~100 lines of SUNDIALS and CasADi warnings and input dumps on the terminal (exit 1
    by accident); a sweep over such a case aborted. Now it is the simulator's 'diverged' verdict: one
    line naming CVODES' flag, exit 1."""
    from tmtcontrol.cli import main

    out = tmp_path / "o"
    assert main(["simulate", "--integrator", "cvodes", "--set", "environment.stiffness.values=[1e8]", "--set",
                 "impedance.k=[0.001, 100.0, 100.0]", "--set", "controller.f_d=1e4", "--set",
                 "trajectory.cycles=0.05", "--no-plots", "--out", str(out)]) == 1
    err = capfd.readouterr().err.strip().splitlines()
    assert err == ["error: simulation diverged: the CVODES integrator stopped (CV_TOO_MUCH_WORK); check the "
                   "stiffness, gains, control rate and simulation.tol"]
    assert not out.exists()


def test_a_ctrl_c_inside_cvodes_is_an_interrupt(tmp_path, capsys, monkeypatch):
    """Regression (review 13): a Ctrl-C while CVODES evaluated its right-hand side became a solver
    failure (CasADi catches the KeyboardInterrupt: 'rhs failed', CV_RHSFUNC_FAIL) and the command
    ended in a traceback with exit 1. The signal the handlers recorded makes it an interrupt: exit 130,
    one line. Emulated here exactly as CasADi does it: the signal lands inside the evaluation, whose
    exception becomes a RuntimeError."""
    import signal

    import tmtcontrol.simulation.rollout as rollout
    from tmtcontrol.cli import main

    def swallowed(self, *args):
        try:
            os.kill(os.getpid(), signal.SIGINT)
            for _ in range(1000):
                pass                                   # the handler runs at a bytecode boundary in here
        except BaseException as exc:                   # what CasADi's evaluation does with it
            raise RuntimeError(f'rhs failed: {type(exc).__name__}\nCVode returned "CV_RHSFUNC_FAIL"') from None
        raise AssertionError("the signal did not arrive")

    for name in ("Rollout", "CompiledRollout"):
        if hasattr(rollout, name):
            monkeypatch.setattr(getattr(rollout, name), "run", swallowed)
    out = tmp_path / "o"
    assert main(["simulate", "--integrator", "cvodes", "--set", "trajectory.cycles=0.05", "--no-plots",
                 "--out", str(out)]) == 130
    assert capsys.readouterr().err.strip().splitlines() == ["interrupted (Ctrl-C): nothing was written"]
    assert not out.exists()
