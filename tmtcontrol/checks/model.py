"""The scenario's own arm model (eq. 1) as derivation-check rows.

:func:`tmtcontrol.model.verify.check_robot` evaluates the identities every
rigid-body model satisfies (M symmetric and positive definite, the energy
identity dq^T (Mdot - 2C) dq = 0, inverse of forward dynamics, the Jacobian
as the derivative of fk) and, where Pinocchio is installed, the agreement of
M, the bias, g, J, fk and ABA with that independent implementation. This
module turns its result into :class:`.derivations.CheckResult` rows for the
arm the scenario names, so a UR5 report checks the UR5 and the paper's
report the PUMA (the paper's own rows of :mod:`.derivations` then leave
their PUMA-only eq. (1) checks out).
"""

from __future__ import annotations

from .derivations import CheckResult

__all__ = ["model_checks", "SAMPLES"]

SAMPLES = 20
"""Seeded random states per identity (as ``tmtcontrol robot`` uses)."""


def model_checks(scenario, seed: int = 2024, pinocchio: bool = True) -> list[CheckResult]:
    """One row per identity of :func:`~tmtcontrol.model.verify.check_robot`
    on the scenario's simulated arm (``simulation.simulator.robot_of``)."""
    from ..model.verify import check_robot
    from ..simulation.simulator import robot_of

    robot = robot_of(scenario)
    check = check_robot(robot, samples=SAMPLES, seed=seed, pinocchio=pinocchio)
    out = []
    for ident in check.identities:
        pd = "positive definite" in ident.name
        pin = "Pinocchio" in ident.name
        method = (f"{check.samples} seeded random states within the joint limits"
                  + (f"; {check.reference}, built from the same {'URDF' if robot.urdf else 'parameter set'}"
                     if pin else ""))
        # the residual column is a relative difference; positive definiteness has a smallest eigenvalue instead
        residual = 0.0 if (pd and ident.ok) else (1.0 if pd else ident.worst)
        out.append(CheckResult(
            f"{ident.name} ({robot.name})", "(1)",
            f"the {robot.name} model of eq. (1): {ident.name}" + ("" if pd else f", within {ident.limit:g} relative"),
            method, residual, ident.ok, ident.limit,
            note=f"smallest eigenvalue of M {ident.worst:.3g} kg m^2" if pd else ""))
    if "not compared" in check.reference:
        out[-1] = CheckResult(out[-1].name, out[-1].equation, out[-1].claim, out[-1].method, out[-1].residual,
                              out[-1].passed, out[-1].tolerance, note=f"Pinocchio {check.reference}")
    return out
