"""Shared fixtures: a private compile cache per test session, headless plots,
and the paper scenario simulated once."""
import os

import pytest

os.environ.setdefault("MPLBACKEND", "Agg")


@pytest.fixture(scope="session", autouse=True)
def _private_cache(tmp_path_factory):
    """A compile cache private to this test run, shared by its xdist workers
    (the cache's atomic, verified writes make sharing safe), so each law's
    step is compiled once per run rather than once per worker."""
    old = os.environ.get("TMTCONTROL_CACHE")
    base = tmp_path_factory.getbasetemp()
    shared = base.parent if os.environ.get("PYTEST_XDIST_WORKER") else base
    cache = shared / "tmtcontrol-cache"
    cache.mkdir(exist_ok=True)
    os.environ["TMTCONTROL_CACHE"] = str(cache)
    yield
    if old is None:
        os.environ.pop("TMTCONTROL_CACHE", None)
    else:
        os.environ["TMTCONTROL_CACHE"] = old


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
