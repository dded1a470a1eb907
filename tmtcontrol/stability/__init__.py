"""Stability analysis: continuous time (eqs. 19-25, :mod:`.continuous`), the
sampled-data loop (:mod:`.sampled`; any law's: :mod:`.lawloop`), one-call analysis of a scenario
(:mod:`.analysis`), the whole simulated loop linearised at a frozen path point (:mod:`.wholeloop`) and along
the moving path (:mod:`.periodic`, the monodromy), the large-signal limit from the scenario's own start
(:mod:`.first_contact`), the limit that decides a scenario's verdict, as every command quotes it
(:mod:`.limit`) and the robust impedance design (:mod:`.design`)."""

from .analysis import (analysis_kwargs, analyze, analyze_scenario, format_analysis, paper_effective_mass,
                       scenario_parameters, scenario_stiffness_limit)
from .limit import ScenarioLimit, deciding_limit, with_stiffness_limit
from .lawloop import (LawLoop, continuous_limit, law_loop, law_stiffness_band, law_stiffness_limit,
                      stiffness_sequence)
from .continuous import (AnalysisError, ContinuousAnalysis, RangeAnalysis, analyze_continuous, analyze_range,
                         bibo_stable, critical_damping, damping_for_range, damping_ratio, internally_stable,
                         minimal_realization, stiffness_sweep, tmt_error_ss, tmt_error_tf, x_e_error_force)
from .sampled import (SampledModel, StiffnessBand, effective_mass, max_stable_stiffness, sampled_closed_loop,
                      spectral_radii, spectral_radius, stability_region, stable_band, stiffness_band,
                      stiffness_margin, switch_response)
from .wholeloop import WholeLoop, WholeLoopModel, equilibrium_damping, whole_loop, whole_loop_limit
from .periodic import (GROWTH_BOUND, PeriodicLimit, PeriodicLoop, PeriodicModel, periodic_limit, periodic_loop,
                       periodic_search)
from .first_contact import FirstContactRun, first_contact_limit, first_contact_run, simulated_limit

__all__ = [
    "AnalysisError", "ContinuousAnalysis", "minimal_realization", "bibo_stable",
    "internally_stable", "tmt_error_tf", "tmt_error_ss", "analyze_continuous",
    "critical_damping", "damping_ratio", "damping_for_range", "RangeAnalysis", "analyze_range",
    "stiffness_sweep", "x_e_error_force", "SampledModel", "sampled_closed_loop",
    "spectral_radius", "spectral_radii", "max_stable_stiffness", "stability_region", "stiffness_margin",
    "switch_response", "StiffnessBand", "stable_band", "stiffness_band", "law_stiffness_band",
    "effective_mass", "scenario_parameters", "paper_effective_mass", "analyze", "analysis_kwargs",
    "format_analysis", "scenario_stiffness_limit", "LawLoop", "law_loop", "law_stiffness_limit",
    "continuous_limit", "stiffness_sequence", "analyze_scenario", "WholeLoop", "WholeLoopModel", "whole_loop",
    "whole_loop_limit", "equilibrium_damping", "PeriodicLoop", "PeriodicModel", "periodic_limit", "periodic_loop",
    "PeriodicLimit", "periodic_search", "GROWTH_BOUND",
    "FirstContactRun", "first_contact_limit", "first_contact_run", "simulated_limit",
    "ScenarioLimit", "deciding_limit", "with_stiffness_limit",
]
