"""tmtcontrol: force-tracking position-based impedance control with the
trajectory modification technique (TMT) for robots on surfaces of unknown
stiffness.

Data path (one way; nothing imports a later stage)::

    model/        robot dynamics, eq. (1)
      -> control/     impedance filter and inner loop (eqs. 2-6); laws/ (eqs. 11-18 and baselines)
      -> simulation/  scenario, environment, closed loop, compiled rollout, metrics, outputs
      -> stability/   continuous (eqs. 19-25), sampled data, design
      -> checks/      derivation checks on the running code
      -> report/      the stability report (HTML, PDF)
      -> cli.py       argument parsing only
"""
__version__ = "0.1.0"

from .model import PUMA560_LINKS, LinkParameters, Puma560
from .simulation.scenario import (Scenario, ScenarioError, apply_overrides, dump_scenario, load_scenario,
                       paper_scenario)
from .simulation.simulator import SimulationError, SimulationResult, Simulator
from .simulation.metrics import SegmentMetrics, segment_metrics
from .simulation.compare import Comparison, LawRun, compare_laws

__all__ = [
    "__version__", "Puma560", "PUMA560_LINKS", "LinkParameters", "Scenario", "ScenarioError",
    "paper_scenario", "load_scenario", "dump_scenario", "apply_overrides", "Simulator",
    "SimulationResult", "SimulationError", "SegmentMetrics", "segment_metrics", "compare_laws", "Comparison",
    "LawRun",
]
