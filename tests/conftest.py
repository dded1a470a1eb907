"""Shared fixtures: a private compile cache per test session, headless plots,
and the paper scenario simulated once."""
import os

import pytest

os.environ.setdefault("MPLBACKEND", "Agg")


@pytest.fixture(scope="session", autouse=True)
def _private_cache(tmp_path_factory):
    old = os.environ.get("TMTCONTROL_CACHE")
    os.environ["TMTCONTROL_CACHE"] = str(tmp_path_factory.mktemp("cache"))
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
