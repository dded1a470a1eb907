"""tmtcontrol: force-tracking position-based impedance control with the
trajectory modification technique (TMT) for robots on surfaces of unknown
stiffness.

Data path (one way)::

    robot (eq. 1) -> reference (eqs. 11-18) / impedance (eqs. 2-6)
      -> closedloop (one control period) -> simulate (CasADi integrator, compiled rollout)
      -> metrics / plots -> output (CSV, JSON, figures) -> cli
"""
__version__ = "0.1.0"

from .robot import PUMA560_LINKS, LinkParameters, Puma560
from .scenario import (Scenario, ScenarioError, apply_overrides, dump_scenario, load_scenario,
                       paper_scenario)
from .simulate import SimulationError, SimulationResult, Simulator
from .metrics import SegmentMetrics, segment_metrics

__all__ = [
    "__version__", "Puma560", "PUMA560_LINKS", "LinkParameters", "Scenario", "ScenarioError",
    "paper_scenario", "load_scenario", "dump_scenario", "apply_overrides", "Simulator",
    "SimulationResult", "SimulationError", "SegmentMetrics", "segment_metrics",
]
