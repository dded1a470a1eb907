"""Shared fixtures: a private compile cache per test session, headless plots,
and the paper scenario simulated once."""
import fcntl
import os
import pathlib
import pickle

import pytest
from hypothesis import settings

os.environ.setdefault("MPLBACKEND", "Agg")


def _installed() -> bool:
    """Whether the tmtcontrol these tests import is an installed copy (in a
    site-packages folder, as CI's ``pip install '.[test]'`` leaves it)."""
    import site

    import tmtcontrol

    home = pathlib.Path(tmtcontrol.__file__).resolve().parent.parent
    return any(home == pathlib.Path(p).resolve() for p in site.getsitepackages())


# The commands the tests start (python -m tmtcontrol.cli, python -c, the analysis scripts) run the package the
# tests import. `python -m` and `-c` put the working folder first on sys.path: from a checkout (CI's fresh clone)
# every command ran the clone's sources, not the installed copy the in-process tests run, and with
# PYTHONDONTWRITEBYTECODE set (CI's machines) compiled them afresh each time: 0.3 s of bytecode compilation in each
# of the README suite's ~190 commands. PYTHONSAFEPATH (Python >= 3.11) leaves the working folder off the path.
if _installed():
    os.environ.setdefault("PYTHONSAFEPATH", "1")

# property tests are deterministic: a fixed seed per test (derandomize) and no example
# database carried between runs, so CI and a fresh clone draw the same examples; a failure
# one of them finds becomes a named @example. HYPOTHESIS_PROFILE=explore draws new ones.
settings.register_profile("fixed", derandomize=True, database=None, print_blob=True)
settings.register_profile("explore", derandomize=False, database=None, print_blob=True)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "fixed"))


@pytest.fixture(scope="session", autouse=True)
def _private_cache(tmp_path_factory):
    """A compile cache private to this test run, shared by its xdist workers
    (the cache's atomic, verified writes make sharing safe), so each law's
    step is compiled once per run rather than once per worker. The analysis
    results kept in it are shared the same way: by the shared fixtures (none
    of them stubs an analysis) and by the tests :func:`_shared_results`
    allows. ``TMTCONTROL_TEST_CACHE`` names a folder to use instead, so that
    two runs share it: ``.ci/run`` gives the README's command and the heavy
    step one, and the heavy step does not compile or compute again what the
    first compiled and computed (each key covers every input; the tests of
    compiling and of the cache itself use caches of their own)."""
    old = {k: os.environ.get(k) for k in ("TMTCONTROL_CACHE", "TMTCONTROL_RESULT_CACHE")}
    shared = os.environ.get("TMTCONTROL_TEST_CACHE")
    cache = pathlib.Path(shared) if shared else _shared_base(tmp_path_factory) / "tmtcontrol-cache"
    cache.mkdir(parents=True, exist_ok=True)
    os.environ["TMTCONTROL_CACHE"] = str(cache)
    os.environ["TMTCONTROL_RESULT_CACHE"] = "1"
    yield
    for k, v in old.items():
        if v is None:
            os.environ.pop(k, None)
        else:
            os.environ[k] = v


def _shared_base(tmp_path_factory):
    """The folder all xdist workers of this run share (the base of their temp folders)."""
    base = tmp_path_factory.getbasetemp()
    return base.parent if os.environ.get("PYTEST_XDIST_WORKER") else base


# modules whose tests interrupt or time the analyses, count what they compute or
# inject faults into them: every analysis runs in each of their tests
_RESULTS_COMPUTED = frozenset({"test_outputs.py", "test_compile_signals.py", "test_processes.py",
                               "test_drawing.py", "test_files_safety.py", "test_result_cache.py",
                               "test_mutations.py"})


@pytest.fixture(autouse=True)
def _shared_results(request):
    """Analysis results (the deciding limit, a design, the derivation checks)
    kept in this run's cache, so a limit several tests' commands need is
    computed once per run (it is the same computation: the key covers every
    input, tests/test_result_cache.py). Off (TMTCONTROL_RESULT_CACHE=0, also
    for the commands a test starts) where a test uses ``monkeypatch``, whose
    stubs must neither reach another test nor be hidden by a kept result, and
    in the modules of ``_RESULTS_COMPUTED``. Checked: the suite passes with
    the results all computed (TMTCONTROL_RESULT_CACHE=0 throughout, as it
    ran before), read back from an earlier run's cache, and mixed."""
    keep = "monkeypatch" not in request.fixturenames and request.path.name not in _RESULTS_COMPUTED
    old = os.environ.get("TMTCONTROL_RESULT_CACHE")
    os.environ["TMTCONTROL_RESULT_CACHE"] = "1" if keep else "0"
    yield
    if old is None:
        os.environ.pop("TMTCONTROL_RESULT_CACHE", None)
    else:
        os.environ["TMTCONTROL_RESULT_CACHE"] = old


@pytest.fixture(scope="session")
def run_once(tmp_path_factory):
    """``run_once(name, make) -> (out, value)``: ``make(out)`` writes into the fresh
    folder ``out`` and returns a picklable value; across the xdist workers of a run it
    runs once (the others wait on a file lock and read the stored value), so an
    expensive command shared by several tests (a report, a comparison) is not
    repeated on every worker."""
    root = _shared_base(tmp_path_factory) / "run-once"
    root.mkdir(exist_ok=True)

    def once(name, make):
        folder = root / name
        with open(root / f"{name}.lock", "w") as lock:
            fcntl.flock(lock, fcntl.LOCK_EX)
            try:
                stored = folder / "value.pickle"
                if not stored.exists():
                    folder.mkdir(exist_ok=True)
                    value = make(folder / "out")
                    stored.write_bytes(pickle.dumps(value))
                return folder / "out", pickle.loads(stored.read_bytes())
            finally:
                fcntl.flock(lock, fcntl.LOCK_UN)

    return once


@pytest.fixture(scope="session")
def paper_sim():
    from tmtcontrol import Simulator, paper_scenario

    return Simulator(paper_scenario())


@pytest.fixture(scope="session")
def known_sim():
    """The paper scenario with the known-stiffness law (its own compiled step)."""
    from tmtcontrol import Simulator, apply_overrides, paper_scenario

    return Simulator(apply_overrides(paper_scenario(), ["controller.law=known"]))


@pytest.fixture(scope="session")
def paper_result(paper_sim):
    return paper_sim.run()


def load_benchmark(name: str):
    """``benchmarks/NAME.py`` as a module (the docs tests compare the pages with
    what a benchmark prints); its folder is on ``sys.path`` while it loads, for
    the ``bench_all`` it imports beside it."""
    import importlib.util
    import pathlib
    import sys

    folder = pathlib.Path(__file__).resolve().parents[1] / "benchmarks"
    sys.path.insert(0, str(folder))
    try:
        spec = importlib.util.spec_from_file_location(name, folder / f"{name}.py")
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
    finally:
        sys.path.remove(str(folder))
    return module
