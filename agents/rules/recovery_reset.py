"""``recovery_reset``: ``recovery`` that first reads the damping gain off the reset observation (issue 19).

The start of WhirlRecovery is the stored limit cycle advanced by a random phase under the actual damping
``g d_opt``: the further ``g`` lies from 1, the further the first observation lies from the stored cycle
(:mod:`gfb_agents.estimation.whirl_start`).  The rule multiplies ``recovery``'s prior over ``g`` by that
likelihood before its first decision, so the dip's damping, the probe's speed and the operating point all
start from the posterior; everything after is ``recovery``'s (survival, the unbalance probe, decays).
"""

from __future__ import annotations

import numpy as np

from gfb_agents.estimation.whirl_start import (
    FirstStepUpdate,
    ResetSensorModel,
    reset_log_likelihood,
    whirl_start_table,
)
from gfb_agents.rules.recovery import RecoveryAgent, RecoveryMemory

__all__ = ["RecoveryResetAgent"]


class RecoveryResetAgent(RecoveryAgent):
    """``recovery_reset`` (WhirlRecovery): :class:`RecoveryAgent` with the reset observation's likelihood
    of ``g`` (the documented start construction and sensor errors; rms error of ``ln g`` 0.14 on
    validation seeds against the prior's 0.32, docs/agents.md) in its posterior from the first step.

    Args:
        env: the task's env (its public configuration only: the start construction, the sensors).
        temper: exponent of the reset likelihood (1: as the sensor model says; < 1 widens it against
            model error).
        first_step: also the first control step's particle update
            (:class:`~gfb_agents.estimation.whirl_start.FirstStepUpdate`).
        probe_sd: skip ``recovery``'s unbalance probe after the dip when the posterior sd of ``ln g`` is
            below this (0: always probe, as ``recovery``; 0.06, set once before measuring: about twice
            the first step's typical sd, 0.014-0.03, and half the reset's, 0.12).
        **kw: :class:`RecoveryAgent`'s.
    """

    def __init__(
        self,
        env,
        temper: float = 1.0,
        first_step: bool = True,
        probe_sd: float = 0.06,
        name: str = "recovery_reset",
        **kw,
    ):
        super().__init__(env, name=name, **kw)
        u = getattr(env, "unwrapped", env)
        if not 0.0 < float(temper) <= 1.0:
            raise ValueError(f"temper must be in (0, 1], got {temper!r}")
        self.temper = float(temper)
        self.probe_sd = float(probe_sd)
        self.start_table = whirl_start_table(u)
        self.sensors = ResetSensorModel.from_env(u)
        layout = u.observation_layout
        # by name: the v2 observation adds entries (the vibration monitor) before the last two
        self._entries = np.array([layout.index(n) for n in self.start_table.names])
        self.first_step = FirstStepUpdate(u, self.start_table) if first_step else None
        if self.first_step is not None:
            self._entries1 = np.array([layout.index(n) for n in self.first_step.names1])
        self._damping_entry = layout.index("damping")
        self._reset_values: np.ndarray | None = None
        self._reset_ll_on_post: np.ndarray | None = None
        #: the last episode's reset log-likelihood on the table's gains (for inspection)
        self.last_reset_log_likelihood: np.ndarray | None = None
        self.last_first_step_log_likelihood: np.ndarray | None = None

    def reset_posterior(self, obs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(gains, log-likelihood)`` of the reset observation ``obs`` on the table's gains."""
        ll = reset_log_likelihood(
            self.start_table, self.sensors, np.asarray(obs, dtype=float)[self._entries], self.temper
        )
        return self.start_table.gains, ll

    def _wants_probe(self, m: RecoveryMemory) -> bool:
        """The unbalance probe only while the posterior sd of ln g is at least ``probe_sd``."""
        if not super()._wants_probe(m):
            return False
        w, lg = m.post.weights, np.log(m.post.gains)
        mu = float(w @ lg)
        return float(np.sqrt(w @ (lg - mu) ** 2)) >= self.probe_sd

    def _act(self, obs, rpm, m: RecoveryMemory):
        post = m.post
        if m.k == 0 and len(post.gains) > 1:
            gains, ll = self.reset_posterior(obs)
            self.last_reset_log_likelihood = ll
            self._reset_values = np.asarray(obs, dtype=float)[self._entries]
            self._reset_ll_on_post = np.interp(np.log(post.gains), np.log(gains), ll)
            post.log_w = post.log_w + self._reset_ll_on_post
            post.measurements.append(("reset", float(gains[int(np.argmax(ll))])))
        elif m.k == 1 and self.first_step is not None and self._reset_ll_on_post is not None:
            o = np.asarray(obs, dtype=float)
            lam1 = m.bearing.bearing_number_at(rpm)
            d_ind1 = self.spec.actions.damping_from_action(float(o[self._damping_entry]))
            ll, _ = self.first_step.log_likelihood(self._reset_values, o[self._entries1], lam1, d_ind1)
            if np.any(np.isfinite(ll)):  # (every particle failed: keep the reset's)
                ll = np.where(np.isfinite(ll), ll, np.min(ll[np.isfinite(ll)]) - 50.0)
                gains = self.start_table.gains
                on_post = np.interp(np.log(post.gains), np.log(gains), ll)
                # the joint likelihood replaces the reset's (it contains it)
                post.log_w = post.log_w - self._reset_ll_on_post + on_post
                post.measurements.append(("first_step", float(gains[int(np.argmax(ll))])))
                self.last_first_step_log_likelihood = ll
                self._decide(m, obs)
        return super()._act(obs, rpm, m)
