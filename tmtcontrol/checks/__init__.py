"""Derivation checks of the paper's equations, of every force-tracking
law's claims and of the analysed against the simulated loop, on the running
code."""

from __future__ import annotations


def check_groups() -> list[str]:
    """The independent groups of :func:`all_checks`, in its order: the
    paper's derivations, one group per registered law (``"law: NAME"``), the
    loop (the report runs them in parallel)."""
    from ..control.laws import laws

    return ["derivations", *(f"law: {name}" for name in laws()), "loop"]


def run_check_group(group: str, seed: int = 2024) -> list:
    """The checks of one of :func:`check_groups`."""
    from . import derivations, laws, loop

    if group == "derivations":
        return derivations.run_checks(seed=seed)
    if group == "loop":
        return loop.run_loop_checks(seed)
    if group.startswith("law: ") and group.removeprefix("law: ") in laws.laws():
        return laws.law_checks(laws.laws()[group.removeprefix("law: ")], seed)
    raise ValueError(f"group: expected one of {', '.join(check_groups())}, got {group!r}")


def all_checks(seed: int = 2024) -> list:
    """The paper's derivation checks, every registered law's, then the loop checks."""
    return [r for group in check_groups() for r in run_check_group(group, seed)]


__all__ = ["all_checks", "run_check_group", "check_groups"]
