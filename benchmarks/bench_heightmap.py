"""What a measured height map costs beside the plane: a loop step and a limit analysis (the sweep's estimate).

Run: python benchmarks/bench_heightmap.py [--repeat 3] [--record [FILE]]

The paper's PUMA on its plane and on a 61 x 61 height map of a 0.5 m dome
sampled every 5 mm (the spline through it is part of every step: CasADi's
B-spline ``interpolant`` and its derivatives, evaluated by generic de Boor
code, where a plane's depth is one dot product). Prints the time of a
compiled step (best of --repeat warm runs of 16 s at 1 kHz) and of the
deciding limit (``stability.limit.deciding_limit``, its result cache off, best
of --repeat after a first run that compiles or loads the steps), each on the
plane and on the map, the limits beside them (N/m), and the map's *extra*
cost in units of the plane's: ``(map - plane) / plane``. Those two figures
are what :attr:`tmtcontrol.surface.HeightMap.step_cost` and
:attr:`~tmtcontrol.surface.HeightMap.analysis_cost` state, which
``Sweep.estimate_seconds`` adds to an arm's own cost (review 43: a 4-case
sweep over height maps was estimated at 11 s and took 324 s).
``--record`` writes the figures as JSON (default
``benchmarks/heightmap_results.json``) with the machine's CPU, core count
and host speed; tests/test_inputs_wave3.py fails when the constants and the
recorded figures differ by more than 10 % (rounded as stated), and when
docs/surfaces.md's sentence (:func:`quoted`) is not the recorded run's.
Nothing here asserts a time.
"""
import argparse
import json
import os
import pathlib
import platform
import sys
import time

import numpy as np

from tmtcontrol import Simulator, apply_overrides, paper_scenario

HERE = pathlib.Path(__file__).resolve().parent
RECORD = HERE / "heightmap_results.json"
RADIUS, POINTS, SPACING = 0.5, 61, 0.005


def dome_scenario(folder: pathlib.Path):
    """The paper's scenario on a height map of a dome of RADIUS (m), POINTS x POINTS every SPACING (m)."""
    u = (np.arange(POINTS) - (POINTS - 1) / 2) * SPACING
    U, V = np.meshgrid(u, u, indexing="ij")
    path = folder / "dome.csv"
    np.savetxt(path, -(RADIUS - np.sqrt(RADIUS ** 2 - U * U - V * V)), delimiter=",", fmt="%.12g")
    return apply_overrides(paper_scenario(), ['environment.shape="heightmap"', f'environment.heightmap="{path}"',
                                              f"environment.grid_spacing={SPACING!r}"])


def _step_seconds(sc, repeat: int) -> float:
    sim = Simulator(sc, compile=True)
    res = sim.run()
    best = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        sim.run()
        best.append(time.perf_counter() - t0)
    return min(best) / res.time.size


def _limit_seconds(sc, repeat: int) -> tuple[float, float]:
    from tmtcontrol.stability.limit import deciding_limit

    limit = deciding_limit(sc)                       # compiles (or loads) the steps
    best = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        deciding_limit(sc)
        best.append(time.perf_counter() - t0)
    return min(best), float(limit.limit)


def measure(repeat: int, folder: pathlib.Path) -> dict:
    plane, dome = paper_scenario(), dome_scenario(folder)
    step = {name: _step_seconds(sc, repeat) for name, sc in (("plane", plane), ("heightmap", dome))}
    limit = {name: _limit_seconds(sc, repeat) for name, sc in (("plane", plane), ("heightmap", dome))}
    return {"step_s": step, "limit_s": {k: v[0] for k, v in limit.items()},
            "limit_N_per_m": {k: v[1] for k, v in limit.items()},
            "step_cost": (step["heightmap"] - step["plane"]) / step["plane"],
            "analysis_cost": (limit["heightmap"][0] - limit["plane"][0]) / limit["plane"][0]}


def quoted(fig: dict) -> str:
    """The sentence docs/surfaces.md quotes from a recorded run (tests/test_inputs_wave3.py checks it)."""
    s, lim = fig["step_s"], fig["limit_s"]
    return (f"a PUMA step on a 61 x 61 map took {s['heightmap'] * 1e6:.1f} µs against {s['plane'] * 1e6:.2f} µs on "
            f"the plane ({fig['step_cost']:.1f}x extra) and its limit analysis {lim['heightmap']:.1f} s against "
            f"{lim['plane']:.1f} s ({fig['analysis_cost']:.1f}x extra; host speed loop "
            f"{fig['machine']['host_speed_loop_s']:.2f} s, {fig['machine']['date']})")


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--repeat", type=int, default=3)
    p.add_argument("--record", nargs="?", const=str(RECORD), default=None, metavar="FILE")
    args = p.parse_args(argv)
    os.environ["TMTCONTROL_RESULT_CACHE"] = "0"          # the limits computed, not read back
    sys.path.insert(0, str(HERE))
    from bench_all import host_speed

    import tempfile

    with tempfile.TemporaryDirectory() as tmp:
        fig = measure(args.repeat, pathlib.Path(tmp))
    s, lim = fig["step_s"], fig["limit_s"]
    print(f"step:  plane {s['plane'] * 1e6:.2f} us, height map {s['heightmap'] * 1e6:.2f} us: "
          f"extra {fig['step_cost']:.1f}x the plane's")
    print(f"limit: plane {lim['plane']:.2f} s ({fig['limit_N_per_m']['plane']:,.0f} N/m), height map "
          f"{lim['heightmap']:.2f} s ({fig['limit_N_per_m']['heightmap']:,.0f} N/m): "
          f"extra {fig['analysis_cost']:.1f}x the plane's")
    if args.record:
        fig["machine"] = {"cpu": platform.processor() or platform.machine(), "cores": os.cpu_count(),
                          "python": platform.python_version(), "host_speed_loop_s": host_speed(),
                          "date": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime()), "repeat": args.repeat}
        pathlib.Path(args.record).write_text(json.dumps(fig, indent=1) + "\n")
        print(f"wrote {args.record}; docs/surfaces.md quotes: {quoted(fig)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
