"""tmtcontrol: force-tracking position-based impedance control with the
trajectory modification technique (TMT) for robots on surfaces of unknown
stiffness.

Data path (one way; nothing imports a later stage)::

    model/        robot dynamics, eq. (1)
      -> surface/     contact surfaces (plane, ...): distance, normal, frame, contact law
      -> control/     impedance filter and inner loop (eqs. 2-6); laws/ (eqs. 11-18 and baselines)
      -> simulation/  scenario, environment, closed loop, compiled rollout, metrics, outputs
      -> stability/   continuous (eqs. 19-25), sampled data, design
      -> checks/      derivation checks on the running code
      -> report/      the stability report (HTML, PDF)
      -> cli.py       argument parsing only
"""
__version__ = "0.1.0"

import importlib
from typing import TYPE_CHECKING

_EXPORTS = {
    "tmtcontrol.model": ("Puma560", "PUMA560_LINKS", "LinkParameters"),
    "tmtcontrol.simulation.scenario": ("Scenario", "ScenarioError", "paper_scenario", "load_scenario",
                                       "dump_scenario", "apply_overrides"),
    "tmtcontrol.simulation.simulator": ("Simulator", "SimulationResult", "SimulationError", "simulator_for"),
    "tmtcontrol.model.robot": ("load_robot", "Robot", "URDFError", "Task"),
    "tmtcontrol.surface": ("Surface", "Plane"),
    "tmtcontrol.simulation.metrics": ("SegmentMetrics", "segment_metrics"),
    "tmtcontrol.simulation.compare": ("compare_laws", "Comparison", "LawRun"),
    "tmtcontrol.stability.limit": ("deciding_limit", "ScenarioLimit"),
    "tmtcontrol.export.generate": ("export_controller", "ExportError"),
    "tmtcontrol.export.sil": ("CompiledController", "simulate_with_controller"),
}
"""The public API by defining module. Imported on first access (PEP 562), so
``import tmtcontrol`` and the command line's start cost no CasADi, NumPy or
pydantic until a command needs them."""

_WHERE = {name: module for module, names in _EXPORTS.items() for name in names}

__all__ = [
    "__version__", "Puma560", "PUMA560_LINKS", "LinkParameters", "Scenario", "ScenarioError",
    "paper_scenario", "load_scenario", "dump_scenario", "apply_overrides", "Simulator",
    "SimulationResult", "SimulationError", "SegmentMetrics", "segment_metrics", "compare_laws", "Comparison",
    "LawRun", "load_robot", "Robot", "URDFError", "export_controller", "ExportError", "CompiledController",
    "simulate_with_controller", "simulator_for", "Task", "Surface", "Plane",
    "deciding_limit", "ScenarioLimit",
]


def __getattr__(name: str):
    module = _WHERE.get(name)
    if module is None:
        raise AttributeError(f"module 'tmtcontrol' has no attribute {name!r}")
    value = getattr(importlib.import_module(module), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted({*globals(), *__all__})


if TYPE_CHECKING:  # pragma: no cover - for type checkers and IDEs
    from .export.generate import ExportError, export_controller
    from .export.sil import CompiledController, simulate_with_controller
    from .model import PUMA560_LINKS, LinkParameters, Puma560
    from .model.robot import Robot, Task, URDFError, load_robot
    from .simulation.compare import Comparison, LawRun, compare_laws
    from .simulation.metrics import SegmentMetrics, segment_metrics
    from .simulation.scenario import (Scenario, ScenarioError, apply_overrides, dump_scenario, load_scenario,
                                      paper_scenario)
    from .simulation.simulator import SimulationError, SimulationResult, Simulator, simulator_for
    from .stability.limit import ScenarioLimit, deciding_limit
    from .surface import Plane, Surface
