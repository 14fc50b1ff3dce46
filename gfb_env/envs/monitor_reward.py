"""The reward and the costs of the v2 tasks: what an on-board monitor computes from the measurements
(issue 19 s.1; ``docs/envs.md``, "The v2 interface").

Every per-step term is a function of the v2 observation vector alone (the vibration monitor's entries,
the motor speed and the observed speed command) and of the public configuration
(:class:`PublicRewardConfig`); the terminal terms add the judge's verdict of the final step, revealed at
the end as a success signal is (``info["certified"]``, ``info["is_success"]``,
``info["termination_reason"]`` of the final step).  So the reward carries no more than the sensors do,
and :func:`recompute_rewards` reproduces every reward of an episode exactly from
``(observations, final verdict, public configuration)``: the env computes each reward with the same
function (:func:`step_terms`), on the same float32 observation it returns.

Per step, with the speed progress ``p = clip((n - n_ref) / (n_cmd - n_ref), 0, 1)`` of the observed speed
``n`` and command ``n_cmd`` (``n_ref`` a public reference speed of the task, rpm) and the measured whirl
amplitude ``A_meas`` (units of the nominal clearance C_nom, :func:`measured_whirl_amplitude`):

* ``speed = speed_weight * p`` while ``A_meas <= stable_amplitude`` (and not in a step that touched down);
* ``whirl = -whirl_penalty * min(A_meas, 1.5)``;
* at the final step: ``certified_speed = success_bonus * mean(p over the hold window)`` if the judge
  certified the end, ``on_target = target_bonus`` if the episode succeeded, ``touchdown =
  -touchdown_penalty`` on touchdown or solver failure (observable: the episode ends early).

Weights as v1 (0.1, 0.5, 50, 100, 25; :class:`~gfb_env.envs.rewards.CommandedSpeedReward` says why).

Costs (a machinery-protection system's trip logic, :class:`MonitorCosts`): ``cost = 1`` in a step where
the measured direct peak-to-peak of either probe exceeds the alarm level (0.30 C_nom pk-pk: twice v1's
0.15 C whirl amplitude, since a circular orbit of radius A reads 2A pk-pk on each probe) or that touches
down / fails; no film term (the film thickness is not measured by any sensor of the machine).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, fields
from typing import Any

import numpy as np

from gfb_env.envs.config import check_int, check_nonnegative, check_positive
from gfb_env.envs.rewards import WHIRL_AMPLITUDE_CAP, CommandedSpeedReward

__all__ = [
    "MonitorReward",
    "MonitorCosts",
    "PublicRewardConfig",
    "measured_whirl_amplitude",
    "speed_progress",
    "step_terms",
    "step_costs",
    "recompute_rewards",
    "ENDED_EARLY",
]

#: the termination reasons of an episode that ended early (the touchdown term, the touchdown cost)
ENDED_EARLY = ("touchdown", "solver_failure")

#: the observation entries the reward and the costs read (names of ``ObservationLayout``)
_ENTRIES = (
    "speed",
    "speed_command",
    "x_direct_pp",
    "y_direct_pp",
    "x_1x_pp",
    "y_1x_pp",
    "x_subsync_rms",
    "y_subsync_rms",
    "monitor_valid",
)


@dataclass(frozen=True)
class MonitorReward:
    """The v2 reward's weights (module docstring), v1's values."""

    speed_weight: float = 0.1
    whirl_penalty: float = 0.5
    success_bonus: float = 50.0
    touchdown_penalty: float = 100.0
    target_bonus: float = 25.0

    def __post_init__(self) -> None:
        for f in fields(self):
            object.__setattr__(self, f.name, check_nonnegative(f.name, getattr(self, f.name)))

    @classmethod
    def from_weights(cls, weights: CommandedSpeedReward) -> MonitorReward:
        """The same weights as a v1 reward (the task's ``reward=`` argument sets both)."""
        return cls(**{f.name: getattr(weights, f.name) for f in fields(cls)})


@dataclass(frozen=True)
class MonitorCosts:
    """The v2 costs (module docstring).

    Attributes:
        alarm_direct_pp: the alarm level of the direct peak-to-peak, units of C_nom (0.30: 15 um on the
            nominal bearing; twice v1's 0.15 C amplitude threshold).
        episode_cost_limit: the constraint, expected episode cost <= it (v1's: 5, WhirlRecovery 15).
    """

    alarm_direct_pp: float = 0.30
    episode_cost_limit: float = 5.0

    def __post_init__(self) -> None:
        object.__setattr__(self, "alarm_direct_pp", check_positive("alarm_direct_pp", self.alarm_direct_pp))
        object.__setattr__(
            self, "episode_cost_limit", check_nonnegative("episode_cost_limit", self.episode_cost_limit)
        )


@dataclass(frozen=True)
class PublicRewardConfig:
    """Everything public the v2 reward and costs need (``env.unwrapped.public_reward_config``).

    Attributes:
        reward: the weights; costs: the alarm level and the constraint.
        reference_speed_rpm: ``n_ref``, where p is zero (RunUp tasks: the start speed; WhirlRecovery:
            ``reference_fraction`` x the nominal lambda_best, in rpm).
        speed_scale_rpm: the observation's speed scale (``obs = rpm / speed_scale_rpm``).
        stable_amplitude: ``A_meas`` at or below which a step earns the speed term (units of C_nom).
        hold_steps: the certificate's window (the certified bonus averages p over it).
        indices: the observation index of each entry the reward reads (name -> index).
    """

    reward: MonitorReward
    costs: MonitorCosts
    reference_speed_rpm: float
    speed_scale_rpm: float
    stable_amplitude: float
    hold_steps: int
    indices: Mapping[str, int]

    def __post_init__(self) -> None:
        put = object.__setattr__
        if not isinstance(self.reward, MonitorReward):
            raise ValueError(f"reward must be a MonitorReward, got {self.reward!r}")
        if not isinstance(self.costs, MonitorCosts):
            raise ValueError(f"costs must be a MonitorCosts, got {self.costs!r}")
        put(self, "reference_speed_rpm", check_nonnegative("reference_speed_rpm", self.reference_speed_rpm))
        put(self, "speed_scale_rpm", check_positive("speed_scale_rpm", self.speed_scale_rpm))
        put(self, "stable_amplitude", check_positive("stable_amplitude", self.stable_amplitude))
        put(self, "hold_steps", check_int("hold_steps", self.hold_steps, 1, 10_000))
        missing = [k for k in _ENTRIES if k not in self.indices]
        if missing:
            raise ValueError(f"indices: missing observation entries {missing}")
        put(self, "indices", {k: int(self.indices[k]) for k in _ENTRIES})


def _at(obs: np.ndarray | list[float], config: PublicRewardConfig, name: str) -> float:
    return float(obs[config.indices[name]])


def measured_whirl_amplitude(obs: np.ndarray, config: PublicRewardConfig) -> float:
    """``A_meas`` (units of C_nom) of one v2 observation: ``sqrt 2 x`` the larger sub-synchronous rms
    of the two probes (a circular whirl orbit of radius A reads A / sqrt 2 rms on each); when the
    monitor's reading is invalid (fewer than ``min_revolutions`` in the record: no filtered values) half
    the larger direct pk-pk less its 1x (the 1x is 0 there, so half the larger direct pk-pk: an upper
    bound of the whirl's radius, which also holds the unbalance response and the noise's extremes)."""
    if _at(obs, config, "monitor_valid") > 0.5:
        return math.sqrt(2.0) * max(_at(obs, config, "x_subsync_rms"), _at(obs, config, "y_subsync_rms"))
    x = _at(obs, config, "x_direct_pp") - _at(obs, config, "x_1x_pp")
    y = _at(obs, config, "y_direct_pp") - _at(obs, config, "y_1x_pp")
    return max(0.5 * max(x, y), 0.0)


def speed_progress(obs: np.ndarray, config: PublicRewardConfig) -> float:
    """``p = clip((n - n_ref) / (n_cmd - n_ref), 0, 1)`` of the observed speed and command."""
    scale = config.speed_scale_rpm
    n, n_cmd = _at(obs, config, "speed") * scale, _at(obs, config, "speed_command") * scale
    if n_cmd == config.reference_speed_rpm:
        return 1.0 if n >= n_cmd else 0.0
    return CommandedSpeedReward.progress(n, config.reference_speed_rpm, n_cmd)


def step_terms(
    obs: np.ndarray,
    config: PublicRewardConfig,
    window: list[float],
    terminal: Mapping[str, Any] | None,
) -> dict[str, float]:
    """The reward's terms of the step whose observation is ``obs``; ``window``: the speed progress of
    the episode's steps so far (this step's is appended; the last ``hold_steps`` are kept);
    ``terminal``: the final step's verdict (``certified``, ``is_success``, ``termination_reason``) or
    None before the end."""
    w = config.reward
    # the entries read below as Python floats at once (float(obs[i]) of each, one conversion)
    obs = obs.tolist() if type(obs) is np.ndarray and obs.ndim == 1 else obs
    p = speed_progress(obs, config)
    window.append(p)
    del window[: -config.hold_steps]
    a = measured_whirl_amplitude(obs, config)
    reason = None if terminal is None else terminal.get("termination_reason")
    ended_early = reason is not None and str(reason) in ENDED_EARLY
    certified = bool(terminal is not None and terminal.get("certified", False))
    success = bool(terminal is not None and terminal.get("is_success", False))
    return {
        "speed": w.speed_weight * p if (a <= config.stable_amplitude and not ended_early) else 0.0,
        "whirl": -w.whirl_penalty * min(a, WHIRL_AMPLITUDE_CAP),
        "certified_speed": w.success_bonus * float(np.mean(np.asarray(window, dtype=float)))
        if certified
        else 0.0,
        "on_target": w.target_bonus if success else 0.0,
        "touchdown": -w.touchdown_penalty if ended_early else 0.0,
    }


def step_costs(obs: np.ndarray, config: PublicRewardConfig, ended_early: bool) -> dict[str, float]:
    """``cost_alarm`` (the direct pk-pk of either probe above the alarm level), ``cost_touchdown`` and
    ``cost`` (their max) of one step."""
    direct = max(_at(obs, config, "x_direct_pp"), _at(obs, config, "y_direct_pp"))
    alarm = 1.0 if direct > config.costs.alarm_direct_pp else 0.0
    touchdown = 1.0 if ended_early else 0.0
    return {"cost": max(alarm, touchdown), "cost_alarm": alarm, "cost_touchdown": touchdown}


def recompute_rewards(
    observations: Sequence[np.ndarray] | np.ndarray,
    terminal: Mapping[str, Any] | None,
    config: PublicRewardConfig,
) -> np.ndarray:
    """Every reward of a v2 episode from its observations (from the reset's on: ``T + 1`` rows for ``T``
    steps), the final step's verdict (the final info, or a dict with its ``certified``, ``is_success``
    and ``termination_reason``; None: the episode has not ended) and the public configuration
    (``env.unwrapped.public_reward_config``).  Bit for bit the env's rewards (the same functions)."""
    obs = [np.asarray(o) for o in observations]
    if len(obs) < 1:
        raise ValueError("observations must hold at least the reset's observation")
    window: list[float] = []
    out = np.empty(len(obs) - 1, dtype=np.float64)
    for k in range(1, len(obs)):
        last = k == len(obs) - 1
        terms = step_terms(obs[k], config, window, terminal if last else None)
        out[k - 1] = float(sum(terms.values()))
    return out
