"""Frames of a run drawn by MuJoCo's offscreen renderer: the arm, the part and the contact force (issue 41).

:func:`render_frames` draws a :class:`.simulator.SimulationResult` of an arm
with a URDF at given times: MuJoCo's model of the same URDF
(:func:`tmtcontrol.model.against_mujoco.mujoco_model`) posed at the logged
joints, its links drawn as capsules between consecutive body origins (the
bundled URDFs have no meshes), the part as a MuJoCo geom
(:func:`.mujoco_plant.add_part`: a plane, or a sphere or cylinder worked from
outside; a concave part or a height map is drawn as its tangent plane at the
path's centre), the tool as a small sphere, and the contact force on the
tool as a red arrow (1 cm per N, along the surface's outward normal), with
the time, force and stiffness written on the image.

MuJoCo renders through OpenGL without a window: ``MUJOCO_GL=egl`` (a GPU or
a headless EGL driver) or ``MUJOCO_GL=osmesa`` (software), read when MuJoCo
is first imported. :func:`prefer_headless_gl` sets ``egl`` where nothing is
set and there is no display; the command line calls it before anything
imports MuJoCo. Where no backend works (or MuJoCo is not installed, or the
arm has no URDF: the PUMA), :class:`RenderUnavailable` says why and
:mod:`.animation` draws with matplotlib instead.

Some OpenGL drivers do not fail politely: on a machine with the EGL loader
but no working driver, creating the renderer aborts the whole process
(SIGABRT) or hangs. :func:`renderer_problem` therefore starts the renderer
once in a child process with the same environment (at most
:data:`PROBE_TIMEOUT` s) before this process tries; a crash or hang there is
one line of :class:`RenderUnavailable`, and matplotlib draws.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys

import numpy as np

__all__ = ["RenderUnavailable", "prefer_headless_gl", "render_frames", "renderer_problem", "FORCE_SCALE",
           "PROBE_TIMEOUT"]

PROBE_TIMEOUT = 60.0
"""Seconds the child process of :func:`renderer_problem` may take to start
MuJoCo's renderer and draw one frame (it takes about 1 s)."""

_QUIET_WARNINGS = ("import sys\nimport mujoco\n"
                   "mujoco.set_mju_user_warning(lambda message: print(message, file=sys.stderr))\n")
"""The probe's first lines: MuJoCo's default warning handler would print to
stdout and append to MUJOCO_LOG.TXT in the working folder (the user's)."""

_PROBE = (_QUIET_WARNINGS +
          "m = mujoco.MjModel.from_xml_string('<mujoco><worldbody><light pos=\"0 0 1\"/><geom size=\"0.1\"/>"
          "</worldbody></mujoco>')\n"
          "r = mujoco.Renderer(m, 8, 8)\n"
          "d = mujoco.MjData(m)\n"
          "mujoco.mj_forward(m, d)\n"
          "r.update_scene(d)\n"
          "r.render()\n"
          "r.close()\n")
_probed: dict[str, str | None] = {}

FORCE_SCALE = 0.01
"""Length of the force arrow per newton (m/N): f_d = 10 N is 0.1 m."""

ARROW_DRAWN = 0.5
"""How long MuJoCo draws an ``mjGEOM_ARROW`` of ``size[2] = L``, per L:
measured 0.5 (MuJoCo 4.0.1: an arrow of L = 0.1 m spans half a 0.1 m box
beside it, with ``mjv_initGeom`` and ``mjv_connector`` alike; review 18: the
arrow was drawn at half of :data:`FORCE_SCALE`, tested in
tests/test_animation.py)."""

ARROW_RADIUS = 0.035
"""The force arrow's radius, m: wider than the wrist links it runs along
(the force on the tool points along the tool's axis, into the wrist), or
the links hide it (0.02 m: 42 red pixels of a 480 x 360 frame of the UR5;
0.008 m: none)."""


def force_arrow(geom, point, frame, f: float) -> None:
    """Make the scene ``geom`` the force arrow of ``f`` newtons from ``point``
    along the third column of ``frame`` (3x3), :data:`FORCE_SCALE` long per
    newton as drawn, red."""
    import mujoco

    mujoco.mjv_initGeom(geom, mujoco.mjtGeom.mjGEOM_ARROW,
                        np.array([ARROW_RADIUS, ARROW_RADIUS, FORCE_SCALE * f / ARROW_DRAWN]),
                        np.asarray(point, float), np.asarray(frame, float).ravel(),
                        np.array([0.85, 0.1, 0.1, 1.0], dtype=np.float32))


class RenderUnavailable(RuntimeError):
    """MuJoCo cannot render this run here; the message says why."""


def prefer_headless_gl() -> None:
    """``MUJOCO_GL=egl`` when no backend is chosen, there is no display and
    the EGL and OpenGL libraries are there (MuJoCo reads it on its first
    import; without them the variable would stop MuJoCo from loading at
    all, physics included)."""
    import ctypes.util

    if "MUJOCO_GL" in os.environ or os.environ.get("DISPLAY"):
        return
    if ctypes.util.find_library("EGL") and (ctypes.util.find_library("OpenGL") or ctypes.util.find_library("GL")):
        os.environ["MUJOCO_GL"] = "egl"


def renderer_problem() -> str | None:
    """``None`` where MuJoCo's offscreen renderer starts and draws a frame in
    a child process with this process's environment (``MUJOCO_GL``
    included); otherwise one line saying why (its error, the signal that
    killed it, or a hang beyond :data:`PROBE_TIMEOUT` s). Asked once per
    process and backend."""
    gl = os.environ.get("MUJOCO_GL", "unset")
    if gl not in _probed:
        why = None
        try:
            r = subprocess.run([sys.executable, "-c", _PROBE], capture_output=True, text=True,
                               timeout=PROBE_TIMEOUT, stdin=subprocess.DEVNULL)
        except subprocess.TimeoutExpired:
            why = f"it did not start within {PROBE_TIMEOUT:g} s"
        else:
            if r.returncode < 0:
                try:
                    name = signal.Signals(-r.returncode).name
                except ValueError:
                    name = f"signal {-r.returncode}"
                why = f"starting it killed a test process ({name})"
            elif r.returncode > 0:
                lines = [ln.strip() for ln in r.stderr.splitlines() if ln.strip()]
                why = lines[-1] if lines else f"a test process exited with status {r.returncode}"
        _probed[gl] = None if why is None else f"MuJoCo's renderer did not start (MUJOCO_GL={gl}): {why}"
    return _probed[gl]


def _scene_model(robot, surface):
    from ..model.against_mujoco import MujocoMissing, base_body, import_mujoco, mujoco_model
    from ..surface import Plane
    from .mujoco_plant import TOOL_RADIUS, add_part

    if robot.urdf is None:
        raise RenderUnavailable(f"{robot.name} has no URDF for MuJoCo to load")
    try:
        mujoco = import_mujoco()
    except MujocoMissing as exc:
        raise RenderUnavailable(str(exc)) from None

    def edit(spec):
        spec.compiler.discardvisual = False           # the geoms added here are visual only
        for body in list(spec.bodies):
            parent = body.parent
            if parent is None or parent.name == body.name:
                continue
            tip = np.asarray(body.pos, dtype=float)
            if np.linalg.norm(tip) > 1e-4:                     # a link: a capsule from the parent's origin
                g = parent.add_geom()
                g.type, g.size = mujoco.mjtGeom.mjGEOM_CAPSULE, [0.025, 0.0, 0.0]
                g.fromto = [0.0, 0.0, 0.0, *tip.tolist()]
                g.rgba, g.contype, g.conaffinity, g.density = [0.25, 0.45, 0.8, 1.0], 0, 0, 0.0
        shown = surface
        if surface.primitive() is None:                      # a bowl, a bore, a height map: its tangent plane
            shown = Plane(surface.frame(surface.c), surface.c)
        part = add_part(mujoco, base_body(spec, robot), shown)
        part.contype = part.conaffinity = 0
        part.rgba = [0.7, 0.7, 0.7, 0.6]
        if part.type == mujoco.mjtGeom.mjGEOM_PLANE:          # drawn as a 0.6 m square around the path's centre
            part.size = [0.3, 0.3, 0.01]
        light = spec.worldbody.add_light()
        light.pos, light.dir = [0.0, 0.0, 3.0], [0.0, 0.0, -1.0]
        tool = spec.body(robot.tip).add_geom()
        tool.type, tool.size = mujoco.mjtGeom.mjGEOM_SPHERE, [max(4 * TOOL_RADIUS, 0.01), 0.0, 0.0]
        tool.rgba, tool.contype, tool.conaffinity, tool.density = [0.9, 0.6, 0.1, 1.0], 0, 0, 0.0

    return mujoco, *mujoco_model(robot, lock_held=True, edit=edit)[1:]


def render_frames(result, indices, size: tuple[int, int] = (480, 360), robot=None) -> list[np.ndarray]:
    """RGB frames (height x width x 3, uint8) of ``result`` at the samples
    ``indices``; ``robot``: the arm whose joints were logged (default: the
    scenario's). Raises :class:`RenderUnavailable` (module docstring)."""
    from PIL import Image, ImageDraw

    from ..model.against_mujoco import base_id
    from ..surface import normal_frame
    from .geometry import surface_of
    from .simulator import robot_of

    import warnings

    robot = robot if robot is not None else robot_of(result.scenario)
    surface = surface_of(result.scenario)
    if "mujoco" not in sys.modules:            # the backend is chosen on MuJoCo's first import
        prefer_headless_gl()
    mujoco, m, d = _scene_model(robot, surface)
    problem = renderer_problem()            # in a child process first: some drivers abort or hang
    if problem is not None:
        raise RenderUnavailable(problem)
    width, height = size
    m.vis.headlight.ambient[:], m.vis.headlight.diffuse[:] = 0.45, 0.5
    m.vis.global_.offwidth, m.vis.global_.offheight = max(width, 640), max(height, 480)
    try:
        with warnings.catch_warnings():        # GLFW's own warnings where there is no display: said below instead
            warnings.simplefilter("ignore")
            renderer = mujoco.Renderer(m, height, width)
    except Exception as exc:                 # no OpenGL backend: MuJoCo says which
        raise RenderUnavailable(f"MuJoCo's renderer did not start (MUJOCO_GL="
                                f"{os.environ.get('MUJOCO_GL', 'unset')}): {str(exc).splitlines()[0]}") from None
    frames = []
    try:
        qadr = np.array([m.jnt_qposadr[m.joint(name).id] for name in robot.joint_names])
        base = base_id(m, robot)
        cam = mujoco.MjvCamera()
        mujoco.mj_forward(m, d)
        Rb, pb = d.xmat[base].reshape(3, 3), d.xpos[base].copy()
        centre = pb + Rb @ np.asarray(result.scenario.trajectory.center, dtype=float)
        reach = max(float(np.linalg.norm(centre - pb)), 0.3)
        cam.lookat[:] = (centre + pb) / 2 + [0.0, 0.0, 0.25 * reach]
        cam.distance = 3.2 * reach
        cam.azimuth, cam.elevation = 135.0, -20.0
        for k in indices:
            d.qpos[qadr] = result.q[:, k]
            mujoco.mj_kinematics(m, d)
            renderer.update_scene(d, camera=cam)
            f = float(result.contact_force[k])
            if f > 0 and renderer.scene.ngeom < renderer.scene.maxgeom:
                p = pb + Rb @ result.position[:, k]
                # the arrow's z along the force on the tool, out of the part (its x, y: the frame's tangents)
                n_out, t1, t2 = normal_frame(-(Rb @ surface.normal(result.position[:, k]))).T
                mat = np.column_stack([t1, t2, n_out])
                force_arrow(renderer.scene.geoms[renderer.scene.ngeom], p, mat, f)
                renderer.scene.ngeom += 1
            img = Image.fromarray(renderer.render())
            ImageDraw.Draw(img).text((8, 6), f"t = {result.time[k]:5.2f} s   f_e = {f:6.2f} N   "
                                     f"k_e = {result.stiffness[k]:,.0f} N/m", fill=(255, 255, 255))
            frames.append(np.asarray(img))
    finally:
        renderer.close()
    return frames
