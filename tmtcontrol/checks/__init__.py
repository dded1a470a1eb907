"""Derivation checks of the paper's equations, of every force-tracking
law's claims and of the analysed against the simulated loop, on the running
code."""

from __future__ import annotations


def all_checks(seed: int = 2024) -> list:
    """The paper's derivation checks, every registered law's, then the loop checks."""
    from . import derivations, laws, loop

    return derivations.run_checks(seed=seed) + laws.run_law_checks(seed) + loop.run_loop_checks(seed)


__all__ = ["all_checks"]
