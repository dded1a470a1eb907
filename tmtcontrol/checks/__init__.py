"""Derivation checks of the paper's equations on the running code."""
