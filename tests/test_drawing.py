"""Figures drawn by forked workers: the same files as drawn here, failures
reported, and nothing written once the caller stops them."""
import os
import subprocess
import sys
import textwrap
import time

import pytest

from tmtcontrol.drawing import FigureProcessError, FigureWorkers
from tmtcontrol.simulation.output import FIGURE_MODULE, SIMULATION_FIGURES

pytestmark = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="the workers fork on Linux only")


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    return True


def test_forked_workers_write_the_files_drawing_here_writes(paper_result, tmp_path):
    """Agg output is deterministic: the PNGs of the two workers equal, byte for
    byte, those drawn in this process from the full result (not its traces)."""
    from tmtcontrol.simulation.figures import save_simulation_figures

    here, there = tmp_path / "here", tmp_path / "there"
    here.mkdir(), there.mkdir()
    expected = save_simulation_figures(paper_result, here)
    with FigureWorkers(FIGURE_MODULE) as workers:
        assert workers.forked
        got = workers.draw(SIMULATION_FIGURES, paper_result.traces, there).result()
    assert [p.name for p in got] == [f"{name}.png" for name, _ in SIMULATION_FIGURES]
    assert sorted(p.name for p in got) == sorted(p.name for p in expected)
    for p in got:
        assert p.parent == there and p.read_bytes() == (here / p.name).read_bytes(), p.name


def test_traces_carry_the_surface_the_wrist_presses_on(paper_result):
    """The plane the path figure draws (through the circle's centre, normal
    e_n = first column of surface_frame) is the surface of eq. (13): in
    contact the wrist's depth below it is f_e / k_e (the paper scenario has
    no environment damping), to rounding."""
    import numpy as np

    tr = paper_result.traces
    depth = (tr.position - tr.center[:, None]).T @ tr.surface_frame[:, 0]
    touching = tr.contact_force > 0
    assert touching.mean() > 0.9
    np.testing.assert_allclose(depth[touching], tr.contact_force[touching] / tr.stiffness[touching],
                               rtol=0, atol=1e-12)
    np.testing.assert_allclose(tr.surface_frame.T @ tr.surface_frame, np.eye(3), atol=1e-15)


@pytest.fixture
def figure_module(tmp_path, monkeypatch):
    """A module of figure functions: one that works, one that raises, one slow."""
    (tmp_path / "mod").mkdir()
    (tmp_path / "mod" / "figs_under_test.py").write_text(textwrap.dedent("""
        import time
        from matplotlib.figure import Figure

        def good(data):
            fig = Figure(figsize=(2, 1))
            fig.add_subplot().plot(data)
            return fig

        def bad(data):
            raise ZeroDivisionError("figure function failed on purpose")

        def slow(data):
            time.sleep(0.4)
            return good(data)
        """))
    monkeypatch.syspath_prepend(str(tmp_path / "mod"))      # the workers inherit sys.path
    out = tmp_path / "out"
    out.mkdir()
    return "figs_under_test", out


def test_a_failing_figure_raises_with_its_traceback(figure_module):
    module, out = figure_module
    with FigureWorkers(module) as workers:
        drawing = workers.draw([("a", "good"), ("b", "bad"), ("c", "good")], [1, 2, 3], out)
        with pytest.raises(FigureProcessError, match="ZeroDivisionError: figure function failed on purpose"):
            drawing.result()


def test_a_missing_module_raises_and_names_it(tmp_path):
    with FigureWorkers("no_such_module_for_figures") as workers:
        with pytest.raises(FigureProcessError, match="No module named 'no_such_module_for_figures'"):
            workers.draw([("a", "good")], [1], tmp_path).result()
    assert list(tmp_path.iterdir()) == []


def test_the_workers_get_their_data_while_this_process_holds_the_interpreters_lock(figure_module):
    """Regression (eighth session): the data went to the workers through the
    job pipes, written by a thread of this process; a pipe holds 64 kB, so
    the rest waited for that thread to get the interpreter's lock, which
    this process's next work (the tables: one long formatting call) held
    for tens of milliseconds, and the drawing with it. Here the caller holds
    the lock until the first worker has drawn and ended (``waitpid`` through
    ``ctypes.PyDLL``, which keeps the lock): with the data sent by a thread
    the worker never gets past 64 kB of 1 MB and the script hangs (the
    timeout is a bound on that, not a timing)."""
    module, out = figure_module
    script = textwrap.dedent(f"""
        import ctypes, sys
        sys.path.insert(0, {str(out.parent / "mod")!r})
        from tmtcontrol.drawing import FigureWorkers
        data = list(range(200_000))                  # about 1 MB pickled: 16 pipes' worth
        workers = FigureWorkers({module!r})
        drawing = workers.draw([("a", "good")], data, {str(out)!r})
        ctypes.PyDLL(None).waitpid(ctypes.c_int(workers._pid), None, 0)      # the lock held meanwhile
        print([p.name for p in drawing.result()])
        """)
    r = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=60)
    assert r.returncode == 0 and r.stdout.split() == ["['a.png']"], r.stderr
    assert (out / "a.png").stat().st_size > 0


def test_data_that_cannot_be_written_is_one_error_and_stops_the_workers(figure_module, monkeypatch):
    """Writing the data for the workers fails (no memory for the memfd, or a
    full temporary folder without one): a FigureProcessError saying so, not
    an OSError the command line would take for its own output's, and no
    worker left."""
    import errno

    from tmtcontrol import drawing as drawing_module

    module, out = figure_module
    write_all = drawing_module.write_all

    def full(fd, data):
        if len(data) > 1000:                 # the data, not the queue's few bytes
            raise OSError(errno.ENOSPC, "No space left on device")
        write_all(fd, data)

    monkeypatch.setattr(drawing_module, "write_all", full)
    workers = FigureWorkers(module)
    pid = workers._pid
    with pytest.raises(FigureProcessError, match="figures' data could not be handed .* No space left"):
        workers.draw([("a", "good")], list(range(10_000)), out)
    assert not _alive(pid) and list(out.iterdir()) == []


def test_stopped_workers_write_nothing_and_are_reaped(figure_module):
    """Stopped while drawing (each figure takes 0.4 s): no file appears after
    stop() returns, and no worker is left."""
    module, out = figure_module
    workers = FigureWorkers(module)
    pid = workers._pid
    drawing = workers.draw([(f"f{i}", "slow") for i in range(6)], [1, 2], out)
    time.sleep(0.6)                 # the workers are drawing (imports take ~0.4 s here)
    drawing.cancel()
    left = sorted(p.name for p in out.iterdir())
    time.sleep(1.0)                 # longer than one more figure would take
    assert sorted(p.name for p in out.iterdir()) == left
    assert len(left) < 6            # stopped before the end: the test tested something
    assert not _alive(pid)
    drawing.cancel()                # twice is harmless


def test_unused_workers_are_stopped_at_exit(tmp_path):
    with FigureWorkers(FIGURE_MODULE) as workers:
        pid = workers._pid
        assert _alive(pid)
    assert not _alive(pid) and list(tmp_path.iterdir()) == []


def test_processes_zero_draws_here(figure_module):
    module, out = figure_module
    workers = FigureWorkers(module, processes=0)
    assert not workers.forked
    paths = workers.draw([("a", "good")], [1, 2], out).result()
    assert [p.name for p in paths] == ["a.png"] and paths[0].stat().st_size > 0
    for bad in (-1, 9, 1.5, True):
        with pytest.raises(ValueError, match="processes"):
            FigureWorkers(module, processes=bad)


def test_one_process_or_three_draw_every_figure_once(figure_module):
    module, out = figure_module
    for n in (1, 3):
        with FigureWorkers(module, processes=n) as workers:
            drawing = workers.draw([(f"f{n}_{i}", "good") for i in range(5)], [1, 2], out)
            paths = drawing.result()
            assert drawing.result() is paths            # waited for once
    assert sorted(p.name for p in out.iterdir()) == sorted(f"f{n}_{i}.png" for n in (1, 3) for i in range(5))


@pytest.mark.heavy
def test_simulate_interrupted_with_figure_workers_leaves_no_process_and_no_file(tmp_path):
    """SIGTERM while the run computes and the workers wait with matplotlib
    loaded: exit 143, nothing written, and no process of the command left
    (a forked worker has the command line of its parent)."""
    import signal

    out = tmp_path / "o"
    cmd = [sys.executable, "-m", "tmtcontrol.cli", "simulate", "--set", "trajectory.cycles=200", "--out", str(out)]
    p = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    while not any(tmp_path.iterdir()):       # the staging folder: running now, whatever the machine's load
        assert p.poll() is None, p.stderr.read()
        time.sleep(0.01)
    p.send_signal(signal.SIGTERM)
    _, err = p.communicate(timeout=60)
    assert p.returncode == 143, err
    assert list(tmp_path.iterdir()) == []

    def left():
        found = []
        for d in os.listdir("/proc"):
            if d.isdigit():
                try:
                    with open(f"/proc/{d}/cmdline", "rb") as fh:
                        if str(out).encode() in fh.read():
                            found.append(d)
                except OSError:
                    pass
        return found

    # a worker notices its parent's death (PR_SET_PDEATHSIG) asynchronously: wait for it to go,
    # bounded far above any scheduling delay (a worker that stays fails the test)
    for _ in range(1000):
        if not left():
            break
        time.sleep(0.01)
    assert left() == []


def test_the_package_and_the_command_line_start_without_numpy_casadi_or_matplotlib():
    """The top-level API resolves on first access (PEP 562), so the command
    line can fork its figure workers before the heavy imports; every name of
    ``__all__`` resolves to the object of its defining module."""
    code = textwrap.dedent("""
        import sys
        import tmtcontrol, tmtcontrol.cli, tmtcontrol.drawing, tmtcontrol.files, tmtcontrol.simulation.output
        heavy = sorted(m for m in ("numpy", "casadi", "matplotlib", "pydantic") if m in sys.modules)
        assert heavy == [], heavy
        from tmtcontrol import *
        import tmtcontrol.simulation.simulator as s
        assert Simulator is s.Simulator and tmtcontrol.SimulationResult is s.SimulationResult
        assert set(tmtcontrol.__all__) == {"__version__", *tmtcontrol._WHERE}
        for name in tmtcontrol.__all__:
            assert getattr(tmtcontrol, name) is not None, name
        try:
            tmtcontrol.no_such_name
        except AttributeError as e:
            assert "no_such_name" in str(e)
        else:
            raise AssertionError("no AttributeError")
        """)
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr


@pytest.mark.parametrize("args,code,needle", [
    (["--set", "nope.x=1"], 2, "nope: unknown key"),
    (["--set", "trajectory.center=[3.0, 0.0, 0.5]"], 2, "unreachable"),
    (["--set", "controller.rate=100", "--set", "impedance.k=[1e6, 1e6, 1e6]", "--set", "trajectory.cycles=0.5"],
     1, "diverged at t ="),
])
def test_simulate_with_figure_workers_fails_in_one_line_and_writes_nothing(tmp_path, args, code, needle):
    """With the figure workers running (no --no-plots): bad input exits 2 and a
    diverging run 1, in one line, with no folder, file or worker left."""
    out = tmp_path / "o"
    r = subprocess.run([sys.executable, "-m", "tmtcontrol.cli", "simulate", "--out", str(out), *args],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == code, r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and needle in lines[0] and "Traceback" not in r.stderr, r.stderr
    assert r.stdout == "" and list(tmp_path.iterdir()) == []


def test_a_drawing_takes_up_to_256_figures_one_byte_each_and_refuses_more(tmp_path):
    """The shared queue holds one byte per figure, its index: 256 fit (0-255); the check read "at
    most 255" (the eleventh mutation run: `> 255` as `> 256` survived). 256 figures get past it
    (here to the workers' missing module, which fails fast), 257 are refused by name before any
    worker is given a figure."""
    many = [(f"f{i}", "good") for i in range(256)]
    with FigureWorkers("no_such_module_for_figures") as workers:
        assert workers.forked                   # Linux: the one-byte queue is the forked workers'
        with pytest.raises(FigureProcessError, match="No module named 'no_such_module_for_figures'"):
            workers.draw(many, [1], tmp_path).result()
    with FigureWorkers("no_such_module_for_figures") as workers:
        with pytest.raises(ValueError, match=r"^figures: at most 256 per drawing, got 257$"):
            workers.draw([*many, ("one_more", "good")], [1], tmp_path)
    assert list(tmp_path.iterdir()) == []
