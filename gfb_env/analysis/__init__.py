"""Stability and bifurcation analysis of the GFB rotor model (paper Sect. 3).

Layer: uses :mod:`gfb_env.params`, :mod:`gfb_env.model`, :mod:`gfb_env.integrator` (and the generic
:mod:`gfb_env.sweeps`); nothing here imports the environments, agents or experiments.

* :mod:`~gfb_env.analysis.continuation` -- equilibria continued in ``Lambda``.
* :mod:`~gfb_env.analysis.stability` -- eigenvalues, growth rate, whirl ratio, ``Lambda_c``.
* :mod:`~gfb_env.analysis.periodic` -- limit cycles by shooting, Floquet multipliers, fold of cycles,
  coast-down cross-check.
* :mod:`~gfb_env.analysis.spectrum` -- FFT, dominant whirl frequency.
* :mod:`~gfb_env.analysis.maps` -- stability map (Fig. 4) and hysteresis map, their files and loaders.
* :mod:`~gfb_env.analysis.campbell` -- rotor-mode frequencies, damping ratio, log decrement vs speed.
* :mod:`~gfb_env.analysis.runup` -- run-up / coast-down at a given acceleration, waterfall, envelopes.

The results own their derived quantities and their figures (``result.plot()``, drawn by
:mod:`gfb_env.plotting`): :class:`CampbellDiagram`, :class:`RunUpAnalysis`,
:class:`~gfb_env.analysis.response.ResponseCurve`, :class:`~gfb_env.analysis.schedule.RunUpSchedule`.
"""

from gfb_env.analysis.campbell import CampbellDiagram, campbell_diagram
from gfb_env.analysis.continuation import EquilibriumBranch, continue_equilibria
from gfb_env.analysis.maps import (
    HysteresisMap,
    StabilityMap,
    compute_hysteresis_map,
    compute_stability_map,
    load_hysteresis_map,
    load_stability_map,
    optimal_foil_damping,
    plot_stability_map,
    write_hysteresis_map,
    write_stability_map,
)
from gfb_env.analysis.periodic import (
    CoastDownResult,
    CycleBranch,
    FoldResult,
    PeriodicOrbit,
    SettledWhirl,
    ShootingError,
    coast_down_fold,
    continue_periodic_orbits,
    find_periodic_orbit,
    fold_bearing_number,
    hopf_cycles,
    periodic_orbit_from_simulation,
    settle_whirl,
)
from gfb_env.analysis.runup import RunUpAnalysis, RunUpResult, Waterfall, analyse_run_up, run_up, waterfall
from gfb_env.analysis.spectrum import (
    AmplitudeSpectrum,
    DominantFrequency,
    amplitude_spectrum,
    dominant_frequency,
)
from gfb_env.analysis.stability import (
    CriticalPoint,
    NoCriticalPointError,
    NoStableEquilibriumError,
    Stability,
    StabilityAnalysisError,
    critical_bearing_number,
    jacobian_eigenvalues,
    linear_stability,
)

__all__ = [
    "AmplitudeSpectrum",
    "CampbellDiagram",
    "RunUpAnalysis",
    "RunUpResult",
    "Waterfall",
    "analyse_run_up",
    "campbell_diagram",
    "run_up",
    "waterfall",
    "CoastDownResult",
    "CriticalPoint",
    "CycleBranch",
    "DominantFrequency",
    "EquilibriumBranch",
    "FoldResult",
    "HysteresisMap",
    "NoCriticalPointError",
    "NoStableEquilibriumError",
    "PeriodicOrbit",
    "SettledWhirl",
    "ShootingError",
    "Stability",
    "StabilityAnalysisError",
    "StabilityMap",
    "amplitude_spectrum",
    "coast_down_fold",
    "compute_hysteresis_map",
    "compute_stability_map",
    "continue_equilibria",
    "continue_periodic_orbits",
    "critical_bearing_number",
    "dominant_frequency",
    "find_periodic_orbit",
    "fold_bearing_number",
    "hopf_cycles",
    "jacobian_eigenvalues",
    "linear_stability",
    "load_hysteresis_map",
    "load_stability_map",
    "optimal_foil_damping",
    "periodic_orbit_from_simulation",
    "plot_stability_map",
    "settle_whirl",
    "write_hysteresis_map",
    "write_stability_map",
]
