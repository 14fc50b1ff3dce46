"""The oracle as DAgger's teacher (issue 21): a privileged expert that is not learned.

:mod:`gfb_agents.learned.teacher_student`'s scheme with the teacher replaced by the benchmark's oracle
(:class:`gfb_agents.oracles.CommandedOracle`, 1 on the normalised scale): the "learning by cheating" form
of teacher-student training (Chen et al. 2019), where the privileged agent is an expert that knows the
hidden plant.  A ``privileged_ppo`` teacher reached 0.59 of the oracle on RunUpRandomized-v2 at 1M steps
(docs/agents.md): its students inherit that ceiling.  The oracle's labels take it away, so what the
student loses against the oracle is what its observation history cannot tell, not the teacher's
optimisation.

:class:`OracleTeacher` computes, for a batch of envs, the action ``CommandedOracle`` would take (the run-up
tasks' plan: the damping command ``D_opt / g`` from the first step, the speed at the motor limit toward
``min(Lambda_cmd, (1 - margin) lambda_best)``, dead-beat): per episode it reads through the privileged
channel of each env (``env_method`` of the vector env: ``best_stable_operating_point``, the episode's
bearing, its motor limit and clock), at every step only the observed speed.  Its labels are exactly
``CommandedOracle``'s actions (tests/agents/test_oracle_teacher.py).  WhirlRecovery's oracle reads the
true whirl amplitude at every step; it is not covered (one clear line).

**The probe** (``oracle_probe`` of ``teacher_student.yml``, optional): the oracle never probes, because it
does not need to; a student that imitates it cannot learn to gather what it lacks (the imitation gap:
docs/agents.md).  With a probe ``((D_1, n_1), (D_2, n_2), ...)`` the teacher first holds the start speed
(speed action 0) and commands the damping ``D_j`` for ``n_j`` control steps each, in order, as the rules'
probe does (``margin_search``: the 1x vector versus damping), and only then follows the oracle's plan: an
expert whose actions are a function of the step index and the hidden plant, so DAgger can still query it
in any state, and whose first steps show the student what tells g.  The student needs a history that
spans the probe (``history`` >= its steps).

The student's observation statistics: the oracle has none (it never normalised anything); the distillation
takes the mean and variance of the observations of its first iteration (played by the teacher alone,
``beta_0 = 1``) and freezes them (``vecnormalize.pkl``, as the student of a learned teacher does with the
teacher's).  Friction-regime changes of ``g`` are not covered either: the v2 tasks have none.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from gfb_agents.oracles.commanded import ORACLE_MARGIN

__all__ = ["ORACLE_TEACHER", "OracleTeacher", "check_probe", "observation_statistics", "save_statistics"]

#: the ``--teacher`` value that names the oracle (not a training run's folder)
ORACLE_TEACHER = "oracle"


class OracleTeacher:
    """``CommandedOracle``'s actions for a batch of ``n_envs`` envs of ``env_id`` (module docstring).

    ``plan_episodes(venv, indices)`` after a reset of those envs (the distillation calls it whenever an
    episode starts); ``act(obs, privileged, starts)`` as :class:`~gfb_agents.learned.teacher_student.
    TeacherPolicy` (``privileged`` is not read: the plan holds what the oracle knows)."""

    kind = "oracle"
    frame_stack = 1

    def __init__(
        self,
        env_id: str,
        n_envs: int,
        damping_slew: float | None = None,
        damping_slew_reserve: float | None = None,
        margin: float | None = None,
        probe: Sequence[Sequence[float]] = (),
    ):
        from gfb_agents.learned.slew import check_damping_slew, check_damping_slew_reserve

        if isinstance(n_envs, bool) or not isinstance(n_envs, int) or n_envs < 1:
            raise ValueError(f"n_envs must be a positive integer, got {n_envs!r}")
        self.env_id, self.n_envs = str(env_id), int(n_envs)
        self.margin = float(ORACLE_MARGIN.get(self.env_id, 0.01) if margin is None else margin)
        if not 0.0 <= self.margin < 0.5:
            raise ValueError(f"margin must lie in [0, 0.5), got {margin!r}")
        self.damping_slew = check_damping_slew(damping_slew)
        self.damping_slew_reserve = check_damping_slew_reserve(damping_slew_reserve, self.damping_slew)
        self.stats: dict[str, tuple[np.ndarray, np.ndarray]] | None = None
        self.eps, self.clip = 1e-8, 10.0
        # per env: the setpoint (Lambda), the damping action, Lambda per observed rpm, Lambda per step at
        # the motor limit; NaN until planned
        self.plan = np.full((self.n_envs, 4), np.nan)
        self._layout = None
        self.probe = check_probe(probe)
        self.probe_steps = int(sum(n for _, n in self.probe))
        self._probe_actions: np.ndarray | None = None  # (probe_steps,) damping actions, per step
        self.k = np.zeros(self.n_envs, dtype=int)  # each env's control steps in its episode so far

    # -- the plan -------------------------------------------------------------------------------------
    def plan_episodes(self, venv: Any, indices: Sequence[int] | np.ndarray) -> None:
        """Read each listed env's episode through the privileged channel (``CommandedOracle._plan``)."""
        for i in np.asarray(indices, dtype=int).reshape(-1):
            i = int(i)
            (best,) = venv.env_method("best_stable_operating_point", indices=[i])
            (cmd,) = venv.get_attr("speed_command", indices=[i])
            (bearing,) = venv.get_attr("bearing", indices=[i])
            (rate,) = venv.env_method("max_rate", bearing, indices=[i])
            (step_tau,) = venv.get_attr("step_tau", indices=[i])
            (d_action,) = venv.env_method("action_from_damping", best.commanded_damping, indices=[i])
            if self._layout is None:
                try:  # WhirlRecovery's envs have a whirl start (CommandedOracle.whirl_start)
                    venv.get_attr("whirl_bearing_number", indices=[i])
                except AttributeError:
                    pass
                else:
                    raise ValueError(
                        f"the oracle teacher covers the run-up tasks; {self.env_id} starts in the whirl "
                        "(its oracle reads the true whirl amplitude at every step)"
                    )
                (self._layout,) = venv.get_attr("observation_layout", indices=[i])
            setpoint = min(cmd.bearing_number, (1.0 - self.margin) * best.bearing_number)
            self.plan[i] = (setpoint, d_action, bearing.bearing_number_at(1.0), rate * step_tau)
            self.k[i] = 0
            if self._probe_actions is None:
                acts = [venv.env_method("action_from_damping", d, indices=[i])[0] for d, _ in self.probe]
                self._probe_actions = np.repeat(np.asarray(acts, dtype=float), [n for _, n in self.probe])

    def act(self, obs: np.ndarray, privileged: np.ndarray | None, starts: np.ndarray) -> np.ndarray:
        """``(n, 2)`` actions for raw observations ``(n, n_obs)``: ``CommandedOracle._act`` per env."""
        if self._layout is None or np.isnan(self.plan).any():
            raise RuntimeError("OracleTeacher.act before plan_episodes of every env")
        obs = np.asarray(obs, dtype=np.float64)
        out = np.empty((obs.shape[0], 2), dtype=np.float32)
        for i in range(obs.shape[0]):
            setpoint, d_action, lam_per_rpm, step = self.plan[i]
            if self.k[i] < self.probe_steps:  # the probe: hold the speed, the probe's damping
                out[i] = (0.0, self._probe_actions[self.k[i]])
            else:
                lam = lam_per_rpm * self._layout.speed_rpm(obs[i])
                out[i, 0] = float(np.clip((setpoint - lam) / step, -1.0, 1.0))
                out[i, 1] = d_action
            self.k[i] += 1
        return out

    def reset(self) -> None:
        self.plan[:] = np.nan

    # -- the student's observation statistics ---------------------------------------------------------
    def set_statistics(self, key: str, mean: np.ndarray, var: np.ndarray) -> None:
        self.stats = {key: (np.asarray(mean, np.float64), np.asarray(var, np.float64))}

    def normalise(self, key: str, x: np.ndarray) -> np.ndarray:
        from gfb_agents.learned.teacher_student import _normalise

        if self.stats is None:
            raise RuntimeError("OracleTeacher.normalise before the observation statistics are set")
        return _normalise(x, *self.stats[key], self.eps, self.clip)


def check_probe(probe: Sequence[Sequence[float]]) -> tuple[tuple[float, int], ...]:
    """The probe as ``((D_W command, steps), ...)``; ValueError (naming ``oracle_probe``) unless every
    entry is a positive finite damping with a positive whole number of steps."""
    out = []
    for entry in probe or ():
        try:
            d, n = entry
        except (TypeError, ValueError):
            raise ValueError(f"oracle_probe entries must be [damping, steps] pairs, got {entry!r}") from None
        if isinstance(d, bool) or not isinstance(d, (int, float)) or not 0 < float(d) < float("inf"):
            raise ValueError(f"oracle_probe damping must be a positive number, got {d!r}")
        if isinstance(n, float) and n.is_integer():
            n = int(n)
        if isinstance(n, bool) or not isinstance(n, int) or n < 1:
            raise ValueError(f"oracle_probe steps must be a positive integer, got {n!r}")
        out.append((float(d), int(n)))
    return tuple(out)


def observation_statistics(raw: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Mean and variance over the rows of ``raw`` (``(m, n_obs)``): the frozen statistics."""
    raw = np.asarray(raw, dtype=np.float64)
    if raw.ndim != 2 or raw.shape[0] < 2:
        raise ValueError(f"observation statistics need at least two observations, got shape {raw.shape}")
    return raw.mean(axis=0), raw.var(axis=0)


def save_statistics(path, venv, mean: np.ndarray, var: np.ndarray) -> None:
    """``path`` (``vecnormalize.pkl``): an SB3 ``VecNormalize`` over ``venv`` holding ``mean`` / ``var``
    as its observation statistics (no reward normalisation), read back by
    :class:`~gfb_agents.learned.evaluate.LearnedPolicy` like any training run's."""
    import pickle

    from stable_baselines3.common.vec_env import VecNormalize

    vn = VecNormalize(venv, training=False, norm_obs=True, norm_reward=False)
    vn.obs_rms.mean = np.asarray(mean, np.float64).copy()
    vn.obs_rms.var = np.asarray(var, np.float64).copy()
    with open(path, "wb") as fh:
        pickle.dump(vn, fh)
