"""Derivation checks of the paper's equations, of every force-tracking
law's claims and of the analysed against the simulated loop, on the running
code."""

from __future__ import annotations

CHECK_GROUPS = ("derivations", "laws", "loop")
"""The three independent groups of :func:`all_checks`, in its order (the
report runs them in parallel)."""


def run_check_group(group: str, seed: int = 2024) -> list:
    """One of :data:`CHECK_GROUPS`: the paper's derivation checks, every
    registered law's checks, or the loop checks."""
    from . import derivations, laws, loop

    run = {"derivations": lambda: derivations.run_checks(seed=seed), "laws": lambda: laws.run_law_checks(seed),
           "loop": lambda: loop.run_loop_checks(seed)}
    if group not in run:
        raise ValueError(f"group: expected one of {', '.join(CHECK_GROUPS)}, got {group!r}")
    return run[group]()


def all_checks(seed: int = 2024) -> list:
    """The paper's derivation checks, every registered law's, then the loop checks."""
    return [r for group in CHECK_GROUPS for r in run_check_group(group, seed)]


__all__ = ["all_checks", "run_check_group", "CHECK_GROUPS"]
