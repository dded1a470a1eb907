"""CPU time and size of the simulation's four PNG figures at zlib levels 6
(Pillow's default) and 1 (what ``tmtcontrol.drawing.save_figures`` writes).

Run: MPLBACKEND=Agg python benchmarks/bench_png.py
Prints, per level, the median and least CPU time (``time.process_time``, so a
loaded machine's other processes count less than in wall time) of making and
saving the four figures of the paper run, over six alternated repeats, and
the files' total size. Quoted in docs/speed.md.
"""
import os
import statistics
import tempfile
import time

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from tmtcontrol import Simulator, paper_scenario  # noqa: E402
from tmtcontrol.plotstyle import plain_log_labels, styled  # noqa: E402
from tmtcontrol.simulation import figures  # noqa: E402
from tmtcontrol.simulation.output import simulation_figures  # noqa: E402

traces = Simulator(paper_scenario()).run().traces
folder = tempfile.mkdtemp(prefix="tmt-png-")
cpu, size = {6: [], 1: []}, {}
for _ in range(6):
    for level in cpu:
        total, nbytes = 0.0, 0
        for name, make in simulation_figures(traces):
            path = os.path.join(folder, f"{name}_{level}.png")
            with styled():
                t0 = time.process_time()
                fig = plain_log_labels(getattr(figures, make)(traces))
                fig.savefig(path, dpi=120, pil_kwargs={"compress_level": level})
                total += time.process_time() - t0
            plt.close(fig)
            nbytes += os.path.getsize(path)
        cpu[level].append(total)
        size[level] = nbytes
for level, times in cpu.items():
    print(f"zlib level {level}: CPU median {statistics.median(times):.3f} s, least {min(times):.3f} s; "
          f"{size[level] / 1e3:.0f} kB in four files")
