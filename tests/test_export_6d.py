"""The exported C controller on a 6-D arm (issue 30): `tmtcontrol export ur5`
/ `panda` generates the 6-D task-frame controller from the expressions the
6-D simulation compiles (taskframe.build_pose_controller and the step share
_pose_control), with n joint angles and velocities in and n joint torques
out; software in the loop and replay equal the built-in 6-D run.

Tolerance of the equality checks: 1e-9 relative to each signal's largest
magnitude, as the PUMA's export (tests/test_export.py). What differs is
rounding: the force enters the controller as a base-frame vector and is
projected back on the normal, and the controller is compiled apart from the
plant. Measured over the 16 s UR5 and Panda runs: about 2e-13 (software in the
loop), 5e-16 (replay).
"""
import json
import shutil
import subprocess

import numpy as np
import pytest

from tmtcontrol.cli import main
from tmtcontrol.export import generate
from tmtcontrol.export.generate import export_controller
from tmtcontrol.simulation.scenario import apply_overrides, load_scenario, paper_scenario

RTOL = 1e-9
STRICT = ["-std=c99", "-Wall", "-Wextra", "-Werror", "-pedantic"]
SHORT = ["trajectory.cycles=0.04"]          # 160 periods of the 4 s circle, in contact


def rel_err(a, b):
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    return float(np.max(np.abs(a - b)) / max(np.max(np.abs(b)), 1e-300))


@pytest.fixture(scope="module")
def exported_ur5(tmp_path_factory):
    """The UR5 controller exported with the inner loop (not compiled)."""
    folder = tmp_path_factory.mktemp("export6d") / "ur5-c"
    assert main(["export", "ur5", "--inner-loop", "--out", str(folder)]) == 0
    return folder


# -- the default suite: generation, the tables, one set of expressions, the refusals -----------------

def test_export_of_the_ur5_writes_an_n_joint_interface(exported_ur5):
    header = (exported_ur5 / "tmt_controller.h").read_text()
    for decl in ("double q[6];", "double dq[6];", "double force[3];", "double q_c[6];", "double dq_c[6];",
                 "double tau[6];", "double e_o[3];", "double R_d[9];"):
        assert decl in header, decl
    assert "closedloop.build_controller" in header
    meta = json.loads((exported_ur5 / generate.METADATA).read_text())
    assert {k: meta["robot"][k] for k in ("model", "tip", "joints", "armature")} == {
        "model": "ur5", "tip": None, "joints": 6, "armature": True}
    assert meta["robot"]["key"]
    replay = (exported_ur5 / "replay.c").read_text()
    assert "t,q1,q2,q3,q4,q5,q6,dq1,dq2,dq3,dq4,dq5,dq6,force_x,force_y,force_z," in replay


def test_interface_tables_are_sized_by_the_joint_count():
    for n in (6, 7):
        m, c = generate.measurement_fields(n), generate.command_fields(True, n)
        assert [f.size for f in m] == [n, n, 3, 2, 2, 2]
        assert [f.size for f in c] == [3, 3, 3, 3, n, n, n]
        assert c[-1].columns == [f"tau{i}" for i in range(1, n + 1)]
        assert [f.size for f in generate.command_fields(False, n)] == [3, 3, 3, 3, n, n]
        assert generate.diagnostic_fields(n)[-1].name == "e_o"
    # the PUMA's tables are the ones its export always had
    assert generate.measurement_fields(3) == generate.MEASUREMENT_FIELDS
    assert generate.command_fields(True) == generate.COMMAND_FIELDS
    assert generate.diagnostic_fields(3) == generate.DIAGNOSTIC_FIELDS


@pytest.mark.parametrize("arm, delay", [("ur5", 0), ("ur5", 2), ("panda", 0)])
def test_exported_function_computes_what_the_6d_step_computes(arm, delay):
    """The Function generated as C, evaluated on a short built-in run's states
    and measurements (CasADi's virtual machine), gives the run's logged
    torques, commands and diagnostics (1e-12 relative: the force enters as a
    base-frame vector)."""
    from tmtcontrol.simulation.simulator import Simulator
    from tmtcontrol.model.robot import task_of
    from tmtcontrol.simulation.closedloop import (command_layout, diagnostics_layout, log_layout, param_layout,
                                                  state_layout)

    sc = apply_overrides(load_scenario(arm), [*SHORT, f"controller.delay_samples={delay}"])
    sim = Simulator(sc, compile=False)
    U, P, s0, _ = sim.inputs(sc)
    S, L = sim.rollout.run(s0, U, P)
    n, N = sim.plant.n, U.shape[1]
    iface = generate.interface(sc, True)
    fn, _ = generate.controller_function(sc, True)
    before = state_layout(task_of(n), sim.law, delay).split(np.hstack([s0[:, None], S[:, :-1]]))
    s_ctl = np.vstack([before[k] for k, s in iface.state.slices.items() if s.stop > s.start])
    lg = log_layout(task_of(n)).split(L)
    R = param_layout(task_of(n), sim.law).split(P)["R"].reshape(3, 3, order="F")
    force = -R[:, [0]] * (lg["f_e"] + U[-1:])                      # the sensor: contact force plus noise
    y = np.vstack([before["q"], before["dq"], force, U[:6]])
    p = iface.param.pack(**param_layout(task_of(n), sim.law).split(P))
    s_next, cmd, diag = (np.array(v) for v in fn.map(N)(s_ctl, y, p))
    C, D = command_layout(task_of(n), True).split(cmd), diagnostics_layout(task_of(n)).split(diag)
    assert lg["f_e"].max() > 1.0                                     # in contact
    for ours, logged in ((C["tau"], lg["tau"]), (C["X_c"], lg["X_c"]), (D["X_r"], lg["X_r"]), (D["X"], lg["X"]),
                         (D["p"], lg["p"]), (D["f_m"], lg["f_m"]), (D["b_n"], lg["b_n"]), (D["e_o"], lg["e_o"])):
        assert rel_err(ours, logged) < 1e-12
    after = state_layout(task_of(n), sim.law, delay).split(S)
    assert rel_err(s_next[iface.state["law"]], after["law"]) < 1e-12
    if delay:
        assert rel_err(s_next[iface.state["tau_wait"]], after["tau_wait"]) < 1e-12


def test_a_controller_exported_for_another_arm_is_refused(exported_ur5, tmp_path, capsys):
    """Refused before compiling: one line naming --controller and the arm, exit 2, nothing written."""
    out = tmp_path / "run"
    assert main(["simulate", "paper", "--controller", str(exported_ur5), "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("error: --controller:") and "'ur5'" in err and "'puma560'" in err and "\n" not in err
    assert not out.exists()
    assert main(["simulate", "ur5", "--set", "controller.delay_samples=1", "--controller", str(exported_ur5),
                 "--out", str(out)]) == 2
    assert "delay" in capsys.readouterr().err and not out.exists()


def test_deploy_doc_lists_the_6d_code_sizes_and_tables():
    """docs/deploy.md's 6-D tables are the field tables the C structs are
    written from, and its code sizes are the UR5's and the Panda's exports'."""
    import pathlib

    from tmtcontrol.control.laws import get_law

    doc = (pathlib.Path(__file__).parents[1] / "docs" / "deploy.md").read_text()
    assert generate._md_table(generate.command_fields(True, 6)) in doc
    assert generate._md_table(generate.measurement_fields(6)[:2]) in doc
    tmt = get_law("tmt")
    three = {f.name for f in generate.param_fields(tmt, 3)}
    added = tuple(f for f in generate.param_fields(tmt, 7) if f.name not in three)
    assert [f.name for f in added] == ["R_d", "kd_rot", "kp_rot", "q_post", "kp_post", "kd_post"]
    assert generate._md_table(added) in doc
    for arm, name in (("ur5", "UR5"), ("panda", "Panda")):
        for inner, label in ((False, "without inner loop"), (True, "with inner loop")):
            fn, _ = generate.controller_function(load_scenario(arm), inner)
            assert f"| {name} {label} | {fn.n_instructions()} | {fn.sz_w()} |" in doc, (arm, label)


SIGNALS = ("contact_force", "measured_force", "q", "dq", "tau", "command_task", "reference_task", "position",
           "damping", "desired_force")


def _sil_and_built_in(sc, folder, compile=True):
    """The run of ``sc`` with the C controller exported to ``folder`` in place of the built-in one
    (`simulate --controller`), and the built-in 6-D run."""
    from tmtcontrol.export.sil import CompiledController, simulate_with_controller
    from tmtcontrol.simulation.simulator import Simulator

    return (simulate_with_controller(sc, CompiledController(folder, scenario=sc)),
            Simulator(sc, compile=compile).run())


def _assert_same_signals(sil, ref, names=SIGNALS):
    for name in names:
        assert rel_err(getattr(sil, name), getattr(ref, name)) < RTOL, name


@pytest.mark.heavy
def test_short_6d_software_in_the_loop_run_equals_the_built_in_one(exported_ur5):
    """The short compiled 6-D check (2.5 s; the other heavy tests run the whole 16 s on both arms):
    160 periods of the UR5 with the exported C controller in place of the built-in one equal the
    built-in run; the exported state starts from the simulation's initial controller state and the
    log row holds every signal (kills mutation_tool's seed-3 sil.py survivors, whose faults only a
    6-D run reaches)."""
    sil, ref = _sil_and_built_in(apply_overrides(load_scenario("ur5"), SHORT), exported_ur5)
    assert sil.info["code"] == "exported C (SIL)" and sil.time.size == ref.time.size == 160
    _assert_same_signals(sil, ref)


# -- heavy: compiled C against the built-in 6-D loop ---------------------------------------------------

def _compilers():
    return [cc for cc in ("gcc", "clang") if shutil.which(cc)]


@pytest.mark.heavy
@pytest.mark.parametrize("arm", ["ur5", "panda"])
@pytest.mark.parametrize("inner", [False, True])
def test_6d_export_compiles_warning_free_with_gcc_and_clang(tmp_path, arm, inner):
    assert "gcc" in _compilers()
    export_controller(load_scenario(arm), tmp_path, inner)
    for cc in _compilers():
        r = subprocess.run(["make", "-B", f"CC={cc}", f"CFLAGS={' '.join(STRICT)} -O2"], cwd=tmp_path,
                           capture_output=True, text=True)
        assert r.returncode == 0 and "warning" not in r.stderr, (cc, r.stderr)
        r = subprocess.run(["./example_loop", "20"], cwd=tmp_path, capture_output=True, text=True)
        assert r.returncode == 0 and "20 periods" in r.stdout


@pytest.mark.heavy
@pytest.mark.parametrize("arm, sets", [("ur5", []), ("panda", []), ("ur5", ["controller.delay_samples=1"])])
def test_6d_software_in_the_loop_equals_the_built_in_run(tmp_path, arm, sets):
    """The whole 16 s scenario with the exported C controller in place of the
    built-in one (`simulate --controller`) equals the built-in 6-D run."""
    sc = apply_overrides(load_scenario(arm), sets)
    export_controller(sc, tmp_path, True)
    sil, ref = _sil_and_built_in(sc, tmp_path)
    assert sil.info["code"] == "exported C (SIL)" and sil.time.size == ref.time.size == 16000
    _assert_same_signals(sil, ref)
    # the orientation error is ~1e-6 rad: compared absolutely, far below the 1 mrad bound
    assert np.abs(sil.orientation_error - ref.orientation_error).max() < 1e-12


@pytest.mark.heavy
@pytest.mark.parametrize("arm", ["ur5", "panda"])
def test_6d_replay_of_the_logged_measurements_gives_the_logged_commands(tmp_path, arm):
    """`replay` over the built-in run's measurements gives its torques and
    commands; the joint command puts the tool at p_c in the commanded
    orientation (forward kinematics, independent of the Newton steps), from
    up to 0.1 m away at the start."""
    from tmtcontrol.export.sil import read_commands, write_measurements
    from tmtcontrol.simulation.geometry import rotation_vector, surface_frame, tool_orientation
    from tmtcontrol.simulation.simulator import Simulator, robot_of

    sc = load_scenario(arm)
    export_controller(sc, tmp_path, True)
    assert subprocess.run(["make", "replay"], cwd=tmp_path, capture_output=True).returncode == 0
    res = Simulator(sc).run()
    write_measurements(res, tmp_path / "measurements.csv")
    r = subprocess.run(["./replay", "measurements.csv", "commands.csv"], cwd=tmp_path, capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    cmd = read_commands(tmp_path / "commands.csv")
    n = res.q.shape[0]
    np.testing.assert_array_equal(cmd["t"], res.time)
    checks = {("x_c1", "x_c2", "x_c3"): res.command_task, ("x_r1", "x_r2", "x_r3"): res.reference_task,
              ("x1", "x2", "x3"): res.position_task, ("p_x", "p_y", "p_z"): res.position,
              ("f_m",): res.measured_force[None], ("b_n",): res.damping[None], ("f_d",): res.desired_force[None],
              tuple(f"tau{i}" for i in range(1, n + 1)): res.tau}
    for cols, logged in checks.items():
        assert rel_err(np.vstack([cmd[c] for c in cols]), logged) < RTOL, cols
    assert np.abs(np.vstack([cmd[f"e_o{i}"] for i in (1, 2, 3)]) - res.orientation_error).max() < 1e-12
    robot = robot_of(sc)
    R_d = tool_orientation(surface_frame(sc.environment), sc.trajectory.tool_spin_deg)
    q_c = np.vstack([cmd[f"q_c{i}"] for i in range(1, n + 1)])
    p_c = np.vstack([cmd[f"p_c_{a}"] for a in "xyz"])
    assert np.abs(p_c - res.position).max() > 0.05                     # the command starts far from the tool
    for k in range(0, res.time.size, 50):
        T = np.array(robot.functions.fk(q_c[:, k]))
        assert np.abs(T[:3, 3] - p_c[:, k]).max() < 1e-12
        assert np.linalg.norm(rotation_vector(R_d @ T[:3, :3].T)) < 1e-12


HARNESS_6D = r"""
#include <stdio.h>
#include <stdlib.h>
#include <math.h>
#include "tmt_controller.h"

static long calls;
void *__real_malloc(size_t n);
void *__real_calloc(size_t n, size_t m);
void *__real_realloc(void *p, size_t n);
void __real_free(void *p);
void *__wrap_malloc(size_t n) { ++calls; return __real_malloc(n); }
void *__wrap_calloc(size_t n, size_t m) { ++calls; return __real_calloc(n, m); }
void *__wrap_realloc(void *p, size_t n) { ++calls; return __real_realloc(p, n); }
void __wrap_free(void *p) { ++calls; __real_free(p); }

int main(void)
{
    static tmt_params params;
    static tmt_state state;
    static tmt_measurement meas;
    static tmt_command cmd;
    void *volatile probe;
    long k, in_steps, failures = 0;
    size_t i, n = sizeof meas.q / sizeof meas.q[0];
    tmt_default_params(&params);
    tmt_init(&params, &state);
    printf("start\n");                 /* stdio's own buffer is allocated here, not below */
    calls = 0;
    probe = malloc(16);                /* the counters count: one malloc and one free */
    free(probe);
    printf("probe %ld\n", calls);
    calls = 0;
    for (k = 0; k < 20000; ++k) {
        for (i = 0; i < n; ++i) {      /* near the start posture (away from singular poses) */
            meas.q[i] = q_start[i] + 0.01 * sin(1e-3 * (double)k + (double)i);
            meas.dq[i] = 1e-5 * cos(1e-3 * (double)k + (double)i);
        }
        meas.force[2] = -(double)(k % 3000) / 100.0;
        failures += tmt_step(&params, &state, &meas, &cmd) != 0;
    }
    in_steps = calls;
    printf("steps %ld failures %ld x_c %.6g\n", in_steps, failures, cmd.x_c[0]);
    return 0;
}
"""


@pytest.mark.heavy
@pytest.mark.parametrize("arm", ["ur5", "panda"])
def test_6d_tmt_step_calls_no_malloc_and_has_no_global_state(tmp_path, arm):
    """As the PUMA's (tests/test_export.py): 20,000 calls with the allocator
    wrapped count no call; the object has no writable data and calls only
    libm's pure functions."""
    from tmtcontrol.simulation.simulator import Simulator

    sc = load_scenario(arm)
    export_controller(sc, tmp_path, True)
    sim = Simulator(sc, compile=False)
    q0 = sim.inputs()[2][:sim.task.n]          # the start posture, where the skeleton's robot stands
    start = "static const double q_start[] = {" + ", ".join(repr(float(v)) for v in q0) + "};\n"
    (tmp_path / "harness.c").write_text(HARNESS_6D.replace("int main(void)", start + "int main(void)", 1))
    wrap = "-Wl,--wrap=malloc,--wrap=free,--wrap=realloc,--wrap=calloc"
    for cmd in (["gcc", *STRICT, "-O2", "-ffp-contract=off", "-c", "tmt_controller.c"],
                ["gcc", *STRICT, "-O0", "-fno-builtin", "harness.c", "tmt_controller.o", wrap, "-lm", "-o", "harness"]):
        r = subprocess.run(cmd, cwd=tmp_path, capture_output=True, text=True)
        assert r.returncode == 0, r.stderr
    out = subprocess.run(["./harness"], cwd=tmp_path, capture_output=True, text=True).stdout.split("\n")
    assert out[1] == "probe 2"          # the wrapped allocator is the one in use
    assert out[2].startswith("steps 0 failures 0 "), out[2]
    syms = subprocess.run(["nm", "tmt_controller.o"], cwd=tmp_path, capture_output=True, text=True).stdout
    kinds = {line.split()[-2] for line in syms.splitlines() if len(line.split()) >= 2}
    assert kinds and not kinds & set("DdBbCG"), syms
    undefined = {line.split()[-1] for line in syms.splitlines() if line.split()[-2:-1] == ["U"]}
    assert undefined <= {"sin", "cos", "sincos", "tan", "sqrt", "fmax", "fmin", "fabs", "atan2", "exp", "log", "pow",
                         "tanh", "asin", "acos", "atan", "floor", "ceil", "erf", "sinh", "cosh"}, undefined


@pytest.mark.heavy
def test_6d_two_interleaved_instances_equal_two_separate_ones(tmp_path):
    """Two UR5 controllers stepped alternately give, bit for bit, what each
    gives alone (no shared mutable state), on two different measurement
    sequences near the start posture."""
    from tmtcontrol.export.sil import CompiledController

    from tmtcontrol.simulation.simulator import Simulator

    export_controller(load_scenario("ur5"), tmp_path, True)
    ctl = CompiledController(tmp_path)
    params = ctl.default_params()
    q0 = Simulator(load_scenario("ur5"), compile=False).inputs()[2][:6]
    N, n = 300, ctl.n
    seqs = []
    for scale in (1.0, 1.7):
        rows = np.zeros((N, len(np.frombuffer(ctl.Measurement(), dtype=float))))
        k = np.arange(N)[:, None]
        rows[:, :n] = q0 + 0.01 * scale * np.sin(1e-2 * k + np.arange(n))
        rows[:, 2 * n + 2] = -scale * (k[:, 0] % 100) / 10.0
        seqs.append(rows)

    def run(states, order):
        outs = [[] for _ in seqs]
        meas, cmd = ctl.Measurement(), ctl.Command()
        y = np.frombuffer(meas, dtype=float)
        for i, k in order:
            y[:] = seqs[i][k]
            assert ctl.step(params, states[i], meas, cmd) == 0
            outs[i].append(np.frombuffer(cmd, dtype=float).copy())
        return [np.array(o) for o in outs]

    alone = [run([ctl.new_state(params)] * 2, [(i, k) for k in range(N)])[i] for i in (0, 1)]
    assert not np.array_equal(alone[0], alone[1])
    inter = run([ctl.new_state(params), ctl.new_state(params)], [(i, k) for k in range(N) for i in (0, 1)])
    np.testing.assert_array_equal(inter[0], alone[0])
    np.testing.assert_array_equal(inter[1], alone[1])


def test_make_clean_removes_only_what_make_built(tmp_path):
    """tmtcontrol never deletes a file it did not write: the exported
    Makefile's clean target leaves the user's measurements.csv and
    commands.csv (replay's output, the user's data) in place."""
    export_controller(paper_scenario(), tmp_path, False)
    built = ("tmt_controller.o", "libtmt_controller.a", "replay", "example_loop")
    for name in (*built, "measurements.csv", "commands.csv"):
        (tmp_path / name).write_text("x\n")
    r = subprocess.run(["make", "clean"], cwd=tmp_path, capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    assert not any((tmp_path / name).exists() for name in built)
    assert (tmp_path / "measurements.csv").read_text() == (tmp_path / "commands.csv").read_text() == "x\n"


@pytest.mark.heavy
@pytest.mark.parametrize("sets", [
    ["controller.law=rls", "controller.damping_schedule.kind='zeta'", "sensor.noise_std=0.05",
     "trajectory.approach_gap=0.002"],
    ["controller.law=integral", "robot.model_mass_scale=1.1", "sensor.filter_cutoff=50.0",
     "controller.x_e_error=0.001", "controller.delay_samples=2"],
])
def test_6d_software_in_the_loop_equals_the_built_in_run_for_other_structures(tmp_path, sets):
    """Other laws, the guarded approach, the damping schedule, sensor noise and
    filter, a wrong controller model and a delay queue on the UR5 (2 s each,
    2,000 periods): the same expressions in C as in the built-in 6-D step."""
    sc = apply_overrides(load_scenario("ur5"), ["trajectory.cycles=0.5", *sets])
    export_controller(sc, tmp_path, True)
    sil, ref = _sil_and_built_in(sc, tmp_path, compile=False)
    assert ref.contact_force.max() > 1.0                  # the runs are in contact
    _assert_same_signals(sil, ref, ("contact_force", "measured_force", "q", "dq", "tau", "command_task", "damping",
                                    "desired_force"))
    assert np.abs(sil.orientation_error - ref.orientation_error).max() < 1e-12


def test_the_arm_an_export_was_made_for_is_checked_by_its_content(exported_ur5, tmp_path):
    """The same URDF read from another path (a scenario file elsewhere) is the
    same arm and is accepted; an edited URDF (another link mass) is another
    arm; a changed controller-model setting is named as that setting. All
    decided from export.json, before compiling."""
    from importlib import resources

    from tmtcontrol.export.generate import ExportError
    from tmtcontrol.export.sil import check_export_matches

    meta = json.loads((exported_ur5 / generate.METADATA).read_text())
    text = resources.files("tmtcontrol.model").joinpath("data", "ur5.urdf").read_text()
    (tmp_path / "my_arm.urdf").write_text(text)
    same = apply_overrides(load_scenario("ur5"), [f"robot.model='{tmp_path / 'my_arm.urdf'}'", "robot.tip='tool0'"])
    check_export_matches(meta, exported_ur5, same)                       # accepted
    with pytest.raises(ExportError, match=r"^--controller: .* model_mass_scale = 1.0, the scenario has 1.1;"):
        check_export_matches(meta, exported_ur5, apply_overrides(same, ["robot.model_mass_scale=1.1"]))
    i = text.index('<mass value="') + len('<mass value="')
    (tmp_path / "edited.urdf").write_text(text[:i] + "1" + text[i:])        # a mass 4.0 -> 14.0 kg
    edited = apply_overrides(same, [f"robot.model='{tmp_path / 'edited.urdf'}'"])
    with pytest.raises(ExportError, match="or another version of it"):
        check_export_matches(meta, exported_ur5, edited)
    with pytest.raises(ExportError, match=r"was exported for robot.model = 'ur5'.*'puma560'"):
        check_export_matches(meta, exported_ur5, paper_scenario())


@pytest.mark.heavy
def test_exported_c_runs_against_mujoco_as_the_built_in_controller_does(exported_ur5):
    """Issue 41: the exported C against MuJoCo's dynamics of the same URDF
    (`simulate --controller DIR --plant mujoco`): the same plant, the
    controller compiled as C instead of run in CasADi's VM, so the same run
    to rounding (1e-9, the SIL tolerance). Both, called from Python with a
    built-in-only key set (substeps = 7, which MuJoCo's RK4 ignores), return
    the scenario MuJoCo ran, the key at its default (the twenty-first session:
    only the command line reset it, so a Python caller's limit read it)."""
    from tmtcontrol.export.sil import CompiledController, simulate_with_controller
    from tmtcontrol.simulation.mujoco_plant import simulate_on_mujoco

    sc = apply_overrides(load_scenario("ur5"), SHORT)
    sc7 = apply_overrides(sc, ["simulation.substeps=7"])
    c = simulate_with_controller(sc7, CompiledController(exported_ur5, scenario=sc, isolated=True), plant="mujoco")
    ref = simulate_on_mujoco(sc7)
    assert c.scenario.simulation == ref.scenario.simulation == sc.simulation != sc7.simulation
    assert c.info["plant"] == ref.info["plant"] == "mujoco (spring contact)" and c.info["code"] == "exported C (SIL)"
    _assert_same_signals(c, ref, ("contact_force", "q", "dq", "tau", "command_task", "position"))


def test_a_cylinders_axis_is_column_3_of_the_exported_R():
    """The parameter table says which column of R is a cylinder's axis (review 11: it said only that
    column 1 is the normal; turning R about the normal moved the depth by 24 mm in the C). On the
    built-in pipe (axis along base y, the normal straight down into it) the exported default R has
    the scenario's axis as column 3 and its normal as column 1."""
    from tmtcontrol import load_scenario
    from tmtcontrol.export.generate import interface, scenario_values

    sc = load_scenario("ur5-pipe")
    p0, _ = scenario_values(sc, False)
    start = 0
    for f in interface(sc, False).param_fields:
        if f.name == "R":
            assert "axis is column 3" in f.doc
            R = np.reshape(p0[start:start + 9], (3, 3), order="F")
        start += f.size
    axis = np.asarray(sc.environment.axis) / np.linalg.norm(sc.environment.axis)
    assert abs(abs(R[:, 2] @ axis) - 1.0) < 1e-15 and np.allclose(R[:, 0], sc.environment.normal, atol=1e-15)


def test_the_header_describes_the_force_and_orientation_of_a_curved_part():
    """Review 24: on the pipe the header said the normal force is -R[:,0].force (35 % off at 0.87 rad
    round the pipe, where the controller rightly uses the local normal), q_c "in the commanded
    orientation R_d" and dq_c "zero angular velocity" (both turn with the surface). On a plane the
    text stays as it was; on a curved part it names the local normal and the turning command."""
    from tmtcontrol import load_scenario
    from tmtcontrol.export.generate import interface

    def docs(name):
        i = interface(load_scenario(name), True)
        return {f.name: f.doc for f in (*i.measurement_fields, *i.command_fields, *i.param_fields)}

    plane, pipe = docs("ur5"), docs("ur5-pipe")
    assert plane["force"].endswith("pushing on the surface is -R[:,0].force")
    assert "R_d" in plane["q_c"] and "zero angular velocity" in plane["dq_c"]
    assert "-R[:,0].force" not in pipe["force"] and "inward unit normal at the tool point" in pipe["force"]
    assert "turned with the surface's normal" in pipe["q_c"] and "zero angular velocity" not in pipe["dq_c"]
    assert "turns with the surface's normal" in pipe["R_d"] and "turns" not in plane["R_d"]
    assert "valid +1 or -1" in pipe["side"] and "valid > 0" in pipe["radius"]
