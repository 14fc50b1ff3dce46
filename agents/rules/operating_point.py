"""The decision of ``margin_search`` and ``recovery``: the commanded damping and speed that maximise the
expected terminal reward under the posterior over the damping gain.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from gfb_agents.estimation.gain import GainPosterior
from gfb_agents.estimation.stability import StabilityTable

__all__ = ["OperatingPointConfig", "OperatingPoint", "choose_operating_point"]


@dataclass(frozen=True)
class OperatingPointConfig:
    """The settings of :func:`choose_operating_point` (validated).

    Attributes:
        damping_range: the commanded dampings searched (low, high), log-spaced.
        rel_sd: relative sd of the plant's ``Lambda_c`` (identification error, interpolation).
        fail_cost: cost of an uncertified end in units of the full progress.
        n_damping, n_lambda: grid sizes of the search over dampings and speeds.
        level: the growth rate that counts as stable (``< 0``: a decay-rate margin).
        target_weight: the on-target bonus in units of the certified bonus (v1 reward: 25 / 50).
        tolerance: relative tolerance of the success test's target.
    """

    damping_range: tuple[float, float]
    rel_sd: float = 0.005
    fail_cost: float = 0.3
    n_damping: int = 49
    n_lambda: int = 200
    level: float = 0.0
    target_weight: float = 0.5
    tolerance: float = 0.02

    def __post_init__(self) -> None:
        lo, hi = (float(x) for x in self.damping_range)
        if not (0.0 < lo <= hi and math.isfinite(hi)):
            raise ValueError(f"damping_range must be 0 < low <= high, got {self.damping_range!r}")
        object.__setattr__(self, "damping_range", (lo, hi))
        if not (self.rel_sd > 0.0 and math.isfinite(self.rel_sd)):
            raise ValueError(f"rel_sd must be positive, got {self.rel_sd!r}")
        for name in ("n_damping", "n_lambda"):
            if int(getattr(self, name)) < 1:
                raise ValueError(f"{name} must be >= 1, got {getattr(self, name)!r}")
        for name in ("fail_cost", "level", "target_weight", "tolerance"):
            if not math.isfinite(float(getattr(self, name))):
                raise ValueError(f"{name} must be finite, got {getattr(self, name)!r}")


class OperatingPoint(NamedTuple):
    """The choice of :func:`choose_operating_point`: commanded damping, Lambda set-point, expected value."""

    damping: float
    bearing_number: float
    value: float


def choose_operating_point(
    table: StabilityTable,
    posterior: GainPosterior,
    lam_ref: float,
    lam_cmd: float,
    lam_cap: float,
    config: OperatingPointConfig,
) -> OperatingPoint:
    """The commanded damping and Lambda set-point maximising the expected terminal reward
    ``E[p(Lambda) 1{stable}] + target_weight P(stable and on target) - fail_cost P(unstable)`` over
    commanded dampings and speeds up to ``min(lam_cmd, lam_cap)`` (in units of the certified bonus: the
    v1 reward's on-target bonus is ``target_weight = 25 / 50`` of it); ``config``:
    :class:`OperatingPointConfig`.

    ``p = clip((Lambda - lam_ref)/(lam_cmd - lam_ref), 0, 1)`` as the v1 reward; "on target" means
    ``Lambda >= (1 - tolerance) min(lam_cmd, lambda_best(g))`` with ``lambda_best(g)`` the best boundary
    over the commanded damping range for that gain, as the env's success test; stable means
    ``Lambda < Lambda_c(g D_cmd)`` with ``Lambda_c`` of the (identified) plant uncertain by a Gaussian of
    relative sd ``rel_sd`` (identification error, interpolation); with ``level < 0`` "stable" means
    ``sigma < level``: a margin in decay rate, so that a shock's transient dies within a few steps and
    cannot throw the rotor over the small unstable cycle near a subcritical ``Lambda_c``.  Ties (e.g. a
    command below every plausible boundary) go to the damping with the highest expected boundary."""
    from scipy.special import ndtr

    damping_range, rel_sd, fail_cost = config.damping_range, config.rel_sd, config.fail_cost
    n_damping, n_lambda, level = int(config.n_damping), int(config.n_lambda), config.level
    target_weight, tolerance = config.target_weight, config.tolerance
    w = posterior.weights
    ds = np.geomspace(*damping_range, n_damping)
    lc = table.critical(posterior.gains[:, None] * ds[None, :], level)  # (n_g, n_d)
    top = min(lam_cmd, lam_cap)
    lams = np.linspace(lam_ref + 0.3 * (top - lam_ref), top, n_lambda)
    p = np.clip((lams - lam_ref) / max(lam_cmd - lam_ref, 1e-9), 0.0, 1.0)
    # the success test's target per gain: the true boundary (level 0), best over the damping range
    lc0 = lc if level == 0.0 else table.critical(posterior.gains[:, None] * ds[None, :], 0.0)
    goal = (1.0 - tolerance) * np.minimum(lam_cmd, lc0.max(axis=1))  # (n_g,)
    hit = lams[None, :] >= goal[:, None]  # (n_g, n_lambda)
    best = (float(ds[0]), float(lams[0]), -np.inf)
    for j in range(n_damping):
        # P(stable at each Lambda) = sum_g w_g Phi((Lambda_c - Lambda)/(rel_sd Lambda_c))
        phi = ndtr((lc[:, j][:, None] - lams[None, :]) / (rel_sd * lc[:, j][:, None]))
        ps = w @ phi
        pt = w @ (phi * hit)
        val = p * ps + target_weight * pt - fail_cost * (1 - ps) + 1e-3 * float(w @ lc[:, j]) / lam_cmd
        k = int(np.argmax(val))
        if val[k] > best[2]:
            best = (float(ds[j]), float(lams[k]), float(val[k]))
    return OperatingPoint(*best)
