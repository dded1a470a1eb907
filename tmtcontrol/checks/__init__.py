"""Derivation checks of the paper's equations and of every force-tracking
law's claims, on the running code."""

from __future__ import annotations


def all_checks(seed: int = 2024) -> list:
    """The paper's derivation checks followed by every registered law's."""
    from . import derivations, laws

    return derivations.run_checks(seed=seed) + laws.run_law_checks(seed)


__all__ = ["all_checks"]
