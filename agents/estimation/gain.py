"""The posterior over the hidden damping effectiveness ``g`` (actual ``D_W = g x`` commanded), fed by decays,
whirl onsets and the unbalance probe.
"""

from __future__ import annotations

import math

import numpy as np

from gfb_agents.estimation.stability import StabilityTable

__all__ = ["DECAY_CALIBRATION", "GainPosterior"]


#: calibration of the measured envelope decay (log per control step) against the linear rate
#: ``step_tau sigma`` (60 sigma on a 60-tau step): slope and offset of ``measured = a * step_tau sigma + b``
#: and the scatter, fitted on training seeds (docs/agents.md)
DECAY_CALIBRATION = {"a": 1.0, "b": 0.0, "sd": 0.15, "outlier": 0.1}


class GainPosterior:
    """Posterior over the hidden damping effectiveness ``g`` on a grid in ``ln g`` (prior: log-uniform
    over the documented ``gain_range``; a single point ``g = 1`` when the task draws none)."""

    def __init__(self, gain_range: tuple[float, float] | None, n: int = 41):
        if gain_range is None:
            self.gains = np.array([1.0])
        else:
            lo, hi = gain_range
            self.gains = np.geomspace(lo, hi, n)
        self.log_w = np.zeros(len(self.gains))
        self.measurements: list[tuple] = []

    @property
    def weights(self) -> np.ndarray:
        w = np.exp(self.log_w - self.log_w.max())
        return w / w.sum()

    def add_decay(
        self, table: StabilityTable, lam: float, d_cmd: float, rate_per_step: float, step_tau: float = 60.0
    ) -> None:
        """A measured decay (log per control step) at ``Lambda`` with commanded damping ``d_cmd``:
        Gaussian around the calibrated prediction, with an outlier floor (robust to a mis-detection).
        ``step_tau``: one control step in tau of ``table``'s plant (the env's ``ControlClock``; 60, v1's step;
        on a v2 drawn bearing ``60 T_nom / T``, the step being a fixed period in seconds)."""
        cal = DECAY_CALIBRATION
        pred = cal["a"] * step_tau * table.growth_rate(lam, self.gains * d_cmd) + cal["b"]
        z = (rate_per_step - pred) / cal["sd"]
        lik = (1 - cal["outlier"]) * np.exp(-0.5 * z * z) / cal["sd"] + cal["outlier"] / 3.0
        self.log_w += np.log(lik)
        self.measurements.append(("decay", lam, d_cmd, rate_per_step))

    def add_instability(self, table: StabilityTable, lam: float, d_cmd: float) -> None:
        """A whirl grew at ``Lambda`` with ``d_cmd``: plants that are clearly stable there are unlikely."""
        sig = table.growth_rate(lam, self.gains * d_cmd)
        self.log_w += np.where(sig > -0.003, 0.0, math.log(0.05))
        self.measurements.append(("whirl", lam, d_cmd))
