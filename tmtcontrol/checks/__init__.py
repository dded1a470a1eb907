"""Derivation checks of the paper's equations, of every force-tracking
law's claims and of the analysed against the simulated loop, on the running
code; with a scenario, also the checks that hold for its arm (``checks.arm``:
the task-frame loop with the ideal inner loop is the paper's loop)."""

from __future__ import annotations


def check_groups(scenario=None) -> list[str]:
    """The independent groups of :func:`all_checks`, in its order: the
    paper's derivations, one group per registered law (``"law: NAME"``), the
    loop, and with a ``scenario`` its arm's model (``"model"``: eq. (1)
    identities and Pinocchio, :mod:`.model`, in place of the PUMA's rows of
    the derivations) and its loop (``"arm"``); the report runs them in
    parallel."""
    from ..control.laws import laws

    return ["derivations", *(f"law: {name}" for name in laws()), "loop",
            *(["model", "arm"] if scenario is not None else [])]


def run_check_group(group: str, seed: int = 2024, scenario=None) -> list:
    """The checks of one of :func:`check_groups` (``"arm"`` needs the ``scenario``)."""
    from . import derivations, laws, loop

    if group == "arm" and scenario is not None:
        from .arm import arm_implementation, run_arm_checks

        return run_arm_checks(arm_implementation(scenario), seed)
    if group == "model" and scenario is not None:
        from .model import model_checks

        return model_checks(scenario, seed)
    if group == "derivations":      # with a scenario, its own arm's eq. (1) rows (group "model") replace the PUMA's
        return derivations.run_checks(seed=seed, model=scenario is None)
    if group == "loop":
        return loop.run_loop_checks(seed)
    if group.startswith("law: ") and group.removeprefix("law: ") in laws.laws():
        return laws.law_checks(laws.laws()[group.removeprefix("law: ")], seed)
    raise ValueError(f"group: expected one of {', '.join(check_groups(scenario))}, got {group!r}")


def kept_check_group(group: str, seed: int = 2024, scenario=None) -> list:
    """:func:`run_check_group`, kept in the cache's results
    (``tmtcontrol.cache.kept_result``) under a key of everything the checks
    run on: the package's sources, the group, the seed, the scenario's every
    value and its arm's content (for the groups that take them), and the
    versions of CasADi, NumPy, SciPy, python-control, SymPy and Pinocchio.
    The report uses it (a warm report reads its rows); ``tmtcontrol check``
    always runs them. ``TMTCONTROL_RESULT_CACHE=0`` always runs them."""
    import importlib.metadata

    from ..cache import kept_result, package_digest
    from .derivations import CheckResult

    def version(dist):
        try:
            return importlib.metadata.version(dist)
        except importlib.metadata.PackageNotFoundError:
            return None

    arm = None
    if scenario is not None and group in ("model", "arm"):
        from ..simulation.simulator import robot_of

        arm = (scenario.model_dump_json(), robot_of(scenario).key, robot_of(scenario, controller=True).key)
    key = repr((package_digest(), group, int(seed), scenario is None, arm,
                *(version(d) for d in ("casadi", "numpy", "scipy", "control", "sympy", "pin"))))
    return kept_result("checks", key, lambda: run_check_group(group, seed, scenario),
                       lambda rows: {"rows": [r.as_dict() for r in rows]},
                       lambda data: [CheckResult(**r) for r in data["rows"]])


def all_checks(seed: int = 2024, scenario=None) -> list:
    """The paper's derivation checks, every registered law's, the loop
    checks, then (with a ``scenario``) the checks of its arm."""
    return [r for group in check_groups(scenario) for r in run_check_group(group, seed, scenario)]


__all__ = ["all_checks", "run_check_group", "kept_check_group", "check_groups"]
