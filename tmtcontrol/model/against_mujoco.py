"""A robot model against MuJoCo's: the same URDF through a physics engine nobody here wrote.

:func:`check_against_mujoco` loads the robot's URDF into MuJoCo (``mujoco``,
an optional extra: ``pip install 'tmtcontrol[mujoco]'``), keeping every link
as a body (``fusestatic="false"``, so the tool frame exists) and the robot's
rotor inertia as MuJoCo's ``armature``, and compares at seeded random states
within the joint limits (:func:`.verify.random_states`):

* the joint-space inertia M(q) with MuJoCo's ``mj_fullM`` (eq. 1);
* the bias C(q, dq) dq + g(q) with MuJoCo's ``qfrc_bias``;
* the tip's position and orientation (fk) with MuJoCo's body pose;
* the tip's 6 x n geometric Jacobian (linear rows first, base axes) with
  ``mj_jacBody``.

Held joints (not actuated, e.g. the Panda's fingers) are set to their held
values with zero rate in MuJoCo and their rows and columns left out: locking
a joint is taking the submatrix. Friction is not compared (MuJoCo keeps it
out of ``qfrc_bias``). The PUMA has no URDF (its model is the paper's DH
parameter set), so it cannot be loaded: :class:`NotImplementedError`, said
in one line by the command line.
"""

from __future__ import annotations

import re

import numpy as np

from .verify import TOLERANCE, Identity, RobotCheck, _rel, random_states

__all__ = ["mujoco_model", "check_against_mujoco", "MujocoMissing", "import_mujoco", "base_id", "base_body"]


class MujocoMissing(ImportError):
    """MuJoCo is not installed; the message says what to install."""


def import_mujoco():
    """The ``mujoco`` module, or :class:`MujocoMissing` saying what to do: not
    installed, or it failed to load its OpenGL backend (``MUJOCO_GL``, read
    on its first import: a library missing raises other errors than
    ImportError)."""
    import os

    try:
        import mujoco
    except ImportError:
        raise MujocoMissing("MuJoCo is not installed: pip install 'tmtcontrol[mujoco]' (or pip install mujoco)") \
            from None
    except Exception as exc:        # noqa: BLE001 - PyOpenGL raises AttributeError for a missing GL library
        raise MujocoMissing(f"MuJoCo did not load with MUJOCO_GL={os.environ.get('MUJOCO_GL', 'unset')} "
                            f"({str(exc).splitlines()[0] if str(exc) else type(exc).__name__}); set MUJOCO_GL to a "
                            "backend this machine has (egl, osmesa or glfw)") from None
    if mujoco.get_mju_user_warning() is None:
        # MuJoCo's own handler prints to stdout and appends to MUJOCO_LOG.TXT in the working folder (a file
        # tmtcontrol must not write); its warnings are kept here instead (a diverged run quotes the first)
        mujoco.set_mju_user_warning(_keep_warning)
    return mujoco


MUJOCO_WARNINGS: list[str] = []
"""MuJoCo's warnings in this process, oldest first (at most 100): e.g. 'Nan,
Inf or huge value in QACC at DOF 1' where a run diverges."""


def _keep_warning(message: str) -> None:
    if len(MUJOCO_WARNINGS) < 100:
        MUJOCO_WARNINGS.append(str(message).strip())


def base_id(model, robot) -> int:
    """The MjModel body id of the robot's base link (0, the world, where
    MuJoCo merged the base into it)."""
    names = {model.body(i).name for i in range(model.nbody)}
    return model.body(robot.base).id if robot.base in names else 0


def base_body(spec, robot):
    """The MjSpec body of the robot's base link (the world body where MuJoCo
    merged the base into it): where a part is placed in the robot's base
    frame."""
    names = {b.name for b in spec.bodies}
    return spec.body(robot.base) if robot.base in names else spec.worldbody


def mujoco_model(robot, lock_held: bool = False, edit=None):
    """``(mujoco, MjModel, MjData)`` of the robot's URDF, every link a body,
    the rotor inertia as armature on the actuated joints; ``lock_held``: the
    held joints made fixed (at their held value, which must be 0: the
    joint's zero is its URDF origin), so a simulation moves none of them;
    ``edit(spec)``: called on MuJoCo's ``MjSpec`` of the URDF before it is
    compiled (geoms added for a contact model)."""
    mujoco = import_mujoco()
    if robot.urdf is None:
        raise NotImplementedError(f"{robot.name} has no URDF (its model is the paper's DH parameter set, "
                                  "not written as a URDF or MJCF file for MuJoCo to load); the URDF arms run")
    text = robot.urdf
    if lock_held:
        for name, value in robot.held.items():
            if value != 0:
                raise NotImplementedError(f"the held joint {name} is at {value:g}, not 0: MuJoCo cannot lock it "
                                          "there from the URDF")
            text = re.sub(rf'(<joint\b[^>]*\bname="{re.escape(name)}"[^>]*\btype=")\w+(")', r"\1fixed\2", text)
    text = re.sub(r"(<robot\b[^>]*>)", r'\1<mujoco><compiler fusestatic="false" discardvisual="true" '
                  r'balanceinertia="false" strippath="true"/></mujoco>', text, count=1)
    text = re.sub(r"<(visual|collision)\b.*?</\1>", "", text, flags=re.S)     # meshes are not dynamics
    if edit is None:
        model = mujoco.MjModel.from_xml_string(text)
    else:
        spec = mujoco.MjSpec.from_string(text)
        edit(spec)
        model = spec.compile()
    model.opt.gravity[:] = (0.0, 0.0, -9.81)
    for j, name in enumerate(robot.joint_names):
        model.dof_armature[model.jnt_dofadr[model.joint(name).id]] = robot.armature[j]
    return mujoco, model, mujoco.MjData(model)


def _full_inertia(mujoco, model, data, out) -> None:
    """``mj_fullM`` in either signature: ``(m, d, dst)`` (MuJoCo 4) or ``(m, dst, qM)`` (3.x)."""
    if hasattr(data, "qM"):
        mujoco.mj_fullM(model, out, data.qM)
    else:
        mujoco.mj_fullM(model, data, out)


def check_against_mujoco(robot, samples: int = 20, seed: int = 0) -> RobotCheck:
    """M, bias, fk and the tip Jacobian against MuJoCo (module docstring), to
    :data:`.verify.TOLERANCE` relative."""
    mujoco, model, data = mujoco_model(robot)
    act = np.array([model.jnt_dofadr[model.joint(name).id] for name in robot.joint_names])
    qpos = np.array([model.jnt_qposadr[model.joint(name).id] for name in robot.joint_names])
    for name, value in robot.held.items():
        data.qpos[model.jnt_qposadr[model.joint(name).id]] = value
    tip = model.body(robot.tip).id
    base = base_id(model, robot)
    worst = {k: 0.0 for k in ("M", "bias", "fk", "J")}
    M_full = np.zeros((model.nv, model.nv))
    jp, jr = np.zeros((3, model.nv)), np.zeros((3, model.nv))
    for q, dq, _ in random_states(robot, samples, seed):
        data.qpos[qpos], data.qvel[:] = q, 0.0
        data.qvel[act] = dq
        mujoco.mj_forward(model, data)
        _full_inertia(mujoco, model, data, M_full)
        worst["M"] = max(worst["M"], _rel(robot.mass_matrix(q), M_full[np.ix_(act, act)]))
        worst["bias"] = max(worst["bias"], _rel(robot.bias(q, dq), data.qfrc_bias[act]))
        Rb, pb = data.xmat[base].reshape(3, 3), data.xpos[base]
        T = np.eye(4)
        T[:3, :3], T[:3, 3] = Rb.T @ data.xmat[tip].reshape(3, 3), Rb.T @ (data.xpos[tip] - pb)
        worst["fk"] = max(worst["fk"], _rel(robot.fk(q), T))
        mujoco.mj_jacBody(model, data, jp, jr, tip)
        J = np.vstack([Rb.T @ jp[:, act], Rb.T @ jr[:, act]])
        worst["J"] = max(worst["J"], _rel(robot.jacobian(q), J))
    version = getattr(mujoco, "__version__", "?")
    labels = {"M": "M = MuJoCo mj_fullM", "bias": "bias = MuJoCo qfrc_bias", "fk": "fk = MuJoCo body pose",
              "J": "J = MuJoCo mj_jacBody"}
    ids = tuple(Identity(labels[k], worst[k], TOLERANCE, worst[k] <= TOLERANCE) for k in labels)
    return RobotCheck(identities=ids, samples=samples, seed=seed, reference=f"mujoco {version}")
