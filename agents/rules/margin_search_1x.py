"""``margin_search_1x``: :class:`~gfb_agents.rules.margin_search.MarginSearchAgent` with the v2
observation's 1x vectors (issue 19 s.3: "the 1x vector versus damping").

The same probe as ``margin_search`` (hold the start speed, step the commanded damping through 0.3, 1.5 and
7.0, ten settled steps each; below the speed at which a control step's record holds the monitor's minimum
revolutions, as RunUpRandomized-v2's 20 600 rpm start, the probe runs 3 % above that speed instead), but
each settled step also gives the vibration monitor's 1x vector of both probes (``x_1x_pp``, ``x_1x_cos``,
... read by name from ``env.unwrapped.observation_layout``), averaged
over the steps of each damping, and the gain follows from the ratios of those vectors between the dampings
against the public model's (:mod:`gfb_agents.estimation.one_x`: the unbalance and the probes' bias drop
out).  The 1x likelihood is added to ``margin_search``'s posterior (which keeps its own unbalance probe on
the v1 channels, the shock decays and the whirl onsets) on a finer grid in ``ln g`` (161 points: the 1x
estimate is sharper than margin_search's 41-point spacing of 0.115), and the operating point is
``margin_search``'s :func:`~gfb_agents.rules.operating_point.choose_operating_point` under it.

Only public information: the nominal bearing, the grid, the actuator's ``gain_range``, the probes'
documented directions and noise, the observation.  Cost: one sparse solve per (candidate gain, damping)
at the probe's speed (161 x 3, ~0.5 s per episode), cached per process on the nominal task (the speed
and the dampings are the same every episode).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from gfb_agents.estimation.gain import GainPosterior
from gfb_agents.estimation.one_x import MonitorPhasors, OneXProbe, monitor_1x_sd, probe_responses
from gfb_agents.rules.margin_search import MarginSearchAgent, MarginSearchMemory, Mode
from gfb_env.equilibrium import find_equilibrium

__all__ = ["MarginSearch1xMemory", "MarginSearch1xAgent"]

#: samples per control step the v2 monitor demodulates (gfb_env.envs.interface_v2.SAMPLES_PER_STEP)
_SAMPLES_PER_STEP = 120


@dataclass
class MarginSearch1xMemory(MarginSearchMemory):
    """:class:`MarginSearchMemory` plus the 1x vectors of the probe and their log-likelihood per gain."""

    onex: OneXProbe | None = None
    ll_1x: np.ndarray | None = None


class MarginSearch1xAgent(MarginSearchAgent):
    """``margin_search_1x`` (module docstring).

    Args:
        n_gains: grid points of the posterior over ``ln g`` (log-uniform prior over ``gain_range``).
        one_x_temper: weight of the 1x log-likelihood (1: the documented noise taken at its word).
        model_error: relative error of the model's 1x response added to the noise (None: 2 % on the
            nominal bearing, 8 % on an identified one).
        kw: :class:`MarginSearchAgent`'s.
    """

    #: the nominal task's responses (per process): (Lambda, dampings, gains) -> (n_g, n_seg, 2)
    _RESPONSE_CACHE: ClassVar[dict] = {}

    def __init__(
        self,
        env,
        n_gains: int = 161,
        one_x_temper: float = 1.0,
        model_error: float | None = None,
        name: str = "margin_search_1x",
        **kw,
    ):
        super().__init__(env, name=name, **kw)
        u = getattr(env, "unwrapped", env)
        if int(n_gains) < 2:
            raise ValueError(f"n_gains must be >= 2, got {n_gains!r}")
        if not one_x_temper >= 0:
            raise ValueError(f"one_x_temper must be >= 0, got {one_x_temper!r}")
        self.n_gains = int(n_gains)
        self.one_x_temper = float(one_x_temper)
        self.model_error = float(
            model_error if model_error is not None else (0.08 if self.randomized else 0.02)
        )
        self.phasors = MonitorPhasors(u.observation_layout)
        probes = u.proximity_probes
        self.directions = np.asarray(probes.directions, dtype=float)
        self.one_x_sd = monitor_1x_sd(
            float(probes.noise_um), _SAMPLES_PER_STEP, self.nominal.clearance_m * 1e6
        )
        #: the latest probe's evidence (for inspection): gains, 1x and v1 log-likelihoods
        self.last_probe: dict | None = None
        # the slowest speed at which the monitor's record of one control step holds its minimum
        # revolutions (public: the monitor's configuration and the step's seconds), with 3 % to spare:
        # RunUpRandomized-v2 starts at 20 600 rpm, below the 22 010 rpm of 3.5 revolutions in 9.54 ms,
        # so a probe at the start speed would get no 1x vector at all
        monitor = getattr(getattr(u, "interface", None), "monitor", None)
        self.probe_floor_rpm = (
            1.03 * monitor.min_revolutions * 60.0 / float(u.control_step_s) if monitor is not None else 0.0
        )

    def _new_memory(self) -> MarginSearch1xMemory:
        base = super()._new_memory()
        m = MarginSearch1xMemory(**{f.name: getattr(base, f.name) for f in dataclasses.fields(base)})
        m.post = GainPosterior(self.gain_range, n=self.n_gains)
        m.onex = OneXProbe(self.one_x_sd)
        return m

    def _init_plant(self, m: MarginSearch1xMemory, obs: np.ndarray, rpm: float) -> None:
        super()._init_plant(m, obs, rpm)
        if m.mode is Mode.PROBE and rpm < self.probe_floor_rpm:
            m.probe_rpm = self.probe_floor_rpm  # the probe where the monitor reads a 1x vector

    def _probe_sample(self, m: MarginSearch1xMemory, d: float, obs: np.ndarray) -> None:
        super()._probe_sample(m, d, obs)
        z = self.phasors(obs)
        if z is not None:
            m.onex.add(d, z)

    def _responses(self, m: MarginSearch1xMemory, lam: float, ds: np.ndarray) -> np.ndarray:
        gains = m.post.gains
        key = (round(lam, 12), tuple(np.round(ds, 12)), len(gains)) if not self.randomized else None
        if key is not None and key in self._RESPONSE_CACHE:
            return self._RESPONSE_CACHE[key]
        s0 = find_equilibrium(m.model, lam)
        flat = probe_responses(m.model, s0, lam, (gains[:, None] * ds[None, :]).ravel(), self.directions)
        out = flat.reshape(len(gains), len(ds), -1)
        if key is not None:
            self._RESPONSE_CACHE[key] = out
        return out

    def _finish_probe(self, m: MarginSearch1xMemory) -> None:
        before = m.post.log_w.copy()
        super()._finish_probe(m)  # margin_search's own probe on the v1 channels (and the mode change)
        ll_v1 = m.post.log_w - before
        onex = m.onex
        onex.segments = [sg for sg in onex.segments if len(sg.z) >= 3]
        if len(onex.segments) < 2 or len(m.post.gains) < 2:
            return
        rpm = m.probe_rpm if m.probe_rpm is not None else self.start_speed_rpm
        lam = m.bearing.bearing_number_at(rpm)
        ds = np.array([sg.d for sg in onex.segments])
        ll = onex.log_likelihood(self._responses(m, lam, ds), self.model_error)
        m.ll_1x = ll
        m.post.log_w = m.post.log_w + self.one_x_temper * ll
        m.post.measurements.append(("one_x", lam, tuple(ds)))
        m.dirty = True
        self.last_probe = {"gains": m.post.gains.copy(), "ll_1x": ll.copy(), "ll_v1": ll_v1, "step": m.k}
