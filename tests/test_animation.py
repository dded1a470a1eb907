"""Watching the arm (issue 41): the skeleton an animation draws against
Pinocchio's joint placements and the DH geometry, and `simulate --animate`'s
GIF (its frames, their timing, nothing else changed)."""

from __future__ import annotations

import os
import subprocess
import sys

import numpy as np
import pytest

from tmtcontrol import load_robot


@pytest.mark.parametrize("name", ["ur5", "panda"])
def test_skeleton_is_pinocchios_joint_placements(name):
    """Every actuated joint's origin equals Pinocchio's oMi translation (an
    independent forward kinematics of the same URDF), the last point the tip."""
    import pinocchio as pin

    robot = load_robot(name)
    model = pin.buildModelFromXML(robot.urdf)
    data = model.createData()
    rng = np.random.default_rng(41)
    for _ in range(5):
        q = rng.uniform(np.maximum(robot.q_min, -np.pi), np.minimum(robot.q_max, np.pi))
        full = pin.neutral(model)
        for i, joint in enumerate(robot.joint_names):
            full[model.joints[model.getJointId(joint)].idx_q] = q[i]
        for joint, value in robot.held.items():
            full[model.joints[model.getJointId(joint)].idx_q] = value
        pin.forwardKinematics(model, data, full)
        ref = np.column_stack([data.oMi[model.getJointId(j)].translation for j in robot.joint_names])
        pts = robot.joint_origins(q)
        assert pts.shape == (3, robot.n + 2)
        assert np.abs(pts[:, 1:-1] - ref).max() < 1e-12
        assert np.abs(pts[:, -1] - robot.fk(q)[:3, 3]).max() < 1e-12 and not pts[:, 0].any()


def test_puma_skeleton_keeps_its_dh_link_lengths():
    """Consecutive DH frame origins are sqrt(a^2 + d^2) apart at every posture."""
    robot = load_robot("puma560")
    lengths = [np.hypot(link.a, link.d) for link in robot.links]
    for q in np.random.default_rng(3).uniform(-2, 2, (5, 3)):
        pts = robot.joint_origins(q)
        assert np.allclose(np.linalg.norm(np.diff(pts[:, :4], axis=1), axis=0), lengths, atol=1e-12)


def test_frame_times_play_in_real_time_and_are_capped():
    from tmtcontrol.simulation.animation import MAX_FRAMES, frame_times

    assert np.allclose(frame_times(1.0, 10.0), np.arange(11) / 10)
    long = frame_times(1000.0, 10.0)
    assert long.size == MAX_FRAMES and long[0] == 0 and long[-1] == 1000.0


def test_simulate_animate_writes_the_gif(tmp_path):
    from PIL import Image

    from tmtcontrol.simulation.animation import frame_times

    runs = {}
    for flag in ([], ["--animate"]):
        out = tmp_path / ("with" if flag else "without")
        r = subprocess.run([sys.executable, "-m", "tmtcontrol.cli", "simulate", "paper", "--set",
                            "trajectory.cycles=0.25", "--no-plots", *flag, "--out", str(out)],
                           capture_output=True, text=True)
        assert r.returncode == 0, r.stderr
        runs[bool(flag)] = {p.name for p in out.iterdir()}
    assert runs[True] == runs[False] | {"animation.gif"}                  # the GIF, and nothing else changed
    with Image.open(tmp_path / "with" / "animation.gif") as gif:
        # the run's last sample is at 0.999 s: frames at 0, 0.1, ..., 0.9 s, played at 100 ms each
        assert gif.n_frames == frame_times(0.999).size == 10 and gif.info["duration"] == 100
        first = np.asarray(gif.convert("RGB"))
        gif.seek(gif.n_frames - 1)
        last = np.asarray(gif.convert("RGB"))
    assert (first != last).any()                                          # the arm moved, the force rose


def _mujoco_renders() -> bool:
    """Whether MuJoCo's offscreen renderer starts here with MUJOCO_GL=egl (probed in a fresh process:
    MuJoCo reads the variable on its first import)."""
    probe = ("import mujoco; m = mujoco.MjModel.from_xml_string('<mujoco><worldbody><geom size=\"0.1\"/>"
             "</worldbody></mujoco>'); mujoco.Renderer(m, 8, 8).close()")
    env = {**os.environ, "MUJOCO_GL": "egl"}
    return subprocess.run([sys.executable, "-c", probe], env=env, capture_output=True).returncode == 0


@pytest.mark.heavy      # MuJoCo's renderer on the UR5 (~4 s); the README suite stays within its 3 minutes
def test_simulate_animate_draws_with_mujoco_where_it_renders(tmp_path):
    """``simulate ur5 --animate`` with MUJOCO_GL=egl: where MuJoCo's renderer
    starts (probed independently), the GIF's frames are MuJoCo's (480 x 360,
    the command says so) and show the force arrow (red pixels) once the tool
    presses, not at t = 0 before contact; elsewhere the command says why it
    drew with matplotlib. The PUMA (no URDF) is drawn by matplotlib, saying
    why."""
    from PIL import Image

    env = {**os.environ, "MUJOCO_GL": "egl"}
    out = tmp_path / "ur5"
    r = subprocess.run([sys.executable, "-m", "tmtcontrol.cli", "simulate", "ur5", "--set", "trajectory.cycles=0.25",
                        "--no-plots", "--animate", "--out", str(out)], capture_output=True, text=True, env=env)
    assert r.returncode == 0, r.stderr
    if not _mujoco_renders():
        assert "animation.gif drawn by matplotlib (MuJoCo's renderer did not start" in r.stdout
        return
    assert "animation.gif drawn by MuJoCo's renderer" in r.stdout
    with Image.open(out / "animation.gif") as gif:
        assert gif.size == (480, 360) and gif.n_frames == 10
        first = np.asarray(gif.convert("RGB")).astype(int)
        gif.seek(gif.n_frames - 1)
        last = np.asarray(gif.convert("RGB")).astype(int)

    def red(img):
        return int(np.count_nonzero((img[..., 0] > 170) & (img[..., 1] < 70) & (img[..., 2] < 70)))

    assert red(first) == 0 and red(last) > 20          # f_e = 0 at t = 0 (the tool on the surface), 10 N at 0.9 s
    assert (first != last).any()
    puma = subprocess.run([sys.executable, "-m", "tmtcontrol.cli", "simulate", "paper", "--set",
                           "trajectory.cycles=0.1", "--no-plots", "--animate", "--out", str(tmp_path / "puma")],
                          capture_output=True, text=True, env=env)
    assert puma.returncode == 0 and "drawn by matplotlib (puma560 has no URDF for MuJoCo to load)" in puma.stdout


_ARROW_SCENE = """
import numpy as np, mujoco
from tmtcontrol.simulation.mujoco_render import force_arrow
xml = ('<mujoco><visual><global offwidth="600" offheight="600"/></visual><worldbody>'
       '<camera name="side" pos="0 -1.5 0.05" xyaxes="1 0 0 0 0 1" fovy="10"/>'
       '<geom type="box" size="0.01 0.01 0.05" pos="-0.05 0 0.05" rgba="0 1 0 1"/></worldbody></mujoco>')
m = mujoco.MjModel.from_xml_string(xml); d = mujoco.MjData(m); mujoco.mj_forward(m, d)
r = mujoco.Renderer(m, 600, 600)
r.update_scene(d, camera="side")
force_arrow(r.scene.geoms[r.scene.ngeom], [0.05, 0.0, 0.0], np.eye(3), 10.0)   # 10 N up from z = 0
r.scene.ngeom += 1
I = r.render().astype(int)
red = (I[..., 0] > I[..., 1] + 40) & (I[..., 0] > I[..., 2] + 40)
green = (I[..., 1] > I[..., 0] + 40) & (I[..., 1] > I[..., 2] + 40)
print(np.count_nonzero(red.any(1)), np.count_nonzero(green.any(1)))
"""


def test_mujocos_force_arrow_is_drawn_1_cm_per_newton():
    """Regression (review 18): MuJoCo draws an arrow of size[2] = L half as long (measured),
    so the 10 N arrow was 5 cm, not the documented 10 cm (the matplotlib fallback's). Seen
    from the side beside a 0.1 m box at the same depth, the 10 N arrow spans the box's rows
    (within 3 %: the head's shading at the tip)."""
    if not _mujoco_renders():
        pytest.skip("MuJoCo's renderer does not start here (MUJOCO_GL=egl)")
    r = subprocess.run([sys.executable, "-c", _ARROW_SCENE], env={**os.environ, "MUJOCO_GL": "egl"},
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    arrow, box = map(int, r.stdout.split())
    assert box > 200 and arrow == pytest.approx(box, rel=0.03)


_NO_GL = '''import ctypes
_orig = ctypes.CDLL.__init__
def _init(self, name, *a, **k):
    if name and any(s in str(name) for s in ("libGL", "libOpenGL", "libEGL", "libGLES", "libOSMesa")):
        raise OSError(f"{name}: cannot open shared object file (simulated)")
    return _orig(self, name, *a, **k)
ctypes.CDLL.__init__ = _init
'''


@pytest.mark.heavy
def test_without_opengl_libraries_the_animation_falls_back_to_matplotlib(tmp_path):
    """Regression (review): on a headless machine whose OpenGL libraries do
    not load (simulated by a sitecustomize that refuses them), MuJoCo fails
    to import with MUJOCO_GL=egl, raising AttributeError, not ImportError;
    ``simulate ur5 --animate`` must still write the GIF with matplotlib and
    say why, not crash after simulating."""
    site = tmp_path / "nogl"
    site.mkdir()
    (site / "sitecustomize.py").write_text(_NO_GL)
    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "MUJOCO_GL")}
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(site), env.get("PYTHONPATH")]))
    out = tmp_path / "o"
    r = subprocess.run([sys.executable, "-m", "tmtcontrol.cli", "simulate", "ur5", "--set", "trajectory.cycles=0.1",
                        "--no-plots", "--animate", "--out", str(out)], capture_output=True, text=True, env=env)
    assert r.returncode == 0, r.stderr
    assert "animation.gif drawn by matplotlib (MuJoCo did not load with MUJOCO_GL=" in r.stdout
    assert (out / "animation.gif").is_file()


_RENDERER_ABORTS = '''import os
try:
    import mujoco
except Exception:
    pass
else:
    def _abort(self, *a, **k):
        os.abort()
    mujoco.Renderer.__init__ = _abort
'''


@pytest.mark.heavy
def test_a_renderer_that_aborts_the_process_falls_back_to_matplotlib(tmp_path):
    """Regression (CI): on a machine whose OpenGL driver aborts the process
    when MuJoCo's renderer starts (SIGABRT inside ``mujoco.Renderer``,
    simulated by a sitecustomize that makes its constructor call
    ``os.abort``), the report's still and ``simulate --animate`` must not die
    with it: the renderer is first started in a child process, its crash is
    named, and matplotlib draws."""
    site = tmp_path / "abort"
    site.mkdir()
    (site / "sitecustomize.py").write_text(_RENDERER_ABORTS)
    env = {**os.environ, "MUJOCO_GL": "egl",
           "PYTHONPATH": os.pathsep.join(filter(None, [str(site), os.environ.get("PYTHONPATH")]))}
    out = tmp_path / "o"
    r = subprocess.run([sys.executable, "-m", "tmtcontrol.cli", "simulate", "ur5", "--set", "trajectory.cycles=0.1",
                        "--no-plots", "--animate", "--out", str(out)], capture_output=True, text=True, env=env)
    assert r.returncode == 0, r.stderr
    assert ("animation.gif drawn by matplotlib (MuJoCo's renderer did not start (MUJOCO_GL=egl): "
            "starting it killed a test process (SIGABRT))") in r.stdout
    assert (out / "animation.gif").is_file()


def test_mujocos_renderer_aborting_while_drawing_is_one_line_and_the_process_lives():
    """MuJoCo's renderer aborted a pytest worker (SIGABRT in EGL) though the
    probe in a fresh process had started it: the frames are now drawn in a
    forked child, whose death by a signal is RenderUnavailable naming it
    (matplotlib then draws), whose exceptions arrive here, and whose
    answer is the frames themselves."""
    import faulthandler
    import os
    import signal

    import numpy as np

    from tmtcontrol.simulation.animation import _in_child
    from tmtcontrol.simulation.mujoco_render import RenderUnavailable

    # the child's faulthandler (pytest's, inherited through the fork) off: its dump of the stack is noise in the log
    with pytest.raises(RenderUnavailable, match="killed by SIGABRT"):
        _in_child(lambda: (faulthandler.disable(), os.kill(os.getpid(), signal.SIGABRT)))
    with pytest.raises(RenderUnavailable, match="no GL here"):
        _in_child(lambda: (_ for _ in ()).throw(RenderUnavailable("no GL here")))
    frames = _in_child(lambda n: [np.full((2, 3, 3), i, dtype=np.uint8) for i in range(n)], 4)
    assert [int(f[0, 0, 0]) for f in frames] == [0, 1, 2, 3] and frames[0].shape == (2, 3, 3)


def test_the_renderer_probe_keeps_mujocos_warnings_out_of_the_users_folder(tmp_path):
    """Regression: the renderer probe's child process ran MuJoCo with its
    default warning handler, which appends every warning to MUJOCO_LOG.TXT
    in the working folder (the user's: a file tmtcontrol did not need to
    write). The probe starts with a handler that prints to stderr: a
    warning raised after it (a NaN velocity stepped) leaves no file; the same
    step without it writes one (the control: that the step warns at all)."""
    from tmtcontrol.simulation.mujoco_render import _PROBE, _QUIET_WARNINGS

    assert _PROBE.startswith(_QUIET_WARNINGS)
    warn = ("import mujoco, numpy\n"
            "m = mujoco.MjModel.from_xml_string('<mujoco><worldbody><body><joint/><geom size=\"0.1\"/></body>"
            "</worldbody></mujoco>')\n"
            "d = mujoco.MjData(m)\nd.qvel[:] = numpy.nan\nmujoco.mj_step(m, d)\n")
    quiet, loud = tmp_path / "quiet", tmp_path / "loud"
    for folder, code in ((quiet, _QUIET_WARNINGS + warn), (loud, warn)):
        folder.mkdir()
        r = subprocess.run([sys.executable, "-c", code], cwd=folder, capture_output=True, text=True, timeout=120)
        assert r.returncode == 0, r.stderr
    assert list(quiet.iterdir()) == []
    assert [p.name for p in loud.iterdir()] == ["MUJOCO_LOG.TXT"]


def test_the_matplotlib_animation_draws_equal_ranges_equal_and_the_stills_renderer_label_inside(monkeypatch):
    """Review 53 (low): the fallback's 3-D axes had equal data ranges but matplotlib's default box
    aspect (4 : 4 : 3), so the pipe's round section was an ellipse and the force arrow's drawn length
    depended on its direction; and the report's still named its renderer in a title below the
    picture, outside the saved SVG's view box: the label now lies within the figure."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    from tmtcontrol.simulation import animation
    from tmtcontrol.simulation.scenario import apply_overrides, load_scenario
    from tmtcontrol.simulation.simulator import Simulator, robot_of

    res = Simulator(apply_overrides(load_scenario("paper"), ["trajectory.cycles=0.05"]), compile=False).run()
    fig, draw, _ = animation._matplotlib_frames(res, robot_of(res.scenario), np.array([0, res.time.size - 1]))
    ax = fig.axes[0]
    spans = [np.ptp(lim) for lim in (ax.get_xlim(), ax.get_ylim(), ax.get_zlim())]
    assert np.allclose(spans, spans[0]) and np.allclose(ax.get_box_aspect() / ax.get_box_aspect()[0], 1.0)

    monkeypatch.setattr(animation, "still", lambda result, robot=None, renderer="auto":
                        (np.zeros((60, 80, 3), dtype=np.uint8), "matplotlib"))
    still = animation.still_figure(res)
    canvas = FigureCanvasAgg(still)
    canvas.draw()
    (label,) = [t for t in still.axes[0].texts if t.get_text() == "drawn by matplotlib"]
    box = label.get_window_extent(canvas.get_renderer())
    assert 0 <= box.x0 and box.x1 <= still.bbox.width and 0 <= box.y0 and box.y1 <= still.bbox.height, box
    from tmtcontrol.report.document import describe

    # its alt text names the picture by that label (the final CI's heavy report test: the title gone, it read "Chart.")
    assert describe(still) == "Chart. drawn by matplotlib: an image."


def test_the_matplotlib_animations_frame_label_is_clear_of_the_force_panels_legend_and_inside_the_figure():
    """Sixteenth session's note: the force panel's "t = ... f_e = ... k_e = ..." line, drawn at the
    panel's top left, ran under its legend at the top right at the paper's 1,000,000 N/m. Both boxes
    measured by Agg's renderer on the last frame (the longest k_e of the run)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    from tmtcontrol.simulation import animation
    from tmtcontrol.simulation.scenario import apply_overrides, load_scenario
    from tmtcontrol.simulation.simulator import Simulator, robot_of

    res = Simulator(apply_overrides(load_scenario("paper"), ["trajectory.cycles=0.05"]), compile=False).run()
    res.stiffness[-1] = 1.0e6                  # the widest k_e the paper's segments print (seven digits, two commas)
    fig, draw, idx = animation._matplotlib_frames(res, robot_of(res.scenario), np.array([0, res.time.size - 1]))
    draw(1)
    canvas = FigureCanvasAgg(fig)
    canvas.draw()
    renderer = canvas.get_renderer()
    axf = fig.axes[1]
    (label,) = [t for t in axf.texts if t.get_text().startswith("t = ")]
    assert "1,000,000 N/m" in label.get_text()
    lab, leg = label.get_window_extent(renderer), axf.get_legend().get_window_extent(renderer)
    assert not lab.overlaps(leg), (lab, leg)
    assert 0 <= lab.x0 and lab.x1 <= fig.bbox.width and 0 <= lab.y0 and lab.y1 <= fig.bbox.height, lab
