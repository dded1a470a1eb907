"""Watch the arm do the task: an animated GIF of a run, the arm's skeleton on the surface with the force beside it.

``tmtcontrol simulate SCENARIO --animate`` writes ``animation.gif`` next to
the figures: each frame draws the surface around the path (the part itself
on a curved scenario), the desired path X_d on it, the trace of the tool
point so far, the arm as its skeleton (base, every joint's origin, the
tool point; :meth:`tmtcontrol.model.Robot.joint_origins`) at that instant,
from the run's logged joints (the same for the built-in, MuJoCo and
exported-C plants), and the contact force on the tool as a red arrow from
the tool point along the surface's outward normal, as long as MuJoCo's
(:data:`.mujoco_render.FORCE_SCALE`, 1 cm per N; none while the tool is
off the surface). Beside it the contact force against f_d up to that
instant, and the time, k_e and the segment's stiffness. Frames are sampled
every ``1 / fps`` s of simulated time (at most :data:`MAX_FRAMES`); the GIF
plays in real time. Written by Pillow, matplotlib's own writer: no ffmpeg
and no OpenGL needed.

Where MuJoCo can render (the ``mujoco`` extra, an arm with a URDF, an
OpenGL backend without a window: ``MUJOCO_GL=egl`` or ``osmesa``),
``renderer="auto"`` draws the frames with MuJoCo's offscreen renderer
instead (:mod:`.mujoco_render`: the arm's links as capsules, the part, the
force as an arrow, the time, force and stiffness written on each frame);
elsewhere matplotlib, as above. :func:`write_animation` returns which, and
why not MuJoCo. :func:`still` is one such frame (the report shows the last).
"""

from __future__ import annotations

import contextlib

import pathlib
from dataclasses import dataclass

import numpy as np

__all__ = ["write_animation", "still", "still_figure", "Drawn", "MAX_FRAMES", "DEFAULT_FPS"]

MAX_FRAMES = 400
"""Most frames of one animation (a 16 s run at 10 frames per second is 160)."""

DEFAULT_FPS = 10.0
"""Frames per second of simulated time (and of playback: real time)."""


def frame_times(duration: float, fps: float = DEFAULT_FPS) -> np.ndarray:
    """The frames' simulated times (s): every ``1/fps`` from 0, at most
    :data:`MAX_FRAMES` (then evenly spread over the run)."""
    n = int(np.floor(duration * fps)) + 1
    if n > MAX_FRAMES:
        return np.linspace(0.0, duration, MAX_FRAMES)
    return np.arange(n) / fps


@dataclass(frozen=True)
class Drawn:
    """What :func:`write_animation` wrote: ``path``, ``renderer``
    (``"mujoco"`` or ``"matplotlib"``) and, for matplotlib, why not MuJoCo
    (``why``, one line; empty when matplotlib was asked for)."""
    path: pathlib.Path
    renderer: str
    why: str = ""


def _in_child(fn, *args, **kw):
    """``fn(*args, **kw)`` in a forked child process on Linux, its result
    (pickled) through a pipe: MuJoCo's offscreen renderer has aborted the
    whole process on starting (SIGABRT in EGL) even where a probe in a fresh
    process had started it (``mujoco_render.renderer_problem``), so it is
    never started in this one. A child killed by a signal, or ending without
    an answer, raises :class:`~.mujoco_render.RenderUnavailable` saying so
    (matplotlib then draws); an exception in the child is raised here. The
    child is killed if this process stops waiting (Ctrl-C). Elsewhere than
    Linux, ``fn`` runs here."""
    import os
    import pickle
    import signal

    from ..drawing import can_fork, read_all, write_all
    from .mujoco_render import RenderUnavailable

    if not can_fork():
        return fn(*args, **kw)
    r, w = os.pipe()
    pid = os.fork()
    if pid == 0:                                   # the child: answer through the pipe, then leave at once
        code = 0
        try:
            os.close(r)
            try:
                out = ("ok", fn(*args, **kw))
            except BaseException as exc:           # noqa: BLE001 - every failure goes to the parent
                out = ("error", exc)
            write_all(w, pickle.dumps(out, protocol=pickle.HIGHEST_PROTOCOL))
        except BaseException:                      # noqa: BLE001
            code = 1
        finally:
            os._exit(code)
    os.close(w)
    try:
        data = read_all(r)
        _, status = os.waitpid(pid, 0)
    except BaseException:
        with contextlib.suppress(OSError):
            os.kill(pid, signal.SIGKILL)
            os.waitpid(pid, 0)
        raise
    finally:
        os.close(r)
    if os.WIFSIGNALED(status):
        name = signal.Signals(os.WTERMSIG(status)).name
        raise RenderUnavailable(f"MuJoCo's renderer was killed by {name} while drawing")
    try:
        kind, value = pickle.loads(data)
    except Exception:                              # noqa: BLE001 - no answer: the child failed to write it
        raise RenderUnavailable("MuJoCo's renderer ended without its frames") from None
    if kind == "error":
        raise value
    return value


def _mujoco_frames(result, indices, robot, renderer: str):
    """MuJoCo's frames, or ``(None, why)`` where it cannot render and ``renderer`` allows matplotlib."""
    if renderer == "matplotlib":
        return None, ""
    from .mujoco_render import RenderUnavailable, render_frames

    try:
        return _in_child(render_frames, result, indices, robot=robot), ""
    except RenderUnavailable as exc:
        if renderer == "mujoco":
            raise
        return None, str(exc)


def still(result, robot=None, renderer: str = "auto") -> tuple[np.ndarray, str]:
    """``(rgb, renderer)``: the last instant of ``result`` as an image
    (height x width x 3, uint8), drawn by MuJoCo where it can render (module
    docstring), else by matplotlib (the animation's first panel)."""
    from .simulator import robot_of

    robot = robot if robot is not None else robot_of(result.scenario)
    k = result.time.size - 1
    frames, _ = _mujoco_frames(result, [k], robot, renderer)
    if frames is not None:
        return frames[0], "mujoco"
    fig, draw, _ = _matplotlib_frames(result, robot, np.array([k]))
    draw(0)
    fig.canvas.draw()
    return np.asarray(fig.canvas.buffer_rgba())[..., :3].copy(), "matplotlib"


def still_figure(result):
    """A matplotlib figure of :func:`still` (for the report)."""
    from matplotlib.figure import Figure

    rgb, how = still(result)
    h, w = rgb.shape[:2]
    fig = Figure(figsize=(4.5, 4.5 * h / w))
    ax = fig.add_axes((0.0, 0.0, 1.0, 1.0))
    ax.imshow(rgb)
    ax.set_axis_off()
    # inside the picture (review 53: a title below the axes fell outside the saved SVG's view box)
    ax.text(0.01, 0.01, f"drawn by {'MuJoCo' if how == 'mujoco' else 'matplotlib'}", transform=ax.transAxes,
            fontsize=7, ha="left", va="bottom", color="0.2", bbox={"facecolor": "white", "alpha": 0.7, "lw": 0})
    return fig


def write_animation(result, path, robot=None, fps: float = DEFAULT_FPS, dpi: int = 90,
                    renderer: str = "auto") -> Drawn:
    """Write the GIF of ``result`` (a :class:`.simulator.SimulationResult`) to
    ``path``; ``robot`` the arm whose joints were logged (default: the
    scenario's); ``renderer``: ``"auto"`` (MuJoCo where it can render, else
    matplotlib), ``"mujoco"`` (raises
    :class:`.mujoco_render.RenderUnavailable` where it cannot) or
    ``"matplotlib"``."""
    from .simulator import robot_of

    if renderer not in ("auto", "mujoco", "matplotlib"):
        raise ValueError(f"renderer: expected 'auto', 'mujoco' or 'matplotlib', got {renderer!r}")
    robot = robot if robot is not None else robot_of(result.scenario)
    t = result.time
    times = frame_times(float(t[-1]), fps)
    idx = np.minimum(np.searchsorted(t, times), t.size - 1)
    path = pathlib.Path(path)
    frames, why = _mujoco_frames(result, idx, robot, renderer)
    if frames is not None:
        from PIL import Image

        images = [Image.fromarray(f).convert("P", palette=Image.Palette.ADAPTIVE) for f in frames]
        images[0].save(path, save_all=True, append_images=images[1:], duration=int(round(1000 / fps)), loop=0)
        return Drawn(path, "mujoco")
    from matplotlib.animation import FuncAnimation, PillowWriter

    fig, draw, _ = _matplotlib_frames(result, robot, idx)
    anim = FuncAnimation(fig, draw, frames=len(idx), blit=False)
    anim.save(path, writer=PillowWriter(fps=fps), dpi=dpi)
    return Drawn(path, "matplotlib", why)


def _matplotlib_frames(result, robot, idx):
    """``(figure, draw(i), idx)``: the matplotlib figure of the animation
    and the function that draws its frame i (sample ``idx[i]``)."""
    import matplotlib

    matplotlib.use("Agg", force=False)
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    from .figures import desired_path
    from .geometry import surface_of
    from .mujoco_render import FORCE_SCALE

    tr = result.traces
    t = result.time
    skeletons = np.stack([robot.joint_origins(result.q[:, k]) for k in idx])      # frames x 3 x points
    xd = desired_path(tr)

    fig = Figure(figsize=(8.0, 4.2))
    FigureCanvasAgg(fig)
    ax = fig.add_subplot(1, 2, 1, projection="3d")
    axf = fig.add_subplot(1, 2, 2)
    if tr.surface_mesh is not None:
        ax.plot_surface(*tr.surface_mesh, alpha=0.25, color="tab:gray")
    stride = max(1, t.size // 2000)
    ax.plot(*xd[:, ::stride], "k--", lw=0.7)
    everything = np.hstack([skeletons.transpose(1, 0, 2).reshape(3, -1), result.position[:, ::stride]])
    lo, hi = everything.min(axis=1), everything.max(axis=1)
    half = 0.55 * float(np.max(hi - lo))
    mid = (lo + hi) / 2
    ax.set(xlim=(mid[0] - half, mid[0] + half), ylim=(mid[1] - half, mid[1] + half),
           zlim=(mid[2] - half, mid[2] + half), xlabel="x (m)", ylabel="y (m)", zlabel="z (m)")
    ax.set_box_aspect((1.0, 1.0, 1.0))        # equal ranges drawn equal (review 53: z 25 % short, a pipe an ellipse)
    ax.set_title(f"{robot.name} on the {tr.surface_name}", fontsize=9)
    arm, = ax.plot([], [], [], "-o", color="tab:blue", lw=3, ms=4)
    trace, = ax.plot([], [], [], color="tab:red", lw=1)
    axf.plot(t, result.desired_force, "k--", lw=0.8, label="f_d")
    force, = axf.plot([], [], color="tab:red", lw=1, label="f_e")
    top = float(np.nanmax(result.contact_force[np.isfinite(result.contact_force)], initial=1.0))
    axf.set(xlim=(0.0, float(t[-1])), ylim=(0.0, 1.1 * max(top, float(result.desired_force.max()))),
            xlabel="time (s)", ylabel="contact force (N)")
    axf.legend(loc="upper right", fontsize=8)
    # the frame's time, force and stiffness above the panel: inside, a long line ran under the legend
    label = axf.text(0.0, 1.02, "", transform=axf.transAxes, va="bottom", fontsize=8)
    fig.subplots_adjust(left=0.02, right=0.98, wspace=0.35)
    surface = surface_of(result.scenario)
    arrow = []                                           # the force arrow drawn now (a Line3DCollection), if any

    def draw(i):
        k = idx[i]
        s = skeletons[i]
        arm.set_data(s[0], s[1])
        arm.set_3d_properties(s[2])
        while arrow:
            arrow.pop().remove()
        f = float(result.contact_force[k])
        if f > 0:                                        # the force on the tool: out of the part, 1 cm per N
            p = result.position[:, k]
            u = -FORCE_SCALE * f * surface.normal(p)
            arrow.append(ax.quiver(*p, *u, color="tab:red", lw=2, arrow_length_ratio=0.25))
        trace.set_data(result.position[0, :k + 1:stride], result.position[1, :k + 1:stride])
        trace.set_3d_properties(result.position[2, :k + 1:stride])
        force.set_data(t[:k + 1], result.contact_force[:k + 1])
        label.set_text(f"t = {t[k]:5.2f} s   f_e = {result.contact_force[k]:6.2f} N   "
                       f"k_e = {result.stiffness[k]:,.0f} N/m")
        return arm, trace, force, label, *arrow

    return fig, draw, idx
