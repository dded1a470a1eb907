"""Watch the arm do the task: an animated GIF of a run, the arm's skeleton on the surface with the force beside it.

``tmtcontrol simulate SCENARIO --animate`` writes ``animation.gif`` next to
the figures: each frame draws the surface around the path (the part itself
on a curved scenario), the desired path X_d on it, the trace of the tool
point so far, and the arm as its skeleton (base, every joint's origin, the
tool point; :meth:`tmtcontrol.model.Robot.joint_origins`) at that instant,
from the run's logged joints (the same for the built-in, MuJoCo and
exported-C plants). Beside it the contact force against f_d up to that
instant, and the time, k_e and the segment's stiffness. Frames are sampled
every ``1 / fps`` s of simulated time (at most :data:`MAX_FRAMES`); the GIF
plays in real time. Written by Pillow, matplotlib's own writer: no ffmpeg
and no OpenGL needed.
"""

from __future__ import annotations

import pathlib

import numpy as np

__all__ = ["write_animation", "MAX_FRAMES", "DEFAULT_FPS"]

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


def write_animation(result, path, robot=None, fps: float = DEFAULT_FPS, dpi: int = 90) -> pathlib.Path:
    """Write the GIF of ``result`` (a :class:`.simulator.SimulationResult`) to
    ``path``; ``robot`` the arm whose joints were logged (default: the
    scenario's). Returns the path."""
    import matplotlib

    matplotlib.use("Agg", force=False)
    from matplotlib.animation import FuncAnimation, PillowWriter
    from matplotlib.figure import Figure

    from .figures import desired_path
    from .simulator import robot_of

    robot = robot if robot is not None else robot_of(result.scenario)
    tr = result.traces
    t = result.time
    times = frame_times(float(t[-1]), fps)
    idx = np.minimum(np.searchsorted(t, times), t.size - 1)
    skeletons = np.stack([robot.joint_origins(result.q[:, k]) for k in idx])      # frames x 3 x points
    xd = desired_path(tr)

    fig = Figure(figsize=(8.0, 4.2))
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
    ax.set_title(f"{robot.name} on the {tr.surface_name}", fontsize=9)
    arm, = ax.plot([], [], [], "-o", color="tab:blue", lw=3, ms=4)
    trace, = ax.plot([], [], [], color="tab:red", lw=1)
    axf.plot(t, result.desired_force, "k--", lw=0.8, label="f_d")
    force, = axf.plot([], [], color="tab:red", lw=1, label="f_e")
    top = float(np.nanmax(result.contact_force[np.isfinite(result.contact_force)], initial=1.0))
    axf.set(xlim=(0.0, float(t[-1])), ylim=(0.0, 1.1 * max(top, float(result.desired_force.max()))),
            xlabel="time (s)", ylabel="contact force (N)")
    axf.legend(loc="upper right", fontsize=8)
    label = axf.text(0.02, 0.97, "", transform=axf.transAxes, va="top", fontsize=8)
    fig.subplots_adjust(left=0.02, right=0.98, wspace=0.25)

    def draw(i):
        k = idx[i]
        s = skeletons[i]
        arm.set_data(s[0], s[1])
        arm.set_3d_properties(s[2])
        trace.set_data(result.position[0, :k + 1:stride], result.position[1, :k + 1:stride])
        trace.set_3d_properties(result.position[2, :k + 1:stride])
        force.set_data(t[:k + 1], result.contact_force[:k + 1])
        label.set_text(f"t = {t[k]:5.2f} s   f_e = {result.contact_force[k]:6.2f} N   "
                       f"k_e = {result.stiffness[k]:,.0f} N/m")
        return arm, trace, force, label

    path = pathlib.Path(path)
    anim = FuncAnimation(fig, draw, frames=len(idx), blit=False)
    anim.save(path, writer=PillowWriter(fps=fps), dpi=dpi)
    return path
