"""The scenario's own arm model (eq. 1) as derivation-check rows, each against an independent statement.

:func:`tmtcontrol.model.verify.check_robot` evaluates the identities every
rigid-body model satisfies (M symmetric and positive definite, the energy
identity dq^T (Mdot - 2C) dq = 0, inverse of forward dynamics, the Jacobian
as the derivative of fk) and, where Pinocchio is installed, the agreement of
M, the bias, g, J, fk and ABA with that independent implementation. This
module turns its result into :class:`.derivations.CheckResult` rows for the
arm the scenario names, so a UR5 report checks the UR5 and the paper's
report the PUMA (the paper's own rows of :mod:`.derivations` then leave
their PUMA-only eq. (1) checks out).

Three more rows compare the code the analyses and the loop run with a
statement of the same quantity that does not come from it:

* the effective normal mass of the 1-D limit and the design
  (:func:`tmtcontrol.stability.onedim.normal_masses`) at the path's poses,
  against ``1/(n^T J_v M^-1 J_v^T n)`` from Pinocchio's M and J;
* the rotation vector of :func:`tmtcontrol.simulation.geometry.rotation_vector`
  against SciPy's ``Rotation.as_rotvec`` at seeded random rotations;
* on a 6-D task, the orientation error e_o the closed loop's step logs at
  seeded joint states off the path pose, against SciPy's rotation vector
  of ``R_d R(q)^T`` with R(q) from forward kinematics, in the task axes.
"""

from __future__ import annotations

from .derivations import CheckResult

__all__ = ["model_checks", "independent_checks", "normal_mass_check", "rotation_vector_check",
           "orientation_error_check", "SAMPLES", "TOLERANCE"]

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
    return out + independent_checks(scenario, seed)


TOLERANCE = 1e-9
"""Relative agreement of the independent rows (double precision on both
sides; a wrong formula is off by percent)."""


def _row(name, claim, method, residual, note=""):
    import math

    ok = bool(math.isfinite(residual) and residual <= TOLERANCE)
    return CheckResult(name, "(1)" if "mass" in name else "(6)", claim, method, float(residual), ok, TOLERANCE,
                       note)


def normal_mass_check(scenario) -> CheckResult:
    """The analyses' effective normal mass against Pinocchio's M and J at the path poses."""
    import numpy as np

    from ..model.verify import pinocchio_model
    from ..simulation.geometry import surface_of
    from ..simulation.simulator import path_of, robot_of
    from ..stability.onedim import normal_masses

    robot = robot_of(scenario)
    name = f"effective normal mass = Pinocchio's ({robot.name})"
    claim = "m_p = 1/(n^T J_v M^-1 J_v^T n) at the path poses, the mass the 1-D limit and the design use"
    try:
        ref = pinocchio_model(robot)
    except (ImportError, NotImplementedError) as exc:
        return _row(name, claim, "not compared", 0.0, note=f"Pinocchio not available: {exc}")
    surface = surface_of(scenario)
    ours = np.asarray(normal_masses(scenario), float)
    theirs = []
    for q in path_of(robot, scenario).q.T:
        d = ref(q, np.zeros(robot.n), np.zeros(robot.n))
        Jv, n = d["J"][:3], surface.normal(d["fk"][:3, 3])
        theirs.append(1.0 / (n @ Jv @ np.linalg.solve(d["M"], Jv.T @ n)))
    theirs = np.asarray(theirs)
    return _row(name, claim, f"stability.onedim.normal_masses against Pinocchio's crba and frame Jacobian at the "
                f"{theirs.size} checked path poses", float(np.max(np.abs(ours - theirs) / theirs)))


def rotation_vector_check(seed: int = 2024) -> CheckResult:
    """geometry.rotation_vector against SciPy at seeded random rotations below pi, a third of them
    within 1e-12 to 1e-2 rad of pi (review 54: there the angle read as about 0)."""
    import numpy as np
    from scipy.spatial.transform import Rotation

    from ..simulation.geometry import rotation_vector

    rng = np.random.default_rng(seed)
    worst = 0.0
    for i in range(30):
        axis = rng.normal(size=3)
        angle = rng.uniform(1e-6, 3.0) if i < 20 else np.pi - 10.0 ** rng.uniform(-12.0, -2.0)
        v = axis / np.linalg.norm(axis) * angle
        R = Rotation.from_rotvec(v).as_matrix()
        worst = max(worst, float(np.linalg.norm(rotation_vector(R) - v) / np.linalg.norm(v)))
    return _row("rotation vector = SciPy's", "log(R)^vee of the orientation error (eq. 6 on the rotational axes)",
                "simulation.geometry.rotation_vector against scipy Rotation.as_rotvec, 30 seeded rotations "
                "(10 within 1e-2 rad of pi)", worst)


def orientation_error_check(scenario, seed: int = 2024) -> CheckResult | None:
    """The loop's logged e_o against SciPy's rotation vector of R_d R(q)^T
    (R from forward kinematics) at seeded joint states near the start pose;
    None on a position-only task."""
    import numpy as np
    from scipy.spatial.transform import Rotation

    from ..simulation.closedloop import param_layout
    from ..simulation.geometry import surface_of, tool_orientation
    from ..simulation.simulator import Simulator

    sim = Simulator(scenario, compile=False)
    if not sim.task.rotational:
        return None
    step = sim.build_step(contact_refine=1)
    U, P, s0, _ = sim.inputs()
    L, G = sim.layout, sim.log
    R_d = P[param_layout(sim.task, sim.law, sim.surface)["R_d"]].reshape(3, 3, order="F")
    rng = np.random.default_rng(seed)
    worst = 0.0
    surface = surface_of(scenario)
    # the controller's part: the true one moved by controller.part_offset (its frame at p is the true one's at p - d)
    d = np.asarray(scenario.controller.part_offset, dtype=float)
    for _ in range(8):
        s = s0.copy()
        s[L["q"]] += rng.uniform(-0.15, 0.15, sim.plant.n)
        q = s[L["q"]]
        T = sim.plant.fk(q)
        R_task = surface.frame(T[:3, 3] - d)
        _, log = step(s, U[:, 0], P)
        log = np.asarray(log).ravel()
        got = log[G["e_o"]]
        R_c = R_d
        if surface.turns:          # the command turns with the surface: the tool orientation on the frame where
            # the command's tangential coordinates meet the surface (its depth may reach a pipe's axis)
            at = surface.to_base(np.r_[0.0, log[G["X_c"]][1:]])
            R_c = tool_orientation(surface.frame(at), scenario.trajectory.tool_spin_deg)
        expected = R_task.T @ Rotation.from_matrix(R_c @ T[:3, :3].T).as_rotvec()
        worst = max(worst, float(np.linalg.norm(got - expected) / max(np.linalg.norm(expected), 1e-12)))
    return _row(f"loop orientation error = SciPy's from fk ({sim.plant.name})",
                "the closed loop's e_o = log(R_d R^T)^vee in the task axes, R the tool orientation of eq. (1)'s fk",
                "the scenario's step at 8 seeded joint states (+-0.15 rad about the start pose) against scipy "
                "Rotation.as_rotvec of R_d fk(q)^T", worst)


def independent_checks(scenario, seed: int = 2024) -> list[CheckResult]:
    """The rows of the module docstring's second list."""
    rows = [normal_mass_check(scenario), rotation_vector_check(seed)]
    e_o = orientation_error_check(scenario, seed)
    return rows + ([e_o] if e_o is not None else [])
