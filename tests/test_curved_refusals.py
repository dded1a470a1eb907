"""Curved parts the tool cannot follow, and paths that leave a part's domain (issue 40's bad input).

* A spherical tool tip (``robot.tool_radius``, the sphere of MuJoCo's own
  contact) touches a concave part at one point only where the part's
  smallest concave radius of curvature exceeds the tip's: a bowl or a bore
  no wider than the tip, or a height map whose spline is hollow tighter than
  the tip somewhere on the path, is refused in one line naming the key
  (exit 2, nothing written); the curvature of the spline is checked against
  closed forms (a spherical cap, a trough) written here in NumPy.
* A path's reach along each task axis is its own (``path_extent``, against
  brute-force sampling of ``path_reference``), not ``trajectory.radius``: a
  raster turned by ``direction_deg`` that leaves a height map's grid or a
  sphere's chart is refused; its neighbours that fit are accepted.
"""

from __future__ import annotations

import numpy as np
import pytest

from tmtcontrol.cli import main
from tmtcontrol.simulation.scenario import ScenarioError, apply_overrides, load_scenario, paper_scenario


def _refused(tmp_path, capsys, toml: str, needle: str, sets=()):
    """``simulate`` of the scenario ``toml`` (with ``--set`` each of ``sets``):
    exit 2, one stderr line holding ``needle``, nothing on stdout, no output
    folder. Returns the line."""
    (tmp_path / "s.toml").write_text(toml)
    out = tmp_path / "out"
    rc = main(["simulate", str(tmp_path / "s.toml"), "--out", str(out), "--no-plots",
               *[a for s in sets for a in ("--set", s)]])
    captured = capsys.readouterr()
    lines = captured.err.strip().splitlines()
    assert rc == 2 and captured.out == "" and len(lines) == 1 and needle in lines[0], captured.err
    assert not out.exists()
    return lines[0]


def _valid(toml: str, sets=()) -> bool:
    """Whether :func:`_validates` accepts the scenario."""
    try:
        _validates(toml, sets)
        return True
    except ScenarioError:
        return False


def _validates(toml: str, sets=()):
    """The scenario ``toml`` with each ``key=value`` of ``sets`` set before
    it is validated (as ``--set`` on a file would), validated."""
    import tomllib

    from tmtcontrol.simulation.scenario import scenario_from_dict

    d = tomllib.loads(toml)
    for item in sets:
        key, raw = item.split("=", 1)
        *sections, name = key.split(".")
        node = d
        for part in sections:
            node = node.setdefault(part, {})
        node[name] = tomllib.loads(f"v = {raw}")["v"]
    return scenario_from_dict(d)


def _grid(f, n=41, spacing=0.01):
    u = (np.arange(n) - (n - 1) / 2) * spacing
    U, V = np.meshgrid(u, u, indexing="ij")
    return f(U, V)


def _heightmap_toml(tmp_path, heights, spacing, extra=""):
    np.savetxt(tmp_path / "part.csv", heights, delimiter=",", fmt="%.12g")
    return (f'[environment]\nshape = "heightmap"\nheightmap = "{tmp_path / "part.csv"}"\n'
            f"grid_spacing = {spacing!r}\n"
            f"[trajectory]\ncycles = 0.25\n{extra}")


# -- A: the tool's tip on a concave part -------------------------------------------------------------

def test_the_default_tool_radius_is_the_mujoco_tool_sphere():
    from tmtcontrol.simulation.mujoco_plant import TOOL_RADIUS
    from tmtcontrol.simulation.scenario import RobotSettings

    assert RobotSettings().tool_radius == TOOL_RADIUS == 1e-3
    assert paper_scenario().robot.tool_radius == TOOL_RADIUS


def test_the_mujoco_contact_touches_with_the_scenarios_tool_sphere():
    pytest.importorskip("mujoco")
    from tmtcontrol.simulation.mujoco_plant import mujoco_plant_for
    from tmtcontrol.simulation.simulator import Simulator

    sc = apply_overrides(load_scenario("ur5"), ['simulation.mujoco_contact="contact"', "robot.tool_radius=0.004"])
    plant, _ = mujoco_plant_for(Simulator(sc, compile=False), sc)
    g = plant.model.geom("tmt_tool").id
    assert plant.model.geom_size[g][0] == pytest.approx(0.004, abs=1e-15)
    assert plant.model.geom_pos[g] == pytest.approx([0.0, 0.0, -0.004], abs=1e-15)   # its lowest point the tool point


def test_the_tool_radius_is_a_setting_where_it_matters(tmp_path):
    """The report's settings table shows robot.tool_radius where it changes
    something: a part worked from inside, a height map, MuJoCo's own contact;
    not on the paper's plane or a convex part."""
    from tmtcontrol.simulation.scenario import applicable_settings

    def shown(sc):
        return "robot.tool_radius" in {r.key for r in applicable_settings(sc)}

    assert shown(load_scenario("panda-bowl")) and not shown(load_scenario("ur5-pipe"))
    assert not shown(paper_scenario())
    assert shown(apply_overrides(load_scenario("ur5"), ['simulation.mujoco_contact="contact"']))
    assert shown(_validates(_heightmap_toml(tmp_path, np.zeros((41, 41)), 0.01)))


@pytest.mark.parametrize("shape, radius, tool", [("sphere", 0.002, 0.002), ("sphere", 0.002, 0.0025),
                                                 ("cylinder", 0.003, 0.003), ("cylinder", 0.003, 0.01)])
def test_a_bowl_or_bore_no_wider_than_the_tool_tip_is_refused(tmp_path, capsys, shape, radius, tool):
    toml = (f'[environment]\nshape = "{shape}"\nradius = {radius!r}\nside = "inside"\n'
            f"[trajectory]\nradius = 0.001\ncycles = 0.25\n")
    line = _refused(tmp_path, capsys, toml, f"environment.radius: a {shape} worked from inside must have a radius "
                    f"larger than the tool's tip (robot.tool_radius = {tool:g} m), got {radius:g} m",
                    [f"robot.tool_radius={tool!r}"])
    assert line.startswith("error: environment.radius:")


@pytest.mark.parametrize("shape", ["sphere", "cylinder"])
def test_a_bowl_or_bore_just_wider_than_the_tool_tip_or_a_convex_part_is_accepted(tmp_path, shape):
    toml = f'[environment]\nshape = "{shape}"\nradius = 0.002\nside = "inside"\n[trajectory]\nradius = 0.001\n'
    assert _validates(toml, ["robot.tool_radius=0.00199"]).robot.tool_radius == 0.00199
    # the outside of the same part is convex: a tip of any size touches it at one point
    convex = _validates(toml.replace('"inside"', '"outside"'), ["robot.tool_radius=0.01"])
    assert convex.environment.side == "outside"


def test_the_reviewers_2_mm_bowl_runs_with_the_default_1_mm_tip(tmp_path, capsys):
    """The 2 mm bowl of the review is wider than the default 1 mm tip: it runs
    (and converges); with a 2 mm tip it is refused (above)."""
    (tmp_path / "s.toml").write_text('[environment]\nshape = "sphere"\nradius = 0.002\nside = "inside"\n'
                                     "[trajectory]\nradius = 0.001\ncycles = 0.25\n")
    rc = main(["simulate", str(tmp_path / "s.toml"), "--out", str(tmp_path / "out"), "--no-plots"])
    assert rc == 0, capsys.readouterr().err
    assert (tmp_path / "out" / "summary.json").exists()


def _spherical_cap(R, spacing, n=41):
    return _grid(lambda U, V: R - np.sqrt(R * R - U * U - V * V), n, spacing)


def test_the_height_maps_principal_curvatures_are_the_closed_forms():
    """The spline's curvatures against closed forms: a spherical cap of
    radius R seen from inside (a bowl) has both principal curvatures 1/R
    (slopes up to 0.4 here: the metric terms matter), upside down (a dome)
    -1/R and no concave radius; a trough ``u^2 / (2 rho)`` has 1/rho across
    it (at u = 0) and 0 along it; a sphere's or cylinder's inside its radius,
    its outside none."""
    from tmtcontrol.surface import Cylinder, HeightMap, Sphere, tilt_frame

    R0, c0 = tilt_frame(45.0), np.array([0.5, -0.15, 0.55])
    s = np.random.default_rng(40).uniform(-0.015, 0.015, (2, 50))
    bowl = HeightMap(R0, c0, _spherical_cap(0.05, 0.001), 0.001)
    k1, k2 = bowl.curvatures(s)
    assert np.abs(k1 * 0.05 - 1).max() < 2e-4 and np.abs(k2 * 0.05 - 1).max() < 2e-4
    assert np.abs(bowl.concave_radius(s) - 0.05).max() < 1e-5
    dome = HeightMap(R0, c0, -_spherical_cap(0.05, 0.001), 0.001)
    assert np.abs(dome.curvatures(s)[1] * 0.05 + 1).max() < 2e-4 and np.all(np.isinf(dome.concave_radius(s)))
    trough = HeightMap(R0, c0, _grid(lambda U, V: U * U / (2 * 0.2)), 0.01)
    axis = np.vstack([np.zeros(5), np.linspace(-0.1, 0.1, 5)])
    k1, k2 = trough.curvatures(axis)
    assert np.abs(k1 * 0.2 - 1).max() < 1e-6 and np.abs(k2).max() < 1e-6
    # beyond the grid the part continues flat: no curvature
    assert np.all(np.isinf(trough.concave_radius(np.array([[0.5], [0.0]]))))
    for cls in (Sphere, Cylinder):
        assert np.all(cls(R0, c0, 0.3, "inside").concave_radius(s) == 0.3)
        assert np.all(np.isinf(cls(R0, c0, 0.3, "outside").concave_radius(s)))


DIP = 0.01 * np.array([np.cos(np.radians(37.0)), np.sin(np.radians(37.0))])
"""Where the hollow is: on the 1 cm circle at 37 deg (between the samples of a coarse path)."""


def _dip(U, V):
    """A Gaussian hollow 5 mm deep, sigma 2 mm, at :data:`DIP`: its bottom's
    curvature is 5e-3 / 2e-3^2 = 1250 1/m (the spline's, about 1330 1/m: a
    concave radius of 0.75 mm), tighter than the 1 mm tip."""
    return -0.005 * np.exp(-((U - DIP[0]) ** 2 + (V - DIP[1]) ** 2) / (2 * 0.002 ** 2))


def test_a_height_map_hollow_tighter_than_the_tool_tip_on_the_path_is_refused(tmp_path, capsys):
    toml = _heightmap_toml(tmp_path, _grid(_dip, 41, 0.001), 0.001, "radius = 0.01\n")
    line = _refused(tmp_path, capsys, toml, "environment.heightmap: must curve concave less tightly than the tool's "
                    "tip (robot.tool_radius = 0.001 m) along the path, got a concave radius of curvature of")
    at = [float(x) for x in line.split("at (u, v) = (")[1].split(")")[0].split(",")]
    assert np.hypot(*(np.array(at) - DIP)) < 2e-4                # the hollow's bottom (0.2 mm: a quarter spacing)
    least = float(line.split("radius of curvature of ")[1].split(" m")[0])
    assert 1 / 1400 < least < 1 / 1250                          # the spline's bottom, near the closed form's
    # the neighbours: a tip finer than the hollow; the same tip on a circle that misses the hollow
    assert _validates(toml, ["robot.tool_radius=0.0007"]).robot.tool_radius == 0.0007
    assert _validates(toml, ["trajectory.radius=0.004"]).trajectory.radius == 0.004


def test_the_tool_tip_bridges_a_groove_the_path_runs_along(tmp_path, capsys):
    """The test is the smallest concave radius over every direction, not the
    curvature along the path: a line running along a trough of radius 0.2 m
    is straight, yet a 0.21 m tip rests on the trough's sides."""
    toml = _heightmap_toml(tmp_path, _grid(lambda U, V: U * U / (2 * 0.2)), 0.01,
                           'path = "line"\ndirection_deg = 90.0\n')
    line = _refused(tmp_path, capsys, toml, "environment.heightmap: must curve concave less tightly",
                    ["robot.tool_radius=0.21"])
    assert "radius of curvature of 0.2 m at (u, v) = (0, " in line
    assert _validates(toml, ["robot.tool_radius=0.19"]).robot.tool_radius == 0.19


def test_a_sweep_couples_the_tool_radius_with_the_parts_radius(tmp_path):
    """Axes in different sections that the cross-section check relates are
    validated in every combination: each value alone fits the 1 cm bowl or
    the 1 mm tip, the 2 mm bowl with the 3 mm tip does not."""
    from tmtcontrol.sweep import sweep_from_dict
    from tmtcontrol.sweep.spec import SweepError

    (tmp_path / "bowl.toml").write_text('[environment]\nshape = "sphere"\nradius = 0.01\nside = "inside"\n'
                                        "[trajectory]\nradius = 0.001\n")
    with pytest.raises(SweepError, match=r"environment\.radius = 0\.002, robot\.tool_radius = 0\.003.*"
                                         r"environment\.radius: a sphere worked from inside"):
        sweep_from_dict({"scenario": "bowl.toml", "grid": {"environment.radius": [0.01, 0.002],
                                                           "robot.tool_radius": [0.001, 0.003]}}, folder=tmp_path)


def test_a_sweep_draws_no_turned_raster_off_the_part_between_two_valid_ends(tmp_path):
    """Regression (found by a review): a sphere of radius 0.09 m takes the
    0.1 m raster unturned (0 deg) and turned 90 deg (1.11 rad from the
    centre), not turned 45 deg (0.133 m, 1.48 rad: beyond the chart's 1.2).
    A random direction over [0, 90] used to be validated at its ends only,
    so the sweep was accepted and drew invalid cases; every case is
    validated now, the first invalid one named. A range that stays valid
    (0 to 5 deg: at most 0.107 m, 1.19 rad) is accepted, and on a plane (no
    domain) the ends suffice."""
    from tmtcontrol.sweep import sweep_from_dict
    from tmtcontrol.sweep.spec import SweepError

    (tmp_path / "dome.toml").write_text('[environment]\nshape = "sphere"\nradius = 0.09\n'
                                        '[trajectory]\npath = "raster"\ncycles = 0.25\n')
    for end in (0.0, 90.0):
        apply_overrides(load_scenario(tmp_path / "dome.toml"), [f"trajectory.direction_deg={end}"])
    random = {"trajectory.direction_deg": {"uniform": [0.0, 90.0]}, "samples": 40, "seed": 3}
    with pytest.raises(SweepError, match=r"^case \d+ \(trajectory\.direction_deg = [\d.]+\): trajectory\.radius: "
                                         r"the path leaves the sphere's domain"):
        sweep_from_dict({"scenario": "dome.toml", "random": random}, folder=tmp_path)
    ok = sweep_from_dict({"scenario": "dome.toml", "random": {**random, "trajectory.direction_deg":
                                                               {"uniform": [0.0, 5.0]}}}, folder=tmp_path)
    assert ok.cases.total == 40
    (tmp_path / "plane.toml").write_text('[trajectory]\npath = "raster"\n')
    assert sweep_from_dict({"scenario": "plane.toml", "random": random}, folder=tmp_path).cases.total == 40


def test_a_part_made_curved_by_a_grid_over_the_whole_environment_table_is_validated_case_by_case(tmp_path):
    """Regression (found by a review): the curved-part test read only the base's
    shape and a grid over ``environment.shape``; a grid over the whole
    ``environment`` table (a plane base, the dome as a grid value) left the random
    direction checked at its ends, 0 and 90 deg, both valid on the 0.09 m dome,
    and the sweep drew rasters off the part. The plane alone as the table's
    value is accepted (no domain: the ends suffice)."""
    from tmtcontrol.sweep import sweep_from_dict
    from tmtcontrol.sweep.spec import SweepError

    (tmp_path / "raster.toml").write_text('[trajectory]\npath = "raster"\ncycles = 0.25\n')
    random = {"trajectory.direction_deg": {"uniform": [0.0, 90.0]}, "samples": 40, "seed": 3}
    dome = {"shape": "sphere", "radius": 0.09}
    with pytest.raises(SweepError, match=r"^case \d+ \(environment = .*trajectory\.direction_deg = [\d.]+\): "
                                         r"trajectory\.radius: the path leaves the sphere's domain"):
        sweep_from_dict({"scenario": "raster.toml", "grid": {"environment": [{"shape": "plane"}, dome]},
                         "random": random}, folder=tmp_path)
    ok = sweep_from_dict({"scenario": "raster.toml", "grid": {"environment": [{"shape": "plane"}]},
                          "random": random}, folder=tmp_path)
    assert ok.cases.total == 40


def test_every_shape_declares_which_of_its_checks_are_not_intervals(tmp_path):
    """The sweep asks the scenario's NOT_INTERVALS by shape: a shape added
    without its entry would fail there (KeyError), and a misspelt key, or one
    the shape does not use, would never match a random axis: each shape's keys
    are settings of a scenario of that shape (raster path: lanes and
    direction apply)."""
    from typing import get_args

    from tmtcontrol.simulation.scenario import NOT_INTERVALS, EnvironmentSettings, applicable_settings

    shapes = get_args(EnvironmentSettings.model_fields["shape"].annotation)
    assert set(NOT_INTERVALS) == set(shapes) and NOT_INTERVALS["plane"] == ()
    raster = '[trajectory]\npath = "raster"\ncycles = 0.25\nradius = 0.01\n'
    tomls = {"plane": raster, "sphere": '[environment]\nshape = "sphere"\nradius = 0.09\n' + raster,
             "cylinder": '[environment]\nshape = "cylinder"\nradius = 0.09\n' + raster,
             "heightmap": _heightmap_toml(tmp_path, np.zeros((41, 41)), 0.01, 'path = "raster"\nradius = 0.01\n')}
    for shape, toml in tomls.items():
        keys = {row.key for row in applicable_settings(_validates(toml))}
        assert set(NOT_INTERVALS[shape]) <= keys, (shape, set(NOT_INTERVALS[shape]) - keys)


@pytest.mark.parametrize("shape", ["sphere", "cylinder"])
def test_on_a_sphere_or_cylinder_the_sizes_are_intervals_so_their_ends_suffice(tmp_path, shape):
    """The claim behind NOT_INTERVALS, checked by brute force: on a sphere or
    cylinder the path's size, the part's radius and the tool's tip are
    checked at their ends only, so every value between two valid ends must be
    valid. Each range ends at the largest valid path (a raster turned 30 deg,
    found by bisection: 1e-9 m) or the smallest valid part radius, where an
    error would show first; 200 seeded cases each, every one through the
    schema."""
    from tmtcontrol.sweep import sweep_from_dict

    toml = (f'[environment]\nshape = "{shape}"\nradius = 0.09\nside = "inside"\n'
            '[trajectory]\npath = "raster"\ncycles = 0.25\ndirection_deg = 30.0\nradius = 0.01\n')

    lo, hi = 0.01, 1.0                 # the largest valid path size
    while hi - lo > 1e-9:
        mid = (lo + hi) / 2
        lo, hi = (mid, hi) if _valid(toml, [f"trajectory.radius={mid!r}"]) else (lo, mid)
    assert 0.05 < lo < 0.3 and not _valid(toml, [f"trajectory.radius={hi!r}"])
    toml = toml.replace("radius = 0.01\n", f"radius = {lo!r}\n")        # the path at its largest
    (tmp_path / "part.toml").write_text(toml)
    for key, rng in (("trajectory.radius", [lo / 2, lo]), ("environment.radius", [0.09, 0.5]),
                     ("robot.tool_radius", [1e-4, 0.0899])):
        sweep = sweep_from_dict({"scenario": "part.toml", "random": {key: {"uniform": rng}, "samples": 200,
                                                                      "seed": 5}}, folder=tmp_path)
        for index in range(sweep.cases.total):
            values = sweep.cases.case(index).values
            assert rng[0] <= values[key] <= rng[1]
            _validates(toml, [f"{key}={values[key]!r}"])


def test_a_height_maps_hollow_between_two_valid_path_sizes_is_found_case_by_case(tmp_path):
    """On a height map the path's size is not an interval: circles of 4 mm and
    16 mm miss the hollow of ``_dip`` (on the 1 cm circle), those near 1 cm run
    through it, tighter than the tool's tip. A random radius over [4, 16] mm
    is valid at both ends, so only a case-by-case check refuses it, naming a
    case whose radius is near the hollow."""
    from tmtcontrol.sweep import sweep_from_dict
    from tmtcontrol.sweep.spec import SweepError

    toml = _heightmap_toml(tmp_path, _grid(_dip, 41, 0.001), 0.001, "radius = 0.004\n")
    (tmp_path / "part.toml").write_text(toml)
    assert not _valid(toml, ["trajectory.radius=0.01"])
    for end in (0.004, 0.016):
        assert _validates(toml, [f"trajectory.radius={end}"]).trajectory.radius == end
    with pytest.raises(SweepError, match=r"^case \d+ \(trajectory\.radius = ([\d.]+)\): environment\.heightmap: "
                                         r"must curve concave less tightly") as err:
        sweep_from_dict({"scenario": "part.toml", "random": {"trajectory.radius": {"uniform": [0.004, 0.016]},
                                                             "samples": 60, "seed": 1}}, folder=tmp_path)
    radius = float(str(err.value).split("trajectory.radius = ")[1].split(")")[0])
    assert 0.007 < radius < 0.013                       # a circle through the hollow (sigma 2 mm)


# -- B: how far the path really reaches ---------------------------------------------------------------

def _traj(**kw):
    from tmtcontrol.simulation.scenario import scenario_from_dict

    return scenario_from_dict({"trajectory": kw}).trajectory


@pytest.mark.parametrize("kw", [{"path": "circle"}, {"path": "line", "direction_deg": 30.0},
                                {"path": "raster"}, {"path": "raster", "direction_deg": 45.0, "radius": 0.17},
                                {"path": "raster", "lanes": 7, "direction_deg": 45.0},
                                {"path": "raster", "lanes": 100, "direction_deg": -30.0, "period": 20.0}])
def test_path_extent_is_the_paths_own_reach(kw):
    """Against ``path_reference`` sampled at 2,000,001 points over a period
    (its sampling error below 2e-9 m here): never below, at most 1e-9 m
    above; a raster within ``radius (|cos| + |sin|)``, which an odd number
    of lanes at 45 deg reaches (``radius sqrt 2``, both harmonics at an end
    together)."""
    from tmtcontrol.simulation.trajectory import path_extent, path_reference

    tr = _traj(**kw)
    ext = np.array(path_extent(tr))
    brute = np.abs(path_reference(np.linspace(0.0, tr.period, 2_000_001), tr).pos).max(axis=1)
    assert np.all(ext >= brute - 1e-15) and np.all(ext - brute < 1e-9), (ext, brute)
    th = np.radians(tr.direction_deg)
    if tr.path == "raster":
        assert ext.max() <= tr.radius * (abs(np.cos(th)) + abs(np.sin(th))) * (1 + 1e-12)
        if tr.lanes % 2 and tr.direction_deg == 45.0:
            assert ext.max() == pytest.approx(tr.radius * np.sqrt(2), rel=1e-12)


def test_a_raster_turned_beyond_the_height_map_is_refused(tmp_path, capsys):
    """41 x 41 at 1 cm: the grid reaches 0.2 m, 0.18 m with the margin. A
    raster of radius 0.17 m turned 45 deg reaches 0.2258 m: refused (it rode
    the flat extension); unturned, or smaller, it fits."""
    toml = _heightmap_toml(tmp_path, np.zeros((41, 41)), 0.01,
                           'path = "raster"\nradius = 0.17\ndirection_deg = 45.0\n')
    line = _refused(tmp_path, capsys, toml, "trajectory.radius: the path leaves the height map: it reaches 0.225836 m "
                    "from its centre along task axis 1 (a raster turned by trajectory.direction_deg reaches beyond "
                    "its radius), the grid (41 x 41 at 0.01 m) reaches 0.2 m")
    assert "two spacings kept as margin" in line
    assert _validates(toml, ["trajectory.direction_deg=0.0"]).trajectory.radius == 0.17
    assert _validates(toml, ["trajectory.radius=0.12"]).trajectory.direction_deg == 45.0


def test_a_height_map_longer_than_wide_is_checked_per_axis(tmp_path, capsys):
    """Rows along task axis 1, columns along axis 2: 61 x 21 at 1 cm reaches
    0.3 m and 0.1 m. A line of 0.2 m along axis 1 fits; turned onto axis 2
    it leaves the grid."""
    toml = _heightmap_toml(tmp_path, np.zeros((61, 21)), 0.01, 'path = "line"\nradius = 0.2\n')
    assert _validates(toml).trajectory.radius == 0.2
    _refused(tmp_path, capsys, toml, "trajectory.radius: the path leaves the height map: it reaches 0.2 m from its "
             "centre along task axis 2", ["trajectory.direction_deg=90.0"])


def test_a_raster_turned_off_the_spheres_chart_is_refused(tmp_path, capsys):
    """r = 0.0835 m: a 0.1 m raster spans 1.198 rad unturned (at most 1.2),
    turned 45 deg 0.13284 m, 1.59 rad: beyond the chart's pi/2 latitude."""
    toml = '[environment]\nshape = "sphere"\nradius = 0.0835\n[trajectory]\npath = "raster"\ncycles = 0.25\n'
    _refused(tmp_path, capsys, toml, "trajectory.radius: the path leaves the sphere's domain: it reaches 0.132845 m "
             "from its centre along task axis 1 (a raster turned by trajectory.direction_deg reaches beyond its "
             "radius), 1.59 rad on radius 0.0835 m (at most 1.2 rad from its centre)",
             ["trajectory.direction_deg=45.0"])
    assert _validates(toml).environment.radius == 0.0835


def test_a_line_is_checked_by_its_own_reach_not_its_radius():
    """A line's reach along each axis is radius |cos|, |sin|: one of 0.11 m
    along task axis 1 on a sphere of radius 0.09 m spans 1.22 rad and is
    refused; turned 60 deg it spans 0.61 rad along axis 1 and 1.06 rad along
    axis 2 and is accepted."""
    sets = ['environment.shape="sphere"', "environment.radius=0.09", 'trajectory.path="line"',
            "trajectory.radius=0.11"]
    with pytest.raises(ScenarioError, match=r"^trajectory\.radius: the path leaves the sphere's domain: it reaches "
                                            r"0\.11 m from its centre along task axis 1, 1\.22 rad"):
        apply_overrides(paper_scenario(), sets)
    assert apply_overrides(paper_scenario(), [*sets, "trajectory.direction_deg=60.0"]).trajectory.radius == 0.11


def test_the_drawn_surface_patch_covers_a_turned_rasters_reach():
    """The figures' surface patch (SimulationTraces.surface_mesh) spans 1.4x
    the path's true reach along each task axis (path_extent): a smooth
    raster turned 45 deg reaches 1.33 radius, not the radius the circle's
    patch was sized by (its patch unchanged: 2 x 1.4 x 0.1 m along base y)."""
    import numpy as np

    from tmtcontrol.simulation.scenario import apply_overrides, paper_scenario
    from tmtcontrol.simulation.simulator import Simulator
    from tmtcontrol.simulation.trajectory import path_extent

    circle = apply_overrides(paper_scenario(), ["trajectory.cycles=0.05"])
    assert np.ptp(Simulator(circle).run().traces.surface_mesh[1]) == pytest.approx(0.28, rel=1e-12)
    sc = apply_overrides(circle, ['trajectory.path="raster"', "trajectory.direction_deg=45"])
    reach = max(path_extent(sc.trajectory))
    assert reach > 1.3 * sc.trajectory.radius
    mesh = Simulator(sc).run().traces.surface_mesh
    assert np.ptp(mesh[1]) == pytest.approx(2 * 1.4 * reach, rel=1e-12)      # base y is task axis 2 here


def test_a_sideways_part_offset_that_moves_the_path_off_the_map_is_refused(tmp_path, capsys):
    """Review 65: the grid's margin was checked on the commanded path, not on the true part under it: a flat
    0.3 m map with controller.part_offset 0.1 m sideways rode 667 of 1,000 samples past the grid's edge,
    on its unmeasured tangent extension, and read converged. The path's reach on the true part is checked
    (naming the offset); 1 mm sideways stays accepted."""
    toml = _heightmap_toml(tmp_path, np.zeros((31, 31)), 0.01)
    line = _refused(tmp_path, capsys, toml, "trajectory.radius: the path leaves the height map: it reaches 0.2 m "
                    "from its centre along task axis 1 (the true part under the commanded path: "
                    "controller.part_offset moves it)", ["controller.part_offset=[0.0, 0.1, 0.0]"])
    assert line.startswith("error: trajectory.radius:")
    assert _valid(toml, ["controller.part_offset=[0.0, 0.001, 0.0]"]) and _valid(toml)


def test_a_groove_the_offset_path_crosses_is_refused_at_its_tightest_point(tmp_path, capsys):
    """Review 65: a V groove at v = 0.12 m (its spline's concave radius 0.0578 m) beside a 0.1 m circle
    passed a 0.06 m tip when controller.part_offset moved the path across it; and sampled eight per grid
    spacing, its tightest point read 0.0604 m. The check follows the true part under the commanded path and refines the least
    sample between its neighbours; without the offset the path misses the groove and is accepted."""
    heights = _grid(lambda U, V: 0.05 * np.abs(V - 0.12), n=41)
    toml = _heightmap_toml(tmp_path, heights, 0.01)
    offset = "controller.part_offset=[0.0283, 0.0, 0.0283]"          # 0.04 m along task axis 2, in the base frame
    line = _refused(tmp_path, capsys, toml, "environment.heightmap: must curve concave less tightly than the "
                    "tool's tip (robot.tool_radius = 0.06 m) along the path, got a concave radius of curvature of "
                    "0.0577 m", ["robot.tool_radius=0.06", offset])
    assert "controller.part_offset moves it" in line
    assert _valid(toml, ["robot.tool_radius=0.06"]) and _valid(toml, ["robot.tool_radius=0.05", offset])


def test_a_map_whose_heights_read_like_millimetres_is_noted(tmp_path, capsys):
    """Review 65: a plate warped 0.1 mm with its heights written in millimetres (0 to 0.15 over a 0.3 m map)
    ran as a 15 cm deep bowl with no word; a sphere's radius has such a note. A map rising more than its grid
    spacing between neighbouring points (steeper than 45 degrees) is noted, naming the key and the
    millimetre reading; the same map in metres is not."""
    from tmtcontrol.simulation.scenario.environment import steep_map_note

    bowl_mm = _grid(lambda U, V: 0.15 * (U ** 2 + V ** 2) / 0.15 ** 2 * 100, n=31)       # 0 to 15 "m" over 0.3 m
    np.savetxt(tmp_path / "mm.csv", bowl_mm, delimiter=",")
    np.savetxt(tmp_path / "m.csv", bowl_mm / 1000, delimiter=",")
    note = steep_map_note(tmp_path / "mm.csv", 0.01)
    assert note.startswith("environment.heightmap: heights spanning 30 m rise up to ") and "millimetres" in note
    assert steep_map_note(tmp_path / "m.csv", 0.01) is None
    toml = _heightmap_toml(tmp_path, bowl_mm / 1000, 0.01)
    assert _validates(toml).environment.unit_notes() == []
    np.savetxt(tmp_path / "part.csv", bowl_mm, delimiter=",")
    assert [n[:36] for n in _validates(toml).environment.unit_notes()] == ["environment.heightmap: heights spann"]


@pytest.mark.parametrize("delimiter", [" ", ";", "\t"])
def test_a_map_written_with_another_delimiter_is_refused_naming_commas(tmp_path, capsys, delimiter):
    """Review 65: numpy.savetxt's default (spaces) gave "row 2 of 'part.csv' is not numbers": the first row
    was taken as a header. The line says the rows must be comma-separated and how to write them."""
    toml = _heightmap_toml(tmp_path, np.zeros((31, 31)), 0.01)
    np.savetxt(tmp_path / "part.csv", np.zeros((31, 31)), delimiter=delimiter)
    _refused(tmp_path, capsys, toml, "is not comma-separated numbers (spaces, tabs or semicolons between them: "
             "write commas, e.g. numpy.savetxt(FILE, heights, delimiter=','))")


def test_the_summary_names_the_part_by_its_content_not_only_its_file(tmp_path):
    """Review 65: summary.json recorded a height map by its file's name only: a file rewritten between two
    runs gave two identical scenario blocks for two parts. The summary names the surface by its key, which
    holds the heights' digest (as the compiled loop's structure key does)."""
    import json

    from tmtcontrol.simulation.geometry import surface_of
    from tmtcontrol.simulation.output import save_simulation
    from tmtcontrol.simulation.simulator import Simulator

    toml = _heightmap_toml(tmp_path, np.zeros((31, 31)), 0.01)
    flat = surface_of(_validates(toml)).key
    np.savetxt(tmp_path / "part.csv", _grid(lambda U, V: 0.1 * U, n=31), delimiter=",")
    tilted = surface_of(_validates(toml)).key
    assert flat != tilted and flat.startswith("heightmap-") and tilted.startswith("heightmap-")
    res = Simulator(apply_overrides(paper_scenario(), ["trajectory.cycles=0.02"])).run()
    (tmp_path / "run").mkdir()
    save_simulation(res, tmp_path / "run", plots=False)
    assert json.loads((tmp_path / "run" / "summary.json").read_text())["surface"] == "plane"


def test_the_tool_check_under_an_offset_follows_the_parts_placement_not_a_cached_one(tmp_path):
    """Review 67: the tool tip's check on a map was cached by the map's heights and the path, but under a
    sideways controller.part_offset the true path depends on where the part sits too: a tilt changed by --set
    reused the first tilt's answer. The same map (V grooves at v = +-0.13 m) and offset (0.05 m along base
    z): at tilt 45 the offset moves the path 0.035 m along task axis 2, across a groove; at tilt 0 it is
    along the normal and the path misses both; in either order, twice."""
    heights = _grid(lambda U, V: 0.05 * np.minimum(np.abs(V - 0.13), np.abs(V + 0.13)), n=41)
    toml = _heightmap_toml(tmp_path, heights, 0.01)
    tilted = ["robot.tool_radius=0.06", "controller.part_offset=[0.0, 0.0, 0.05]"]
    flat = [*tilted, "environment.tilt_deg=0.0"]
    for _ in range(2):
        assert _valid(toml, flat)
        assert not _valid(toml, tilted)
    assert _valid(toml, ["robot.tool_radius=0.06"])


def test_a_refused_map_that_reads_like_millimetres_says_so_in_its_line(tmp_path, capsys):
    """Review 67: the millimetre note was held until the checks passed, so a map in millimetres refused by
    the tool tip's check (its hollows 1000x too tight) said nothing of units. The refusal carries the note."""
    waves = _grid(lambda U, V: 0.5 * np.sin(2 * np.pi * U / 0.05), n=41)                 # 0.5 mm written as 0.5
    line = _refused(tmp_path, capsys, _heightmap_toml(tmp_path, waves, 0.01),
                    "environment.heightmap: must curve concave less tightly than the tool's tip")
    assert "if the heights are in millimetres, divide them by 1000" in line
