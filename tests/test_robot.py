"""Tests of the PUMA 560 model: parameters, physical identities, cross-checks."""
import csv
import math
import pathlib

import casadi as ca
import numpy as np
import pytest

from tmtcontrol import PUMA560_LINKS, Puma560

DATA = pathlib.Path(__file__).parent / "data"
RNG = np.random.default_rng(12345)
STATES = [RNG.uniform(-math.pi, math.pi, (3, 3)) for _ in range(20)]


@pytest.fixture(scope="module")
def robot():
    return Puma560()


def arr(x):
    return np.array(x, dtype=float).squeeze()


def test_parameter_table_pinned():
    # Corke & Armstrong-Helouvry (1994), as listed in the issue; a typo in
    # robot.py must fail here, not silently change every later result.
    expected = [
        (0.67183, 0.0, math.pi / 2, 0.0, (0, 0, 0), (0, 0.35, 0), 200e-6, -62.6111, 1.48e-3, (0.395, -0.435)),
        (0.0, 0.4318, 0.0, 17.4, (-0.3638, 0.006, 0.2275), (0.13, 0.524, 0.539), 200e-6, 107.815, 0.817e-3, (0.126, -0.071)),
        (0.15005, 0.0203, -math.pi / 2, 4.8, (-0.0203, -0.0141, 0.070), (0.066, 0.086, 0.0125), 200e-6, -53.7063, 1.38e-3, (0.132, -0.105)),
    ]
    for link, row in zip(PUMA560_LINKS, expected, strict=True):
        got = (link.d, link.a, link.alpha, link.m, link.r, link.I, link.Jm, link.G, link.B, link.Tc)
        assert got == row


def load_reference():
    with (DATA / "puma560_rtb_reference.csv").open() as fh:
        rows = list(csv.DictReader(fh))
    assert len(rows) >= 20
    return rows


@pytest.mark.parametrize("row", load_reference())
def test_matches_published_model(robot, row):
    # Independent implementation: Robotics Toolbox for Python (see
    # tests/data/make_puma560_reference.py). 1e-9 relative is the spec; the
    # two agree to ~1e-14, so 1e-9 leaves only round-off headroom.
    v = lambda keys: np.array([float(row[k]) for k in keys])
    q, dq, ddq = v(["q1", "q2", "q3"]), v(["dq1", "dq2", "dq3"]), v(["ddq1", "ddq2", "ddq3"])
    tau = v(["tau1", "tau2", "tau3"])
    M = v([f"M{i}{j}" for i in (1, 2, 3) for j in (1, 2, 3)]).reshape(3, 3)
    g = v(["g1", "g2", "g3"])
    p = v(["px", "py", "pz"])
    np.testing.assert_allclose(arr(robot.inverse_dynamics(q, dq, ddq)), tau, rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(arr(robot.mass_matrix(q)), M, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(arr(robot.gravity(q)), g, rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(arr(robot.fk(q)), p, rtol=1e-9, atol=1e-12)


@pytest.mark.parametrize("armature", [True, False])
def test_mass_matrix_symmetric_positive_definite(armature):
    r = Puma560(armature=armature, friction=False)
    for q, _, _ in STATES:
        M = arr(r.mass_matrix(q))
        np.testing.assert_allclose(M, M.T, atol=1e-14)
        assert np.linalg.eigvalsh(M).min() > 1e-3


def test_mdot_minus_2c_is_skew(robot):
    # d/dt M(q) = sum_k dM/dq_k dq_k, taken by CasADi AD of the same M.
    q, dq = robot.q, robot.dq
    Mdot = ca.Function("Mdot", [q, dq], [ca.reshape(ca.jtimes(ca.vec(robot.expr["M"]), q, dq), 3, 3)])
    for q0, dq0, _ in STATES:
        S = arr(Mdot(q0, dq0)) - 2 * arr(robot.coriolis_matrix(q0, dq0))
        scale = np.abs(arr(Mdot(q0, dq0))).max() + 1.0
        np.testing.assert_allclose(S, -S.T, atol=1e-12 * scale)
        # and C dq from the matrix is the vector returned by `coriolis`
        np.testing.assert_allclose(arr(robot.coriolis_matrix(q0, dq0)) @ dq0,
                                   arr(robot.coriolis(q0, dq0)), atol=1e-12 * scale)


def test_forward_inverse_dynamics_identity(robot):
    for q, dq, ddq in STATES:
        dq = np.where(dq == 0, 0.1, dq)
        tau = robot.inverse_dynamics(q, dq, ddq)
        np.testing.assert_allclose(arr(robot.forward_dynamics(q, dq, tau)), ddq, atol=1e-10)


@pytest.mark.parametrize("armature,friction", [(True, True), (False, False), (True, False)])
def test_newton_euler_matches_euler_lagrange(armature, friction):
    r = Puma560(armature=armature, friction=friction)
    for q, dq, ddq in STATES:
        a = arr(r.inverse_dynamics(q, dq, ddq))
        b = arr(r.rnea(q, dq, ddq))
        np.testing.assert_allclose(a, b, rtol=1e-12, atol=1e-12)


def test_friction_model_exact_signs():
    r = Puma560()
    G = np.array([l.G for l in PUMA560_LINKS])
    B = np.array([l.B for l in PUMA560_LINKS])
    Tp = np.array([l.Tc[0] for l in PUMA560_LINKS])
    Tn = np.array([l.Tc[1] for l in PUMA560_LINKS])
    dq = np.array([0.5, -0.7, 0.0])
    expected = np.abs(G) * (B * np.abs(G) * dq + np.array([Tp[0], Tn[1], 0.0]))
    np.testing.assert_allclose(arr(r.friction(dq)), expected, rtol=1e-15)
    assert np.all(arr(Puma560(friction=False).friction(dq)) == 0)


def test_smooth_friction_approaches_exact_away_from_zero():
    r = Puma560(friction="smooth", coulomb_velocity=1e-3)
    exact = Puma560(friction=True)
    for dq in ([0.1, -0.2, 0.3], [-1.0, 1.0, -0.05]):
        # tanh(50)^2 differs from 1 by ~1e-43: agreement is at round-off level
        np.testing.assert_allclose(arr(r.friction(dq)), arr(exact.friction(dq)), rtol=1e-12)
    np.testing.assert_allclose(arr(r.friction([0, 0, 0])), 0.0)
    # continuous through zero: small velocity -> small Coulomb torque
    assert np.abs(arr(r.friction([1e-7, -1e-7, 1e-7]))).max() < 1e-2


def test_jacobian_matches_finite_differences(robot):
    h = 1e-6
    for q, _, _ in STATES:
        J = arr(robot.jacobian(q))
        Jfd = np.column_stack([(arr(robot.fk(q + h * e)) - arr(robot.fk(q - h * e))) / (2 * h)
                               for e in np.eye(3)])
        # central difference error O(h^2 * |p'''|) ~ 1e-12, round-off ~1e-16/h = 1e-10
        np.testing.assert_allclose(J, Jfd, atol=1e-8)


def test_cartesian_form_reproduces_joint_dynamics():
    r = Puma560(friction=True)
    for q, dq, ddq in STATES:
        if arr(r.condition_number(q)) > 1e3:
            continue
        J = arr(r.jacobian(q))
        xdd = J @ ddq + arr(r.jacobian_dot(q, dq))
        F = arr(r.cartesian_inertia(q)) @ xdd + arr(r.cartesian_bias(q, dq)) + arr(r.cartesian_friction(q, dq))
        np.testing.assert_allclose(J.T @ F, arr(r.inverse_dynamics(q, dq, ddq)), rtol=1e-9, atol=1e-9)
        D = arr(r.cartesian_inertia(q))
        Jinv = np.linalg.inv(J)
        np.testing.assert_allclose(D, Jinv.T @ arr(r.mass_matrix(q)) @ Jinv, rtol=1e-9)


def test_joint_torque_is_eq5_mapped_by_jacobian_transpose():
    # two implementations of tau = J^T F, F from eq. (5): the Cartesian form
    # (D*, h* formed) and the closed loop's joint form (one solve, no D*)
    from tmtcontrol.control.impedance import control_force, joint_torque

    r = Puma560(friction=True)
    for q, dq, U in STATES:
        if arr(r.condition_number(q)) > 1e3:
            continue
        F_e = U[::-1] * 10
        J = arr(r.jacobian(q))
        cart = J.T @ arr(control_force(r.cartesian_inertia(q), r.cartesian_bias(q, dq), U, F_e))
        joint = arr(joint_torque(r.mass_matrix(q), r.bias(q, dq), r.jacobian(q), r.jacobian_dot(q, dq), U, F_e))
        np.testing.assert_allclose(joint, cart, rtol=1e-9, atol=1e-9)   # rounding of cond <= 1e3 matrices


def test_energy_conserved_without_torque_and_friction():
    r = Puma560(armature=True, friction=False)
    x = ca.SX.sym("x", 6)
    ode = r.forward_dynamics(x[:3], x[3:], ca.DM.zeros(3))
    integ = ca.integrator("free", "cvodes", {"x": x, "ode": ca.vertcat(x[3:], ode)}, 0,
                          np.linspace(0.1, 2.0, 20), {"abstol": 1e-12, "reltol": 1e-12})
    x0 = np.r_[0.3, -0.4, 0.8, 1.0, -0.5, 1.5]
    E = lambda s: sum(float(v) for v in r.energy(s[:3], s[3:]))
    E0 = E(x0)
    traj = np.array(integ(x0=x0)["xf"])
    drift = max(abs(E(traj[:, k]) - E0) for k in range(traj.shape[1]))
    # CVODES at 1e-12 tolerances over 2 s: energy (~100 J) holds to ~1e-8 J.
    assert drift < 1e-6, drift
    # the check can fail: with friction on, energy is dissipated measurably
    rf = Puma560(armature=True, friction="smooth", coulomb_velocity=0.05)
    odef = rf.forward_dynamics(x[:3], x[3:], ca.DM.zeros(3))
    integf = ca.integrator("fric", "cvodes", {"x": x, "ode": ca.vertcat(x[3:], odef)}, 0, 0.5,
                           {"abstol": 1e-10, "reltol": 1e-10})
    xf = np.array(integf(x0=x0)["xf"]).ravel()
    assert E(xf) < E0 - 1e-3


def test_condition_number_and_manipulability(robot):
    # wrist centre on the joint-1 axis (x = y = 0 in frame 0) is a singularity
    # of this arm; a nominal pose is well conditioned
    q_nominal = np.array([0.0, -0.5, 0.5])
    assert arr(robot.condition_number(q_nominal)) < 20
    assert arr(robot.manipulability(q_nominal)) > 1e-3
    # elbow fully stretched (q3 such that links 2 and 3 align) -> det J ~ 0
    qs = np.linspace(-math.pi, math.pi, 2001)
    w = [float(arr(robot.manipulability([0.0, 0.2, q3]))) for q3 in qs]
    assert min(w) < 1e-3 * max(w)


def test_functions_have_named_io(robot):
    assert robot.inverse_dynamics.name_in() == ["q", "dq", "ddq"]
    assert robot.inverse_dynamics.name_out() == ["tau"]
    assert robot.forward_dynamics.name_in() == ["q", "dq", "tau"]
    assert robot.cartesian_bias.name_in() == ["q", "dq"]


def test_rejects_bad_friction_option():
    with pytest.raises(ValueError, match="friction"):
        Puma560(friction="yes")


def test_closed_form_inverse_kinematics_round_trip(robot):
    # Independent reference: the DH forward kinematics (CasADi). For random
    # joint angles, every one of the four closed-form branches reaches fk(q)
    # (tolerance 1e-12 m: double-precision trig on ~1 m lengths), and one of
    # them is q itself (1e-9 rad: arccos loses digits near a stretched arm).
    q = RNG.uniform(-math.pi, math.pi, (3, 200))
    P = np.asarray(robot.fk.map(200)(q))
    found = np.zeros(200, bool)
    for shoulder in (1, -1):
        for elbow in (1, -1):
            Q = robot.inverse_kinematics(P, shoulder=shoulder, elbow=elbow)
            assert Q.shape == (3, 200)
            assert np.abs(np.asarray(robot.fk.map(200)(Q)) - P).max() < 1e-12
            d = (Q - q + math.pi) % (2 * math.pi) - math.pi
            found |= np.abs(d).max(axis=0) < 1e-9
    assert found.all()
    # one point gives one joint vector; a point beyond reach is named
    assert robot.inverse_kinematics(P[:, 0]).shape == (3,)
    with pytest.raises(ValueError, match=r"point \[2.0, 0.0, 0.5\] m is outside the workspace"):
        robot.inverse_kinematics(np.array([[0.5, 2.0], [0.0, 0.0], [0.5, 0.5]]))



def test_dh_twist_of_90_degrees_is_exact():
    """A +-90 deg twist has cos = 6.1e-17 in floating point; the model takes it
    as the exact 0 (the twisted axis rows are exactly 0 and +-1), so the
    dynamics carry no 1e-17 terms, which constant folding could not drop."""
    from tmtcontrol.model.puma560 import _dh

    q = ca.SX.sym("q")
    twisted = 0
    for link in PUMA560_LINKS:
        A = ca.Function("A", [q], [_dh(q, link)])(0.37).full()
        expected = (math.cos(link.alpha), math.sin(link.alpha))
        if abs(abs(link.alpha) - math.pi / 2) < 1e-12:
            twisted += 1
            expected = (0.0, math.copysign(1.0, link.alpha))
        assert (A[2, 2], A[2, 1]) == expected            # exact, no tolerance
    assert twisted == 2


def test_dynamics_built_on_first_use_and_unknown_attributes_refused():
    """The kinematics are built with the model, the dynamics on first access
    of any of their Functions (a simulator's path check needs only fk and J)."""
    robot = Puma560()
    assert "mass_matrix" not in vars(robot) and "fk" in vars(robot)
    before = set(vars(robot))
    M = np.asarray(robot.mass_matrix([0.1, -0.5, 0.4]))
    assert set(vars(robot)) - before == Puma560._DYNAMICS     # every attribute built there is declared
    assert {"mass_matrix", "forward_dynamics", "expr"} <= set(vars(robot))
    np.testing.assert_allclose(M, M.T, atol=1e-12)
    with pytest.raises(AttributeError, match="no attribute 'mass_matrx'"):
        robot.mass_matrx


def _serial_urdf(axes, name="serial"):
    """A serial arm of len(axes) revolute joints, 0.15 m apart along x, each
    about its axis (a string "x y z"), 1 kg links."""
    inertia = '<inertial><mass value="1"/><inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial>'
    parts = [f'<robot name="{name}"><link name="l0"/>']
    for i, axis in enumerate(axes, 1):
        parts.append(f'<link name="l{i}">{inertia}</link><joint name="j{i}" type="revolute"><parent link="l{i - 1}"/>'
                     f'<child link="l{i}"/><origin xyz="0.15 0 0.05"/><axis xyz="{axis}"/>'
                     '<limit lower="-3" upper="3" effort="100" velocity="3"/></joint>')
    return "".join(parts) + "</robot>"


@pytest.mark.parametrize("axes, dim, rank", [(["0 0 1"] * 6, 6, 3), (["0 0 1"] * 4, 3, 2),
                                             (["0 0 1", "0 1 0", "0 1 0", "0 0 1"], 3, 3),
                                             (["0 0 1", "0 1 0", "0 1 0", "1 0 0", "0 1 0", "1 0 0"], 6, 6)])
def test_an_arm_whose_axes_cannot_span_its_task_is_refused_in_one_line(tmp_path, axes, dim, rank):
    """Review 59: a 6-joint URDF with every axis along z (a planar arm: x, y
    and the turn about z, rank 3) was declared a 6-axis task and failed in
    CasADi's rootfinder with a traceback (exit 1) on simulate, check and
    export. The task's rank is counted from the Jacobian (closed form here:
    parallel z axes move the tool in x, y and turn it about z only); below the
    task's dimension the arm is refused, one line naming robot.model, exit 2,
    nothing written. Arms whose axes span the task (a 4-joint position arm, a
    6-joint one with a spherical-like wrist) keep their task."""
    import subprocess
    import sys

    from tmtcontrol import load_robot

    urdf = tmp_path / "arm.urdf"
    urdf.write_text(_serial_urdf(axes))
    robot = load_robot(str(urdf))
    assert robot.task_rank(dim) == rank
    if rank == dim:
        assert robot.task.dim == dim
        return
    with pytest.raises(ValueError, match=rf"along at most {rank} of the {dim} axes of its task"):
        robot.task
    (tmp_path / "s.toml").write_text(f'[robot]\nmodel = "arm.urdf"\nq0 = {[0.3] * len(axes)}\n')
    r = subprocess.run([sys.executable, "-m", "tmtcontrol.cli", "simulate", str(tmp_path / "s.toml"), "--no-plots",
                        "--out", str(tmp_path / "o")], capture_output=True, text=True)
    assert r.returncode == 2 and r.stderr.startswith("error: robot.model: serial has ") \
        and len(r.stderr.splitlines()) == 1, r.stderr
    assert not (tmp_path / "o").exists()


def test_the_arms_numpy_functions_refuse_a_state_that_is_not_finite():
    """Review 58: Robot.mass_matrix(np.full(6, nan)) returned a NaN matrix
    silently; a joint vector of the wrong length was refused already."""
    from tmtcontrol import load_robot

    arm = load_robot("ur5")
    with pytest.raises(ValueError, match=r"^q: expected finite values, got \[nan"):
        arm.mass_matrix(np.full(6, np.nan))
    with pytest.raises(ValueError, match=r"^dq: expected finite values"):
        arm.bias(np.zeros(6), np.r_[np.inf, np.zeros(5)])
    with pytest.raises(ValueError, match=r"^q: expected 6 values, got shape \(5,\)"):
        arm.mass_matrix(np.zeros(5))
