"""Certificates and designs: functions of a system and of gains, below the estimators.

Each function returns a small frozen result carrying the numbers and a verdict, ``holds``
(the statement it proves or checks). One module per family, named for what it certifies or
designs:

* :mod:`.observability` and :mod:`.stability` (Lyapunov/LMI, JSR bounds, mean square);
* :mod:`.steady_state_kalman`: the steady-state Kalman gain of a mode;
* :mod:`.mode_mismatch`: the bias of the mode-based Kalman filter under mode mismatch
  (Zhang & Natarajan, paper 001);
* :mod:`.switch_time_bounds`: error bounds from a switching-time error (Shankar et al., 000);
* :mod:`.min_distance_design`: the minimum-distance detector's constants and windows
  (Lee, paper 002);
* :mod:`.subsystem_error_dynamics`: the sub-states and sampled error system of subsystem
  observers, its mean-square tests and second moments (Wang, paper 003);
* :mod:`.subsystem_observers`: their mean-square design, critical interval and gains (Wang, 003);
* :mod:`.error_moments`: their error's moments per component and given the modes (Wang, 003);
* :mod:`.impulsive_lmis`: the impulsive observer's LMIs (Etienne et al., 004), with
  :mod:`.impulsive_certificates` (what they prove) and :mod:`.impulsive_rates` (the decay rates);
* :mod:`.scalar_search`: the largest feasible scalar of a monotone problem (bracket, bisect).

Each name is imported from its module at its first use (PEP 562 ``__getattr__``): importing
one design does not load cvxpy or scipy.optimize for the others.
"""

from .._lazy import deferred

# module -> the names it defines that the package exports
_EXPORTS = {
    "error_moments": ("ComponentOptimum", "ScalarErrorMoments", "WindowSums",
                      "component_steady_state", "moment_fixed_point", "moment_matrix",
                      "optimal_component_gain", "scalar_error_moments", "state_error_moments",
                      "window_average_sd", "window_sums_given_modes"),
    "impulsive_certificates": ("ClosedLoopCertificate", "ImpulsiveObserverCertificate",
                               "ImpulsiveObserverSearch"),
    "impulsive_lmis": ("closed_loop_matrices", "impulsive_closed_loop_analysis",
                       "impulsive_observer_search", "impulsive_observer_synthesis"),
    "impulsive_rates": ("impulsive_closed_loop_decay_rate", "impulsive_observer_decay_rate",
                        "largest_tolerable_delay"),
    "min_distance_design": ("LeeAssumptions", "LeeCondition", "LeeConstants", "LeeWindows",
                            "decay_observer_gains", "default_observer_gains", "lee_assumptions",
                            "lee_constants", "lee_windows", "observability_gramians"),
    "mode_mismatch": ("AutonomousBiasStability", "MismatchDynamics", "ToleranceCheck",
                      "TransformedSystem", "UnstableComponents", "autonomous_stability",
                      "bias_recursion", "bibo_gain", "filter_stability_hypotheses",
                      "max_mismatch_probability", "mean_state", "mismatch_bias_bound",
                      "mismatch_dynamics", "riccati_gains", "stable_mismatch_region",
                      "steady_state_gains", "tolerance_region", "transformed_system",
                      "unstable_components"),
    "observability": ("CombinedObservability", "DwellTimeObservability", "JointObservability",
                      "KalmanDecomposition", "ModeObservability", "UniformObservability",
                      "combined_observability", "dwell_time_observability", "is_observable",
                      "joint_gramian", "joint_observability", "kalman_decomposition",
                      "mode_decompositions", "mode_observability", "observability_matrix",
                      "omega_min", "uniform_observability", "window_gramian"),
    "scalar_search": ("largest_feasible",),
    "stability": ("JSRBounds", "LyapunovCertificate", "MeanSquareStability", "cqlf",
                  "decrease_margin", "jsr_bounds", "ms_stable_iid", "spectral_radius"),
    "steady_state_kalman": ("steady_state_gain",),
    "subsystem_error_dynamics": ("ErrorDynamics", "MSConvergence", "SteadyState",
                                 "SubsystemStructure", "error_dynamics", "ms_convergence",
                                 "second_moments", "steady_state", "substate_gains",
                                 "subsystem_structure"),
    "subsystem_observers": ("CriticalInterval", "GainBounds", "OptimalGains", "critical_interval",
                            "decoupled_gain_bounds", "kalman_bucy_gains", "optimal_gains",
                            "place_gains", "pole_placement_gain"),
    "switch_time_bounds": ("EstimationErrorBounds", "SwitchMatrixBounds",
                           "estimation_error_bounds", "switch_matrix_bounds"),
}
__getattr__, __dir__ = deferred(__name__, globals(), _EXPORTS)
__all__ = sorted((n for names in _EXPORTS.values() for n in names), key=str.lower)
