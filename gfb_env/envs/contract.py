"""The information contract of the tasks (issue 19, ``docs/envs.md`` "Information contract"): the documented
classification of every ``info`` key, per task id (the current v2 ids and, for the record, the retired v1
ids), and the checks of it.

Every key a task's ``info`` may hold is in one class (:class:`InfoClass`):

* ``SENSOR``: a function of the sensor stream (the noisy, biased measurements of ``docs/machine.md``),
  the actions and the public configuration, e.g. the probe readings, the motor speed, the step count;
* ``PUBLIC``: the task's public configuration (a constant of the registered id);
* ``GROUND_TRUTH``: a hidden draw, the true (noise-free) state or a quantity of the judge computed from
  the true plant (whirl amplitude, film thickness, the certificate, the reward's terms, the costs);
* ``PRIVILEGED``: the opt-in channel itself (``info["privileged"]``, only with ``privileged_info=True``);
* ``VERDICT``: the judge's verdict on the true plant, in the **final step's** info only (v2:
  ``certified``, ``is_success``, ``termination_reason``).  It is ground truth, but it leaks nothing a
  policy can use: the episode is over when it is revealed (as any task's success signal is), and the
  next episode draws a new plant.  The v2 reward's terminal terms pay on it, so it must be given for
  the reward to be recomputed (:func:`~gfb_env.envs.monitor_reward.recompute_rewards`).

The v1 ids leak: their ``info`` holds GROUND_TRUTH keys at every reset and step, which is why they are
retired (:mod:`gfb_env.envs.retired`; their envs, built for the record by ``make_retired``, keep it bit for
bit for the published v1 results; :func:`leaked_ground_truth` lists the keys).  The v2 ids hold none
(tested).
A key that is in no class fails :func:`unclassified_keys` (a test walks whole episodes of every
id), so a new key must be classified here before it ships.

Where a key's class depends on the task it says so: on RunUpRandomized-v1 the clearance is drawn, so
every quantity scaled by the drawn bearing (Lambda ~ rpm C^-2, the time in s ~ tau C^2) tells it.
"""

from __future__ import annotations

import enum
import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from types import MappingProxyType
from typing import Any

from gfb_env.envs.privileged import flatten_numbers

__all__ = [
    "InfoClass",
    "InfoEntry",
    "INFO_CONTRACT",
    "classify",
    "unclassified_keys",
    "leaked_ground_truth",
    "hidden_value_matches",
]


class InfoClass(enum.StrEnum):
    """The class of an ``info`` key (module docstring)."""

    SENSOR = "sensor"
    PUBLIC = "public"
    GROUND_TRUTH = "ground_truth"
    PRIVILEGED = "privileged"
    VERDICT = "verdict"


@dataclass(frozen=True)
class InfoEntry:
    """One ``info`` key's class and why."""

    cls: InfoClass
    why: str


S, P, G = InfoClass.SENSOR, InfoClass.PUBLIC, InfoClass.GROUND_TRUTH

#: the keys every v1 task has (base env, reward terms, objective, costs), on the nominal bearing
_V1_COMMON: dict[str, InfoEntry] = {
    # the clock and the counts
    "step": InfoEntry(S, "control steps taken (the count of actions)"),
    "tau": InfoEntry(S, "control_interval x steps; shorter only in a step that touched down (observable)"),
    "time_s": InfoEntry(S, "tau x T_nom on the nominal bearing (public scale)"),
    "integrator_steps": InfoEntry(G, "the simulator's accepted steps: grows with the true orbit's motion"),
    # the instruments
    "probe_x_um": InfoEntry(S, "the X probe reading (noisy, biased)"),
    "probe_y_um": InfoEntry(S, "the Y probe reading (noisy, biased)"),
    "speed_rpm": InfoEntry(S, "the motor speed (observation entry 6, exact)"),
    "bearing_number": InfoEntry(S, "Lambda = speed x const(nominal bearing): the measured speed, scaled"),
    # the actions
    "action_applied": InfoEntry(S, "the sanitised action"),
    "action_sanitised": InfoEntry(S, "whether the action was mended (a function of the action)"),
    # hidden draws
    "foil_damping": InfoEntry(G, "the actual D_W = g x indicated: tells the hidden gain g"),
    "damping_gain": InfoEntry(G, "the hidden damping effectiveness g itself"),
    "balance_grade_mm_s": InfoEntry(G, "the drawn balance grade"),
    "unbalance_um": InfoEntry(G, "the drawn unbalance amplitude"),
    "shocks": InfoEntry(G, "the number of base shocks drawn in the step (no accelerometer is observed)"),
    "shock_peak_g": InfoEntry(G, "the largest drawn shock peak of the step"),
    "disturbance": InfoEntry(G, "a legacy velocity kick was drawn in the step"),
    # the true state
    "xi_um": InfoEntry(G, "true (noise-free) journal position"),
    "eta_um": InfoEntry(G, "true (noise-free) journal position"),
    "xi_dot_m_s": InfoEntry(G, "true journal velocity"),
    "eta_dot_m_s": InfoEntry(G, "true journal velocity"),
    "eccentricity": InfoEntry(G, "true eccentricity"),
    "eccentricity_um": InfoEntry(G, "true eccentricity"),
    "bearing_force_n": InfoEntry(G, "the true film force"),
    # the judge's true quantities
    "min_film_thickness": InfoEntry(G, "the judge's true min film thickness"),
    "min_film_thickness_um": InfoEntry(G, "the judge's true min film thickness"),
    "whirl_amplitude": InfoEntry(G, "the judge's true whirl amplitude"),
    "whirl_amplitude_um": InfoEntry(G, "the judge's true whirl amplitude"),
    "termination_reason": InfoEntry(G, "success vs horizon is the certificate's verdict on the true plant"),
    "is_success": InfoEntry(G, "the certificate and lambda_best of the true plant"),
    "certified": InfoEntry(G, "the certificate: true whirl amplitudes and the true plant's eigenvalues"),
    "certification": InfoEntry(G, "the certificate's reason"),
    "growth_rate": InfoEntry(G, "the true plant's leading eigenvalue at the horizon"),
    "reward_speed": InfoEntry(G, "0.1 p while calm: calm is the true whirl amplitude below 0.05 C"),
    "reward_whirl": InfoEntry(G, "-0.5 A, A the true whirl amplitude"),
    "reward_certified_speed": InfoEntry(G, "paid on the true plant's certificate"),
    "reward_on_target": InfoEntry(G, "paid on success (the true plant's lambda_best)"),
    "reward_touchdown": InfoEntry(S, "-100 on touchdown, an observable event (the episode ends early)"),
    "cost": InfoEntry(G, "the max of the cost terms (whirl and film from the true plant)"),
    "cost_whirl": InfoEntry(G, "the true whirl amplitude above 0.15 C"),
    "cost_film": InfoEntry(G, "the true min film below 0.1 C"),
    "cost_touchdown": InfoEntry(S, "touchdown or solver failure: observable (the episode ends early)"),
    "episode_cost": InfoEntry(G, "the sum of the costs"),
    # the objective's public entries
    "speed_command_rpm": InfoEntry(S, "the command, observed (observation entry -2)"),
    "speed_command_bearing_number": InfoEntry(S, "the command as Lambda of the nominal bearing"),
    "reference_bearing_number": InfoEntry(P, "Lambda_ref of the nominal bearing: a task constant"),
    "episode_steps": InfoEntry(P, "the horizon"),
    "steps_left": InfoEntry(S, "episode_steps - step (observation entry -1)"),
    "speed_progress": InfoEntry(S, "p = (n - n_ref) / (n_cmd - n_ref): the measured speeds"),
    "hold_steps": InfoEntry(P, "a constant 0, kept for the info's stability"),
    "privileged": InfoEntry(InfoClass.PRIVILEGED, "the opt-in channel (privileged_info=True only)"),
}

_RUN_UP_V1 = {
    **_V1_COMMON,
    "start_bearing_number": InfoEntry(P, "Lambda_0 of the nominal bearing at the start speed"),
}

#: RunUpRandomized-v1: the drawn bearing, and every quantity the drawn clearance scales
_RUN_UP_RANDOMIZED_V1 = {
    **_V1_COMMON,
    "clearance_um": InfoEntry(G, "the drawn clearance C"),
    "stiffness_factor": InfoEntry(G, "the drawn foil stiffness factor f_K"),
    "foil_stiffness": InfoEntry(G, "K_W = f_K K_W,WA(C) of the drawn bearing"),
    "load_n": InfoEntry(G, "the drawn load F_L"),
    "bearing_number": InfoEntry(G, "Lambda = speed x const(C), const ~ C^-2: with speed_rpm, the clearance"),
    "time_s": InfoEntry(G, "tau x T(C), T ~ C^2: with tau, the clearance"),
    "start_bearing_number": InfoEntry(G, "Lambda_0 of the drawn bearing: the clearance"),
    "speed_command_bearing_number": InfoEntry(G, "Lambda_cmd of the drawn bearing: the clearance"),
    "reference_bearing_number": InfoEntry(G, "Lambda_0 of the drawn bearing: the clearance"),
}

_WHIRL_RECOVERY_V1 = {
    **_V1_COMMON,
    "whirl_bearing_number": InfoEntry(P, "Lambda_w, the start's speed: a task constant"),
    "whirl_speed_rpm": InfoEntry(P, "the start's speed in rpm: a task constant"),
}

V = InfoClass.VERDICT

#: the keys of every v2 task (:mod:`gfb_env.envs.interface_v2`): no GROUND_TRUTH key
_V2: dict[str, InfoEntry] = {
    "step": InfoEntry(S, "control steps taken (the count of actions)"),
    "steps_left": InfoEntry(S, "episode_steps - step (observation entry -1)"),
    "episode_steps": InfoEntry(P, "the horizon"),
    "speed_rpm": InfoEntry(S, "the motor speed (observation entry 6)"),
    "speed_command_rpm": InfoEntry(S, "the command, observed (observation entry -2)"),
    "reference_speed_rpm": InfoEntry(P, "n_ref of the reward's speed progress: a task constant in rpm"),
    "damping_indicated": InfoEntry(S, "the actuator's indicated D_W (observation entry 7, decoded)"),
    "probe_x_um": InfoEntry(S, "the X probe's last reading (noisy, biased)"),
    "probe_y_um": InfoEntry(S, "the Y probe's last reading (noisy, biased)"),
    "action_applied": InfoEntry(S, "the sanitised action"),
    "action_sanitised": InfoEntry(S, "whether the action was mended (a function of the action)"),
    "touchdown": InfoEntry(S, "a rub is audible and the episode ends: an event the machine reports"),
    "monitor_alarm": InfoEntry(S, "the monitor's direct pk-pk above the alarm level (the observation's)"),
    "monitor": InfoEntry(S, "the vibration monitor's reading of the measured samples, um and degrees"),
    "reward_speed": InfoEntry(S, "0.1 p while A_meas <= 0.05 C_nom: the observation's entries"),
    "reward_whirl": InfoEntry(S, "-0.5 min(A_meas, 1.5), A_meas from the observation's monitor entries"),
    "reward_certified_speed": InfoEntry(S, "final step: 50 x the window mean of the observed p if certified"),
    "reward_on_target": InfoEntry(S, "final step: 25 on success (the final verdict, revealed at the end)"),
    "reward_touchdown": InfoEntry(S, "-100 on touchdown / solver failure (the episode ends early)"),
    "cost": InfoEntry(S, "max of the cost terms (measured alarm, touchdown)"),
    "cost_alarm": InfoEntry(S, "the measured direct pk-pk of a probe above 0.30 C_nom"),
    "cost_touchdown": InfoEntry(S, "touchdown or solver failure: observable (the episode ends early)"),
    "episode_cost": InfoEntry(S, "the sum of the costs"),
    "certified": InfoEntry(V, "final step only: the certificate of the true plant (the episode is over)"),
    "is_success": InfoEntry(V, "final step only: certified and on target (the episode is over)"),
    "termination_reason": InfoEntry(V, "final step only: success / horizon / touchdown / solver_failure"),
    "probe_samples": InfoEntry(S, "raw_probe_samples=True only: the step's measured samples and key angles"),
    "privileged": InfoEntry(InfoClass.PRIVILEGED, "the opt-in channel (privileged_info=True only)"),
}

#: task id (the v2 ids; the retired v1 ids, for the record) -> {info key -> :class:`InfoEntry`} (read-only)
INFO_CONTRACT: Mapping[str, Mapping[str, InfoEntry]] = MappingProxyType(
    {
        "gfb_env/RunUp-v1": MappingProxyType(_RUN_UP_V1),
        "gfb_env/RunUpRandomized-v1": MappingProxyType(_RUN_UP_RANDOMIZED_V1),
        "gfb_env/WhirlRecovery-v1": MappingProxyType(_WHIRL_RECOVERY_V1),
        "gfb_env/RunUp-v2": MappingProxyType(_V2),
        "gfb_env/RunUpRandomized-v2": MappingProxyType(_V2),
        "gfb_env/WhirlRecovery-v2": MappingProxyType(_V2),
    }
)


def _contract(env_id: str) -> Mapping[str, InfoEntry]:
    try:
        return INFO_CONTRACT[env_id]
    except KeyError:
        raise ValueError(
            f"env_id: no information contract for {env_id!r} (known: {sorted(INFO_CONTRACT)})"
        ) from None


def classify(env_id: str, key: str) -> InfoClass:
    """The class of ``info[key]`` on ``env_id``; ``KeyError`` for a key that is not classified."""
    return _contract(env_id)[key].cls


def unclassified_keys(env_id: str, info: Mapping[str, Any]) -> list[str]:
    """The keys of ``info`` that the contract of ``env_id`` does not classify (must be empty)."""
    table = _contract(env_id)
    return sorted(k for k in info if k not in table)


def leaked_ground_truth(env_id: str) -> tuple[str, ...]:
    """The GROUND_TRUTH keys of ``env_id``'s info (what a v2 id must not have), sorted."""
    return tuple(sorted(k for k, e in _contract(env_id).items() if e.cls is InfoClass.GROUND_TRUTH))


def _is_draw(v: float) -> bool:
    """Whether a hidden value takes part in the equality check: finite and not a whole number (a count,
    a zero of a component that is not drawn: equal to any step count or flag by construction)."""
    return math.isfinite(v) and not float(v).is_integer()


def hidden_value_matches(
    info: Mapping[str, Any], hidden: Mapping[str, Any], keys: Iterable[str] | None = None
) -> dict[str, list[str]]:
    """``{info key: [hidden parameter paths]}`` where a number in ``info[key]`` (nested values
    flattened) equals, exactly as a float, a hidden parameter of ``hidden``
    (:meth:`~gfb_env.envs.base.GFBEnv.hidden_parameters`; whole numbers are not draws and are left
    out).  ``keys``: only these (default: every key but ``privileged``)."""
    by_value: dict[float, list[str]] = {}
    for path, v in flatten_numbers(hidden):
        if _is_draw(v):
            by_value.setdefault(v, []).append(path)
    out: dict[str, list[str]] = {}
    for key in info if keys is None else keys:
        if key == "privileged" or key not in info:
            continue
        hits = sorted({p for _, v in flatten_numbers(info[key]) for p in by_value.get(v, ())})
        if hits:
            out[key] = hits
    return out
