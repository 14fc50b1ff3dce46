"""A slew limit on the learned damping command (issue 21, "Realisable actuation"): the action
parameterisation that keeps the commanded damping from chattering, by construction.

The policy's damping output ``u`` (action entry 1, in ``[-1, 1]``) is a *set-point*; the command sent to
the env moves toward it by at most ``r`` per control step::

    a_d(k) = a_d(k-1) + clip(u(k) - a_d(k-1), -r, r),        a_d(-1) = the reset observation's damping

and the speed action (entry 0) passes unchanged.  So every step's ``|a_d(k) - a_d(k-1)|`` is at most
``r``, and so is its mean over an episode: the benchmark's ``mean_damping_change``
(:func:`gfb_agents.learned.evaluate.run_episode`, which measures the command from the same start).  The
command is delivered in float32 (the action's dtype), and its rounding could land a hair past the limit:
such a value is moved one float32 step back toward the previous command, so the bound holds exactly in
the float64 arithmetic ``run_episode`` measures with.

With a *reserve* ``C`` (``--damping-slew-reserve C``; default none) a step that moves less than ``r`` saves
the rest, up to ``C``, and a later step may move by ``r`` plus what is saved (a token bucket)::

    a_d(k) = a_d(k-1) + clip(u(k) - a_d(k-1), -(r + s(k-1)), r + s(k-1)),
    s(k) = clip(s(k-1) + r - |a_d(k) - a_d(k-1)|, 0, C),      s(-1) = 0,

so the moves of steps ``0..k`` sum to at most ``(k + 1) r`` however the episode ends (the mean stays at
most ``r``), while a policy that holds the damping may jump as the best rules do (they hold and jump:
docs/agents.md).  The saved allowance is not in the observation; a policy with memory can infer it.

Why a set-point and not an increment (``a_d(k) = a_d(k-1) + r u(k)``): the set-point keeps the action's
meaning (the damping the policy wants, as for a rule and as without the limit), a level is held by
asking for it (the increment form must output exactly 0, and a Gaussian policy's noise then walks the
command), and ``a_d`` stays in ``[-1, 1]`` without a clip (it lies between ``a_d(k-1)`` and ``u``).  The
price: every ``u`` beyond ``a_d(k-1) +- r`` acts alike (a flat region of the action for the learner),
where the increment form maps the whole output range onto distinct moves.

What the policy knows of ``a_d(k-1)``: its own previous command, kept here (:class:`DampingSlew`; reset
per episode from the reset observation).  The v2 observation's ``damping`` entry is the actuator's
*indicated* damping (its position feedback, ``D_W / g``), not the command; it follows the command through
the actuator's 10 ms lag, within about one step's move (``0.63 r`` on a ramp at the limit), so the policy's
input tells it nearly where the command is.  Training (:class:`gfb_agents.learned.vec_env.DampingSlewVecEnv`,
``python -m gfb_experiments.train --damping-slew R``) and deployment
(:class:`gfb_agents.learned.evaluate.LearnedPolicy`, which reads ``damping_slew`` from ``run.json`` /
``policy.json``) call the same :func:`slew_damping`, so they send the same bits.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np

from gfb_agents.policy import Policy
from gfb_env.envs.units import OBS_DAMPING

__all__ = [
    "MAX_DAMPING_SLEW",
    "DAMPING_ACTION",
    "check_damping_slew",
    "check_damping_slew_reserve",
    "slew_damping",
    "DampingSlew",
    "slewed_actions",
    "SlewLimitedPolicy",
]

#: the whole damping range in action units (``[-1, 1]``): a larger slew never binds
MAX_DAMPING_SLEW = 2.0
#: the damping entry of the action (entry 0 is the speed)
DAMPING_ACTION = 1
#: with a reserve, the allowance saved per step is ``rate * (1 - _RESERVE_MARGIN)``: the saved allowance is
#: a float64 running sum, and this keeps its rounding (and that of ``run_episode``'s sum) inside the bound
_RESERVE_MARGIN = 1e-9


def _action_units(value: Any, field: str, what: str) -> float:
    """``value`` as a float in ``(0, MAX_DAMPING_SLEW]``; a one-line ValueError naming ``field`` else."""
    ok = isinstance(value, (int, float, np.floating, np.integer)) and not isinstance(value, bool)
    if not ok or not math.isfinite(float(value)) or not 0.0 < float(value) <= MAX_DAMPING_SLEW:
        raise ValueError(
            f"{field} must be a finite number in (0, {MAX_DAMPING_SLEW:g}] action units{what}, got {value!r}"
        )
    return float(value)


def check_damping_slew(rate: Any) -> float | None:
    """``rate`` as a float in ``(0, MAX_DAMPING_SLEW]`` (None: no slew limit); one-line ValueError else."""
    if rate is None:
        return None
    what = f" per control step ({MAX_DAMPING_SLEW:g} is the whole damping range)"
    return _action_units(rate, "--damping-slew (damping_slew)", what)


def check_damping_slew_reserve(reserve: Any, rate: float | None) -> float | None:
    """``reserve`` as a float in ``(0, MAX_DAMPING_SLEW]`` (None: none), only with a ``rate``; one-line
    ValueError else."""
    if reserve is None:
        return None
    value = _action_units(reserve, "--damping-slew-reserve (damping_slew_reserve)", "")
    if rate is None:
        raise ValueError("--damping-slew-reserve (damping_slew_reserve): only with --damping-slew")
    return value


def slew_damping(previous: np.ndarray, target: np.ndarray, rate: float | np.ndarray) -> np.ndarray:
    """The commands ``previous + clip(target - previous, -rate, rate)`` (float32), each within ``rate``
    (a number, or one per env) of ``previous`` exactly (module docstring); ``target`` is clipped to
    ``[-1, 1]`` first, as the env clips an action."""
    p32 = np.asarray(previous, dtype=np.float32)
    p = p32.astype(np.float64)
    u = np.clip(np.asarray(target, dtype=np.float64), -1.0, 1.0)
    out = (p + np.clip(u - p, -rate, rate)).astype(np.float32)
    # float32 rounding past the limit: one float32 step back toward the previous command (which is a
    # float32 value, so the step lands between it and the exact value)
    over = np.abs(out.astype(np.float64) - p) > np.asarray(rate, dtype=np.float64)
    if np.any(over):
        out[over] = np.nextafter(out[over], p32[over])
    return out


class DampingSlew:
    """The slew limit's state for ``n`` envs: each env's previous damping command (and, with a
    ``reserve``, the allowance it saved).

    :meth:`start` sets it from (raw) observations: their ``damping`` entry, the indicated damping at
    reset, where the actuator rests at the command (and where ``run_episode`` starts its measure);
    :meth:`__call__` turns a batch of policy actions ``(n, 2)`` into the commands and keeps them.

    ``reserve`` (None: none): a step that moves less than ``rate`` saves the rest, up to ``reserve``
    action units, and a later step may move by ``rate`` plus what is saved (a token bucket).  The moves
    of steps ``0..k`` then sum to at most ``(k + 1) rate`` whenever the episode ends -- the mean stays at
    most ``rate`` -- while a policy that holds the damping may jump as the rules do."""

    def __init__(self, rate: float, reserve: float | None = None):
        r = check_damping_slew(rate)
        if r is None:
            raise ValueError("DampingSlew needs a rate (--damping-slew)")
        self.rate = r
        self.reserve = check_damping_slew_reserve(reserve, r)
        self.previous: np.ndarray | None = None  # (n,) float32
        self.saved: np.ndarray | None = None  # (n,) float64: the allowance saved (with a reserve)

    def reset(self) -> None:
        self.previous = None
        self.saved = None

    def start(self, observations: np.ndarray, which: np.ndarray | None = None) -> None:
        """New episodes for the envs ``which`` (a bool mask; None: all, and the env count is taken from
        ``observations``, shape ``(n, n_obs)``): their previous command is their observation's damping."""
        obs = np.asarray(observations)
        d = np.clip(obs[:, OBS_DAMPING].astype(np.float32), np.float32(-1.0), np.float32(1.0))
        if which is None or self.previous is None or self.previous.shape[0] != obs.shape[0]:
            self.previous = d.copy()
            self.saved = np.zeros(d.shape[0])
            return
        w = np.asarray(which, dtype=bool)
        self.previous[w] = d[w]
        self.saved[w] = 0.0

    def __call__(self, actions: np.ndarray) -> np.ndarray:
        """The commands of ``actions`` (shape ``(n, 2)``): the damping entry slewed (a float32 value), the
        speed entry unchanged."""
        if self.previous is None:
            raise RuntimeError("DampingSlew: start() with the reset observations first")
        x = np.asarray(actions)
        # the speed entry passes bit for bit (a float64 batch stays float64; the commands are float32)
        dtype = np.result_type(x.dtype, np.float32) if np.issubdtype(x.dtype, np.floating) else np.float32
        a = np.array(x, dtype=dtype, copy=True).reshape(self.previous.shape[0], -1)
        if self.reserve is None:
            a[:, DAMPING_ACTION] = slew_damping(self.previous, a[:, DAMPING_ACTION], self.rate)
        else:
            accrual = self.rate * (1.0 - _RESERVE_MARGIN)
            new = slew_damping(self.previous, a[:, DAMPING_ACTION], accrual + self.saved)
            moved = np.abs(new.astype(np.float64) - self.previous.astype(np.float64))
            self.saved = np.clip(self.saved + accrual - moved, 0.0, self.reserve)
            a[:, DAMPING_ACTION] = new
        self.previous = a[:, DAMPING_ACTION].copy()
        return a


def slewed_actions(
    slew: DampingSlew, observation: np.ndarray, action: np.ndarray, episode_start: Any
) -> np.ndarray:
    """A policy's ``action`` for ``observation`` (one ``(n_obs,)`` or a batch ``(n, n_obs)``, raw) as the
    commands of ``slew``; an env whose episode starts (``episode_start``, as SB3 passes it; or the first
    call after :meth:`DampingSlew.reset`) starts from its observation's damping.  The one code path of
    every deployed policy with a slew limit (:class:`~gfb_agents.learned.evaluate.LearnedPolicy`, the
    teacher's validation, :class:`SlewLimitedPolicy`)."""
    obs = np.asarray(observation)
    single = obs.ndim == 1
    o2 = obs[None, :] if single else obs
    n = o2.shape[0]
    if slew.previous is None or slew.previous.shape[0] != n:
        slew.start(o2)
    elif episode_start is not None:
        starts = np.broadcast_to(np.asarray(episode_start, dtype=bool), (n,))
        if starts.any():
            slew.start(o2, starts)
    a = slew(np.asarray(action).reshape(n, -1))
    return a[0] if single else a


class SlewLimitedPolicy(Policy):
    """Any :class:`~gfb_agents.policy.Policy` with the damping command slew-limited to ``rate`` per control
    step (its damping action read as a set-point).  A policy handed the reset info (an oracle) still is."""

    def __init__(self, policy: Policy, rate: float, reserve: float | None = None):
        self.policy = policy
        self.slew = DampingSlew(rate, reserve)
        self.name, self.kind = f"{policy.name}+slew{self.slew.rate:g}", policy.kind

    def reset(self) -> None:
        self.policy.reset()
        self.slew.reset()

    def observe_reset_info(self, info: Mapping[str, Any]) -> None:
        observe = getattr(self.policy, "observe_reset_info", None)
        if observe is not None:  # only a policy that takes it (run_episode's rule)
            observe(info)

    def predict(
        self,
        observation: np.ndarray,
        state: Any = None,
        episode_start: np.ndarray | bool | None = None,
        deterministic: bool = True,
    ) -> tuple[np.ndarray, Any]:
        action, state = self.policy.predict(observation, state, episode_start, deterministic)
        return slewed_actions(self.slew, observation, action, episode_start), state
