"""The stability / hysteresis map of the tasks' *nominal* bearing, as the scripted agents may know it.

The scripted agents are engineering rules: they may use what an engineer would have on paper for the
nominal bearing, i.e. the documented task constants of the environment (``env.constants``: the curve
``Lambda_c(D_W)``, its maximum ``lambda_best`` at ``d_opt``) and the fold of cycles ``Lambda_fold(D_W)``
(the lower edge of the hysteresis band) -- never the drawn parameters of a randomised episode nor the
simulator state.

The fold curve is read from the hysteresis map shipped with the package
(:func:`gfb_env.analysis.load_hysteresis_map`, ``gfb_env/data/hysteresis_map.csv``) when that map contains
the nominal foil stiffness (within 5 %); otherwise it is unknown (empty) and the agents fall back to
``Lambda_c`` minus a margin. (At the time of writing the map covers ``K_W = 1`` and the Table-1 foil, not
the tasks' ``K_W = 0.50``; a quasi-static coast-down from the stored whirl at ``d_opt`` found the whirl
dying within a step of ``Lambda_c``, i.e. a narrow band, but critical slowing-down near ``Lambda_c`` makes
that estimate unreliable, so it is not used.)
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

__all__ = ["NominalMap"]


@dataclass
class NominalMap:
    """``Lambda_c(D_W)`` and (if known) ``Lambda_fold(D_W)`` of the nominal bearing, interpolated in log D_W.

    Attributes:
        damping, critical: the tabulated curve ``Lambda_c(D_W)``.
        lambda_best, d_opt: its maximum and the damping that attains it.
        fold_damping, fold: the tabulated fold curve (empty if unknown).
        speed_per_lambda_rpm: rpm of the nominal bearing per unit bearing number.
    """

    damping: np.ndarray
    critical: np.ndarray
    lambda_best: float
    d_opt: float
    speed_per_lambda_rpm: float
    fold_damping: np.ndarray = field(default_factory=lambda: np.zeros(0))
    fold: np.ndarray = field(default_factory=lambda: np.zeros(0))

    @classmethod
    def from_env(
        cls, env, hysteresis_map_path: str | Path | None = None, use_fold: bool = True
    ) -> NominalMap:
        """From a gfb_env task (its documented ``constants`` of the nominal bearing) and, if it covers the
        nominal foil stiffness, the hysteresis map (``hysteresis_map_path``; default: the one shipped with
        gfb_env; a missing file raises FileNotFoundError)."""
        u = getattr(env, "unwrapped", env)
        c = u.constants
        # the tabulated curve plus its refined maximum (lambda_best at d_opt), sorted in D_W
        ds = np.r_[np.asarray(c["curve_d"], dtype=float), float(c["d_opt"])]
        lcs = np.r_[np.asarray(c["curve_lambda_c"], dtype=float), float(c["lambda_best"])]
        order = np.argsort(ds)
        m = cls(
            damping=ds[order],
            critical=lcs[order],
            lambda_best=float(c["lambda_best"]),
            d_opt=float(c["d_opt"]),
            speed_per_lambda_rpm=float(u.nominal_bearing.speed_rpm_at(1.0)),
        )
        if use_fold:
            m.fold_damping, m.fold = _nominal_fold(
                float(u.constants.get("foil_stiffness", 0.0) or u.nominal_bearing.foil_stiffness),
                hysteresis_map_path,
            )
        return m

    def critical_at(self, d: float) -> float:
        """``Lambda_c`` at damping ``d`` (linear in log D_W, clamped to the table)."""
        return float(np.interp(math.log(d), np.log(self.damping), self.critical))

    def fold_at(self, d: float) -> float:
        """``Lambda_fold`` at ``d`` (NaN if the fold curve is unknown)."""
        if len(self.fold) == 0:
            return math.nan
        return float(np.interp(math.log(d), np.log(self.fold_damping), self.fold))

    def region(self, bearing_number: float, d: float) -> str:
        """``"stable"`` (equilibrium only), ``"bistable"`` (equilibrium and whirl) or ``"whirl"``."""
        if bearing_number >= self.critical_at(d):
            return "whirl"
        f = self.fold_at(d)
        if math.isfinite(f) and bearing_number >= f:
            return "bistable"
        return "stable"

    def rpm(self, bearing_number: float) -> float:
        """Rotor speed of the nominal bearing at ``bearing_number``."""
        return bearing_number * self.speed_per_lambda_rpm

    def best_fold_damping(self) -> float:
        """Damping with the highest fold (the narrowest hysteresis band from above); ``d_opt`` if unknown."""
        if len(self.fold) == 0:
            return self.d_opt
        return float(self.fold_damping[int(np.argmax(self.fold))])


def _nominal_fold(foil_stiffness: float, path: str | Path | None) -> tuple[np.ndarray, np.ndarray]:
    """``(D_W, Lambda_fold)`` of the hysteresis map at ``foil_stiffness`` (within 5 %), else empty arrays."""
    from gfb_env.analysis import load_hysteresis_map

    empty = (np.zeros(0), np.zeros(0))
    # a missing or empty map is an error (FileNotFoundError / ValueError naming the file and the script
    # that makes it), never a silently unknown fold; "unknown" means only: the map lacks this stiffness
    hm = load_hysteresis_map(path)
    if not (foil_stiffness > 0):
        return empty
    sel = np.abs(np.log(hm.foil_stiffness / foil_stiffness)) < 0.05
    sel &= np.isfinite(hm.fold_bearing_number)
    if not sel.any():
        return empty
    order = np.argsort(hm.foil_damping[sel])
    return hm.foil_damping[sel][order], hm.fold_bearing_number[sel][order]
