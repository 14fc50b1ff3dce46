"""The stability table of one plant: the growth rate of the whirl mode on a grid of speed and actual
damping."""

from __future__ import annotations

import numpy as np

from gfb_env.analysis import jacobian_eigenvalues
from gfb_env.equilibrium import find_equilibrium
from gfb_env.model import GFBModel

__all__ = ["StabilityTable"]


class StabilityTable:
    """Growth rate ``sigma = max Re(eig J)`` of the whirl mode of one plant on a grid of ``Lambda`` and
    actual ``D_W`` (log-spaced), interpolated bilinearly in ``(Lambda, ln D_W)``.

    The static equilibrium does not depend on ``D_W``, so one equilibrium per ``Lambda`` serves every
    damping (as :func:`gfb_env.analysis.task_constants.critical_bearing_numbers_on_grid`)."""

    def __init__(self, lambdas: np.ndarray, dampings: np.ndarray, sigma: np.ndarray):
        self.lambdas = np.asarray(lambdas, dtype=float)
        self.dampings = np.asarray(dampings, dtype=float)
        self.log_d = np.log(self.dampings)
        self.sigma = np.asarray(sigma, dtype=float)  # (n_lambda, n_damping)

    @classmethod
    def compute(
        cls,
        model: GFBModel,
        lam_lo: float,
        lam_hi: float,
        n_lambda: int = 25,
        damping_range: tuple[float, float] = (0.025, 40.0),
        n_damping: int = 21,
    ) -> StabilityTable:
        lams = np.linspace(lam_lo, lam_hi, n_lambda)
        ds = np.geomspace(*damping_range, n_damping)
        sig = np.full((n_lambda, n_damping), np.nan)
        s = None
        for i, lam in enumerate(lams):
            s = find_equilibrium(model, float(lam), guess=s)
            for j, d in enumerate(ds):
                sig[i, j] = jacobian_eigenvalues(model, s, float(lam), float(d))[0].real
        return cls(lams, ds, sig)

    def _columns(self, d: np.ndarray) -> np.ndarray:
        """sigma(Lambda_grid, d) for actual dampings ``d`` (any shape): shape (n_lambda, *d.shape)."""
        x = np.clip(np.log(np.asarray(d, dtype=float)), self.log_d[0], self.log_d[-1])
        j = np.clip(np.searchsorted(self.log_d, x) - 1, 0, len(self.log_d) - 2)
        w = (x - self.log_d[j]) / (self.log_d[j + 1] - self.log_d[j])
        return self.sigma[:, j] * (1 - w) + self.sigma[:, j + 1] * w

    def growth_rate(self, lam: float, d: np.ndarray) -> np.ndarray:
        """``sigma(Lambda, d)`` (per tau) for actual dampings ``d``."""
        cols = self._columns(d)
        lam = float(np.clip(lam, self.lambdas[0], self.lambdas[-1]))
        i = int(np.clip(np.searchsorted(self.lambdas, lam) - 1, 0, len(self.lambdas) - 2))
        w = (lam - self.lambdas[i]) / (self.lambdas[i + 1] - self.lambdas[i])
        out = cols[i] * (1 - w) + cols[i + 1] * w
        # outside the table in Lambda: extrapolate linearly with the end slope (sigma is ~linear there)
        return out

    def critical(self, d: np.ndarray, level: float = 0.0) -> np.ndarray:
        """``Lambda_c`` at actual dampings ``d`` (any shape): first crossing of ``sigma = level`` along
        the grid (linear interpolation; ``level = 0``: the stability boundary, ``level < 0``: where the
        mode still decays at that rate); the grid's top if below throughout, its bottom if above at once."""
        cols = self._columns(d) - level  # (n_lambda, ...)
        flat = cols.reshape(len(self.lambdas), -1)
        out = np.full(flat.shape[1], self.lambdas[-1])
        unstable = flat >= 0
        first = np.where(unstable.any(axis=0), unstable.argmax(axis=0), -1)
        for k in np.flatnonzero(first >= 0):
            i = first[k]
            if i == 0:
                out[k] = self.lambdas[0]
            else:
                s0, s1 = flat[i - 1, k], flat[i, k]
                out[k] = self.lambdas[i - 1] + (self.lambdas[i] - self.lambdas[i - 1]) * s0 / (s0 - s1)
        return out.reshape(np.shape(d))
