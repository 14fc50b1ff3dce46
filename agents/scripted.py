"""Scripted baselines for the gfb_env tasks, behind one small SB3-like policy interface.

Every agent (scripted here, learned in :mod:`gfb_agents.evaluate`) implements::

    policy.reset()                                           # forget everything (a new episode)
    action, state = policy.predict(obs, state=None, episode_start=None, deterministic=True)

``obs`` is the env's documented observation (one of shape ``(n_obs,)`` or a batch ``(n_envs, n_obs)``);
``episode_start`` (a bool or an array of them, as SB3 passes it) resets the memory of the matching env.
Scripted agents read only the documented observation (indices below), the env's documented
configuration (:class:`ControlSpec`: action mapping, motor limit, control interval, nominal task
target) and the nominal map (:class:`~gfb_agents.nominal_map.NominalMap`); never the drawn parameters nor
the simulator state.

The observation and action units have one owner, :mod:`gfb_env.envs.units` (``env.observation_layout``
and ``env.actions``); the agents decode observations and encode actions only through it.

Agents (:func:`make_scripted_agents` builds the standard set):

* :class:`ScheduleAgent` (``paper_ramp_D<d>``): the paper's schedule -- a linear speed ramp (half the
  motor limit) at a constant foil damping to the nominal task speed, then hold.
* :class:`MapInformedAgent` (``map_informed``): damping at the map's ``argmax Lambda_c``, ramp at the motor
  limit, hold at ``(1 - margin) Lambda_c(d_opt)``; ``map_informed_fold`` holds below the fold of cycles
  instead (safe against large disturbances, slower).
* :class:`WhirlGuardAgent` (``feedback``): the map-informed schedule plus feedback -- detect whirl onset
  from the orbit envelope, back the speed off below the fold, retune the damping (to the damping with
  the highest fold), then creep back to just below the speed at which the whirl appeared.
* :class:`DampingSearchAgent` (``damping_search``): online search for the best damping -- probe the whirl
  onset speed at a few dampings (ramping, backing off at onset), then run at the damping with the highest
  onset to ``(1 - margin)`` of that onset speed.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from gfb_agents.nominal_map import NominalMap
from gfb_env.envs.units import ActionMap, ObservationLayout

__all__ = [
    "Policy",
    "ControlSpec",
    "ScheduleAgent",
    "MapInformedAgent",
    "WhirlGuardAgent",
    "DampingSearchAgent",
    "make_scripted_agents",
]


class Policy:
    """SB3-like policy interface shared by scripted and learned agents."""

    name: str = "policy"
    kind: str = "scripted"

    def reset(self) -> None:
        """Forget the episode memory of every env."""

    def predict(
        self,
        observation: np.ndarray,
        state: Any = None,
        episode_start: np.ndarray | bool | None = None,
        deterministic: bool = True,
    ) -> tuple[np.ndarray, Any]:
        """Action(s) for ``observation`` (shape ``(n_obs,)`` or ``(n_envs, n_obs)``).

        Returns ``(action, state)`` with ``action`` of shape ``(2,)`` or ``(n_envs, 2)`` in ``[-1, 1]``."""
        raise NotImplementedError

    def __repr__(self) -> str:
        return f"{type(self).__name__}({self.name!r})"


@dataclass(frozen=True)
class ControlSpec:
    """The env's documented configuration that a scripted agent may use.

    Attributes:
        actions: the env's action map (log-scaled damping, motor limit).
        observations: the env's observation layout (indices, scales, decoders).
        rpm_per_step: nominal speed change of one control step at action[0] = 1 (motor limit times the
            control step of the *nominal* bearing; for a randomised bearing the agents re-estimate it).
        target_rpm: the nominal task's target speed (``target_fraction * lambda_best`` of the nominal
            bearing; RunUp-v0's documented target).
        stable_amplitude: whirl amplitude (units of C) that counts as stable.
    """

    actions: ActionMap
    observations: ObservationLayout
    rpm_per_step: float
    target_rpm: float
    stable_amplitude: float

    @classmethod
    def from_env(cls, env, nmap: NominalMap | None = None) -> ControlSpec:
        u = getattr(env, "unwrapped", env)
        nmap = nmap or NominalMap.from_env(u)
        frac = float(getattr(u, "target_fraction", 0.95))
        return cls(
            actions=u.actions,
            observations=u.observation_layout,
            rpm_per_step=u.actions.rpm_per_step(u.nominal_bearing, u.control_interval),
            target_rpm=float(nmap.rpm(frac * nmap.lambda_best)),
            stable_amplitude=float(u.stable_amplitude),
        )

    @property
    def damping_range(self) -> tuple[float, float]:
        return self.actions.damping_range

    def damping_action(self, d: float) -> float:
        """Action[1] for damping ``d`` (the env's log mapping, clipped)."""
        return self.actions.action_from_damping(d)


class ScriptedPolicy(Policy):
    """Base of the scripted agents: per-env memory, a speed set-point tracker with an online estimate of
    the speed change per control step (the randomised clearance changes the time scale)."""

    kind = "scripted"

    def __init__(self, name: str, spec: ControlSpec):
        self.name = name
        self.spec = spec
        self._mem: list[dict] = []

    def reset(self) -> None:
        self._mem = []

    def _new_memory(self) -> dict:
        return {"k": 0, "rate": self.spec.rpm_per_step, "prev_rpm": None, "prev_a0": 0.0}

    def predict(self, observation, state=None, episode_start=None, deterministic=True):
        obs = np.asarray(observation, dtype=np.float64)
        single = obs.ndim == 1
        obs2 = obs[None, :] if single else obs
        n = obs2.shape[0]
        starts = (
            np.zeros(n, dtype=bool)
            if episode_start is None
            else np.broadcast_to(np.asarray(episode_start, dtype=bool), (n,))
        )
        while len(self._mem) < n:
            self._mem.append(self._new_memory())
        acts = np.empty((n, 2), dtype=np.float32)
        for i in range(n):
            if starts[i]:
                self._mem[i] = self._new_memory()
            m = self._mem[i]
            rpm = self.spec.observations.speed_rpm(obs2[i])
            self._update_rate(m, rpm)
            a = np.clip(np.asarray(self._act(obs2[i], rpm, m), dtype=np.float64), -1.0, 1.0)
            m["prev_rpm"], m["prev_a0"], m["k"] = rpm, float(a[0]), m["k"] + 1
            acts[i] = a
        return (acts[0] if single else acts), state

    @staticmethod
    def _update_rate(m: dict, rpm: float) -> None:
        """Re-estimate the rpm per control step at action[0] = 1 from the last full-rate step."""
        if m["prev_rpm"] is not None and abs(m["prev_a0"]) >= 0.5:
            r = (rpm - m["prev_rpm"]) / m["prev_a0"]
            if r > 0.2 * m["rate"] and r < 5 * m["rate"]:
                m["rate"] = r

    @staticmethod
    def track(m: dict, rpm: float, setpoint: float, max_rate: float = 1.0) -> float:
        """Action[0] that moves the speed to ``setpoint`` (dead-beat with the estimated step rate)."""
        return float(np.clip((setpoint - rpm) / m["rate"], -max_rate, max_rate))

    def _act(self, obs: np.ndarray, rpm: float, m: dict) -> np.ndarray:  # pragma: no cover - abstract
        raise NotImplementedError


class ScheduleAgent(ScriptedPolicy):
    """The paper's schedule: a linear ramp at ``ramp`` of the motor limit to ``setpoint_rpm`` (default the
    nominal task target) at constant damping ``damping``, then hold."""

    def __init__(
        self,
        spec: ControlSpec,
        damping: float,
        ramp: float = 0.5,
        setpoint_rpm: float | None = None,
        name: str | None = None,
    ):
        super().__init__(name or f"paper_ramp_D{damping:g}", spec)
        if not (0 < ramp <= 1):
            raise ValueError(f"ramp must lie in (0, 1], got {ramp!r}")
        self.damping, self.ramp = float(damping), float(ramp)
        self.setpoint_rpm = float(setpoint_rpm if setpoint_rpm is not None else spec.target_rpm)

    @classmethod
    def from_schedule(cls, spec: ControlSpec, schedule, name: str = "designed_schedule") -> ScheduleAgent:
        """The run-up designed by ``gfb schedule`` (:class:`gfb_env.analysis.schedule.RunUpSchedule`):
        its damping, its acceleration (as a fraction of the env's motor limit, at most 1) and its end
        speed."""
        b = schedule.model.bearing
        accel = b.rate_rpm_per_s(schedule.rate)
        ramp = min(1.0, accel / spec.actions.max_acceleration_rpm_per_s)
        return cls(spec, schedule.foil_damping, ramp, b.speed_rpm_at(schedule.end_bearing_number), name)

    def _act(self, obs, rpm, m):
        return [self.track(m, rpm, self.setpoint_rpm, self.ramp), self.spec.damping_action(self.damping)]


class MapInformedAgent(ScriptedPolicy):
    """Damping at the map's optimum (``argmax Lambda_c``), ramp at the motor limit, hold at
    ``(1 - margin) Lambda_c(d_opt)``; with ``below_fold=True`` hold at ``(1 - margin) Lambda_fold`` instead
    (where the map knows the fold), so that no disturbance can start a surviving whirl."""

    def __init__(
        self,
        spec: ControlSpec,
        nmap: NominalMap,
        margin: float = 0.05,
        below_fold: bool = False,
        name: str | None = None,
    ):
        super().__init__(name or ("map_informed_fold" if below_fold else "map_informed"), spec)
        if not (0 <= margin < 0.5):
            raise ValueError(f"margin must lie in [0, 0.5), got {margin!r}")
        self.damping = nmap.best_fold_damping() if below_fold else nmap.d_opt
        lam = nmap.critical_at(self.damping)
        if below_fold and math.isfinite(nmap.fold_at(self.damping)):
            lam = nmap.fold_at(self.damping)
        self.setpoint_rpm = nmap.rpm((1.0 - margin) * lam)

    def _act(self, obs, rpm, m):
        return [self.track(m, rpm, self.setpoint_rpm), self.spec.damping_action(self.damping)]


def whirl_seen(envelope: float, m: dict, threshold: float, big: float = 0.06, persist: int = 3) -> bool:
    """Whirl detector on the orbit envelope (:meth:`ObservationLayout.envelope`, units of C).

    A disturbance kick makes the envelope of one control step jump to ~0.01-0.03 C, after which it decays
    (slowly near ``Lambda_c``); a whirl persists and grows.  So: envelope above ``threshold`` and not
    decaying (at least 95 % of the previous step's) in ``persist`` consecutive control steps, or above
    ``big`` once.  (While ramping, the drift of the equilibrium alone gives ~0.002-0.007 C.)  Keeps its
    counters in ``m``."""
    e = envelope
    prev = m.get("ext_prev", 0.0)
    m["ext_prev"] = e
    m["ext_count"] = m.get("ext_count", 0) + 1 if (e > threshold and e >= 0.95 * prev) else 0
    return e > big or m["ext_count"] >= persist


class WhirlGuardAgent(ScriptedPolicy):
    """Map-informed schedule with whirl feedback.

    Runs like :class:`MapInformedAgent` (``d_opt``, motor limit, set-point ``(1 - margin) Lambda_c``).  A
    whirl is detected by :func:`whirl_seen` (orbit envelope above ``threshold`` in two consecutive
    steps).  On a whirl it decelerates at the motor limit to ``backoff`` below the
    speed where the whirl appeared (below the fold: the nominal map's fold when known), switches the
    damping to the value with the highest fold, and, once the envelope has stayed calm for ``calm_steps``,
    returns to ``(1 - margin)`` of the whirl speed (or the original set-point, if lower).
    """

    def __init__(
        self,
        spec: ControlSpec,
        nmap: NominalMap,
        margin: float = 0.05,
        threshold: float = 0.01,
        backoff: float = 0.08,
        calm_steps: int = 3,
        name: str = "feedback",
    ):
        super().__init__(name, spec)
        self.nmap = nmap
        self.margin, self.threshold, self.backoff, self.calm_steps = (
            margin,
            threshold,
            backoff,
            int(calm_steps),
        )
        self.d_run = nmap.d_opt
        self.d_recover = nmap.best_fold_damping()
        self.setpoint_rpm = nmap.rpm((1.0 - margin) * nmap.critical_at(self.d_run))
        fold = nmap.fold_at(self.d_recover)
        # the fold relative to Lambda_c: how far below a whirl's speed the cycle is sure to die
        self.fold_ratio = fold / nmap.critical_at(self.d_recover) if math.isfinite(fold) else 1.0 - backoff

    def _new_memory(self) -> dict:
        m = super()._new_memory()
        m.update(
            {
                "mode": "run",
                "setpoint": self.setpoint_rpm,
                "damping": self.d_run,
                "calm": 0,
                "whirl_rpm": None,
            }
        )
        return m

    def _act(self, obs, rpm, m):
        whirl = whirl_seen(self.spec.observations.envelope(obs), m, self.threshold)
        if whirl:
            if m["mode"] != "recover":
                m["whirl_rpm"] = rpm if m["whirl_rpm"] is None else min(m["whirl_rpm"], rpm)
                m["setpoint"] = m["whirl_rpm"] * min(1.0 - self.backoff, self.fold_ratio * (1 - self.margin))
            elif rpm <= m["setpoint"] + 0.5 * m["rate"]:
                # at the set-point and still whirling: the fold is lower still
                m["setpoint"] *= 1.0 - 0.5 * self.backoff
            m["mode"], m["calm"], m["damping"] = "recover", 0, self.d_recover
        elif m["mode"] == "recover":
            m["calm"] += 1
            if m["calm"] >= self.calm_steps and abs(rpm - m["setpoint"]) < 0.5 * m["rate"]:
                m["mode"] = "return"
                m["setpoint"] = min(self.setpoint_rpm, (1.0 - self.margin) * m["whirl_rpm"])
        return [self.track(m, rpm, m["setpoint"]), self.spec.damping_action(m["damping"])]


class DampingSearchAgent(ScriptedPolicy):
    """Online search for the best damping by probing the whirl onset.

    Probes the dampings ``candidates`` (default ``d_opt`` and a factor ``spread`` either side) in turn: ramp
    at ``probe_rate`` of the motor limit until the orbit envelope exceeds ``threshold`` (or the speed reaches
    ``max_probe`` times the nominal ``lambda_best`` speed: no onset seen), note the onset speed, back off by
    ``backoff`` at full rate (below the fold) and calm down; then run at the damping with the highest
    onset to ``(1 - margin)`` of that onset speed.  The ramp overshoots ``Lambda_c`` a little (the
    instability needs time to grow), which the margin absorbs.
    """

    def __init__(
        self,
        spec: ControlSpec,
        nmap: NominalMap,
        spread: float = 2.0,
        margin: float = 0.05,
        threshold: float = 0.01,
        backoff: float = 0.1,
        probe_rate: float = 0.5,
        max_probe: float = 1.03,
        calm_steps: int = 3,
        name: str = "damping_search",
    ):
        super().__init__(name, spec)
        self.nmap = nmap
        self.candidates = [nmap.d_opt, nmap.d_opt / spread, nmap.d_opt * spread]
        self.margin, self.threshold, self.backoff = margin, threshold, backoff
        self.probe_rate, self.calm_steps = probe_rate, int(calm_steps)
        self.max_probe_rpm = nmap.rpm(max_probe * nmap.lambda_best)
        # approach fast up to where the lowest-onset bearing of the nominal map could whirl
        self.fast_until_rpm = nmap.rpm(0.9 * float(np.min(nmap.critical)))

    def _new_memory(self) -> dict:
        m = super()._new_memory()
        m.update({"mode": "probe", "i": 0, "onsets": [], "calm": 0, "setpoint": None, "best": None})
        return m

    def _finish_search(self, m: dict) -> None:
        onsets = m["onsets"]
        j = int(np.argmax(onsets))
        m["best"] = self.candidates[j]
        m["mode"] = "run"
        m["setpoint"] = (1.0 - self.margin) * onsets[j]

    def _act(self, obs, rpm, m):
        whirl = whirl_seen(self.spec.observations.envelope(obs), m, self.threshold)
        if m["mode"] == "probe":
            d = self.candidates[m["i"]]
            if whirl or rpm >= self.max_probe_rpm:
                m["onsets"].append(rpm)
                m["mode"], m["calm"] = "backoff", 0
                m["setpoint"] = rpm * (1.0 - self.backoff)
            else:
                rate = 1.0 if rpm < self.fast_until_rpm else self.probe_rate
                return [rate, self.spec.damping_action(d)]
        if m["mode"] == "backoff":
            m["calm"] = 0 if whirl else m["calm"] + 1
            d = (
                max(self.candidates[m["i"]], self.nmap.best_fold_damping())
                if whirl
                else self.candidates[m["i"]]
            )
            if m["calm"] >= self.calm_steps and rpm <= m["setpoint"] + 0.5 * m["rate"]:
                m["i"] += 1
                if m["i"] >= len(self.candidates):
                    self._finish_search(m)
                else:
                    m["mode"] = "probe"
                    return [self.probe_rate, self.spec.damping_action(self.candidates[m["i"]])]
            else:
                return [self.track(m, rpm, m["setpoint"]), self.spec.damping_action(d)]
        # run: hold just below the best onset; on a whirl, back off and lower the set-point
        if whirl:
            m["setpoint"] = min(m["setpoint"], rpm) * (1.0 - self.backoff)
        return [self.track(m, rpm, m["setpoint"]), self.spec.damping_action(m["best"])]


#: dampings of the paper-schedule baselines (constant D_W)
PAPER_DAMPINGS = (0.3, 1.0, 3.0, 10.0)


def make_scripted_agents(env, nmap: NominalMap | None = None) -> dict[str, ScriptedPolicy]:
    """The standard set of scripted baselines for ``env`` (any gfb_env task), by name."""
    nmap = nmap or NominalMap.from_env(env)
    spec = ControlSpec.from_env(env, nmap)
    agents: list[ScriptedPolicy] = [ScheduleAgent(spec, d) for d in PAPER_DAMPINGS]
    agents.append(MapInformedAgent(spec, nmap))
    if len(nmap.fold):
        agents.append(MapInformedAgent(spec, nmap, below_fold=True))
    agents += [WhirlGuardAgent(spec, nmap), DampingSearchAgent(spec, nmap)]
    return {a.name: a for a in agents}
