"""Gymnasium environments of the gas foil bearing rotor (see ``docs/envs.md``).

Importing this package registers (idempotently):

* ``gfb_env/RunUp-v2`` (:class:`~gfb_env.envs.run_up.RunUpEnv`, ``max_episode_steps=250``),
  ``gfb_env/RunUpRandomized-v2`` (:class:`~gfb_env.envs.run_up_randomized.RunUpRandomizedEnv`, 250),
  ``gfb_env/WhirlRecovery-v2`` (:class:`~gfb_env.envs.whirl_recovery.WhirlRecoveryEnv`, 200)
  (:data:`ENV_IDS`, the current tasks; :data:`V2_ENV_IDS` is the same tuple): the commanded-speed tasks
  (:data:`V1_TASK`, :mod:`gfb_env.envs.commanded`: an observed speed command, a fixed horizon, a stability
  certificate at the end, costs) on the instrumented machine (:data:`MACHINE_V1`: actuator lag and rate limit,
  noisy biased probes and taps, random base shocks instead of the velocity kick, a residual unbalance;
  ``docs/machine.md``) with a hidden damping effectiveness (:data:`V1_DAMPING_GAIN_RANGE`), behind the v2
  information interface (:data:`INTERFACE_V2`, :mod:`gfb_env.envs.interface_v2`: the vibration monitor's
  observation, the reward and costs from the measurements, an info with no ground truth, the certificate that
  forgives a shock's ring-down).
* the retired ``gfb_env/RunUp-v1``, ``gfb_env/RunUpRandomized-v1``, ``gfb_env/WhirlRecovery-v1``
  (:data:`RETIRED_V1_IDS`: the same tasks with the v1 interface, whose info and reward leak the hidden plant;
  issue 19) and ``gfb_env/RunUp-v0``, ``gfb_env/RunUpRandomized-v0``, ``gfb_env/WhirlRecovery-v0``: making one
  raises :class:`~gfb_env.envs.retired.RetiredTaskError` (why, and the -v2 id to use).  A v1 env is built for
  the record only (not a benchmark) with :func:`~gfb_env.envs.retired.make_retired`.

Every id has a native vector env (:class:`~gfb_env.envs.vector.GFBVectorEnv`, registered as its
``vector_entry_point``): ``gymnasium.make_vec(id, num_envs=N)`` returns it, bit for bit the same as
``vectorization_mode="sync"``.
"""

from __future__ import annotations

from gymnasium.envs.registration import register, registry

from gfb_env.envs._data import NOMINAL_BEARING
from gfb_env.envs.base import DEFAULT_GRID, GFBEnv, PlantResult, StepPlan, advance_plans
from gfb_env.envs.commanded import CommandedObjective
from gfb_env.envs.interface_v2 import MonitorInterface
from gfb_env.envs.retired import (
    RETIRED_IDS,
    RETIRED_V1_IDS,
    RetiredEntryPoint,
    RetiredTaskError,
    make_env,
    make_retired,
    make_retired_vec,
)
from gfb_env.envs.run_up import RunUpEnv
from gfb_env.envs.run_up_randomized import RunUpRandomizedEnv
from gfb_env.envs.vector import GFBVectorEnv
from gfb_env.envs.whirl_recovery import WhirlRecoveryEnv
from gfb_env.integrator import BENCHMARK_INTEGRATOR_OPTIONS
from gfb_env.machine import (
    FoilDampingActuator,
    PressureTaps,
    ProximityProbes,
    RotorBalance,
    ShockArrivals,
)

__all__ = [
    "GFBEnv",
    "RunUpEnv",
    "RunUpRandomizedEnv",
    "WhirlRecoveryEnv",
    "GFBVectorEnv",
    "StepPlan",
    "PlantResult",
    "advance_plans",
    "CommandedObjective",
    "DEFAULT_GRID",
    "NOMINAL_BEARING",
    "ENV_IDS",
    "V2_ENV_IDS",
    "FAST_PLANT_V2",
    "PLAIN_PLANT",
    "INTERFACE_V2",
    "MonitorInterface",
    "RETIRED_IDS",
    "RETIRED_V1_IDS",
    "RetiredTaskError",
    "make_retired",
    "make_retired_vec",
    "make_env",
    "MACHINE_V1",
    "V1_TASK",
    "V1_DAMPING_GAIN_RANGE",
    "V1_WHIRL_RECOVERY_GAIN_RANGE",
    "V1_SHOCK_PEAK_G_RANGE",
]

#: The instrumented machine of the v1 tasks (defaults and their reasons in ``docs/machine.md``).
MACHINE_V1: dict = {
    "damping_actuator": FoilDampingActuator(),
    "proximity_probes": ProximityProbes(),
    "pressure_taps": PressureTaps(),
    "shock_arrivals": ShockArrivals(),
    "rotor_balance": RotorBalance(),
    "disturbance_probability": 0.0,  # physical shocks replace the legacy velocity kick
}

#: The hidden damping effectiveness of every v1 task: actual D_W = g x commanded, g log-uniform in
#: [10^-0.5, 10^0.5] = [0.316, 3.16] (paper Eq. 15: D_W is known only to an order of magnitude).
#: The nominal optimum D_opt = 2.26 needs the command D_opt / g in [0.71, 7.1], inside [0.1, 10].
V1_DAMPING_GAIN_RANGE = (10.0**-0.5, 10.0**0.5)

#: WhirlRecovery-v1's hidden gain: the machine is found whirling steadily at Lambda_w with the nominal
#: D_opt = 2.24 commanded, which only a plant with g in about [0.55, 2.1] survives: with the start command
#: the whirl touched down within 1-3 control steps for g <= 0.52 and g >= 2.27 and never for 0.61 <= g <=
#: 1.93 (15 gains x 4 seeds, issue 11), and at g = 0.316 or 3.16 even the oracle's damping came too late.
#: A draw outside would start a machine that cannot exist (and an episode no policy can save without
#: knowing g before its first action), so g is log-uniform in [0.6, 1.8] here (a factor of 3).
V1_WHIRL_RECOVERY_GAIN_RANGE = (0.6, 1.8)

#: The base shocks of the v1 tasks: in-service transients, peak 2-8 g (log-uniform; rate and pulse
#: length as the machine's default, docs/machine.md).  A hard landing or a pothole gives a few g up to
#: ~8 g at the mount; the machine's default top of 20 g is the MIL-STD-810 Method 516 functional-test
#: (qualification) level.  With 2-20 g, 6-8 of 50 episodes per task of the oracle touched down whatever
#: its margin (9-16 g shocks, one at Lambda = 0.53, far below the boundary): the score would be a
#: lottery of the shock draw, not of the policy (docs/envs.md).
V1_SHOCK_PEAK_G_RANGE = (2.0, 8.0)

#: The keyword arguments of the v1 ids: the instrumented machine with the hidden damping gain and the
#: commanded-speed objective (:mod:`gfb_env.envs.commanded`; horizons 250 / 250 / 200 control steps).
V1_TASK: dict = {
    **MACHINE_V1,
    "damping_actuator": FoilDampingActuator(gain_range=V1_DAMPING_GAIN_RANGE),
    "shock_arrivals": ShockArrivals(peak_g_range=V1_SHOCK_PEAK_G_RANGE),
}

#: The v2 interface (issue 19): the vibration monitor's observation, the reward and costs from the
#: measurements, the sensor-only info, the certificate that forgives a shock's ring-down
#: (:mod:`gfb_env.envs.interface_v2`); the same machine, tasks and horizons as v1.
INTERFACE_V2 = MonitorInterface()

#: The plant of the v2 ids (issue 20): the synchronous unbalance response superposed analytically where
#: the plant is linear (:mod:`gfb_env.envs.synchronous_plant`; stepped in the whirl, next to Lambda_c, in
#: a shock) and the step limit lifted at a settled operating point
#: (:data:`~gfb_env.integrator.BENCHMARK_INTEGRATOR_OPTIONS`).  Near equilibrium a control step takes ~6
#: integrator steps instead of 138; accuracy against the tight reference in ``results/plant_accuracy/``.
#: ``gym.make(id, **PLAIN_PLANT)`` gives the plain plant (v1's, for comparisons and references).
FAST_PLANT_V2: dict = {
    "synchronous_response": "superposed",
    "integrator_options": BENCHMARK_INTEGRATOR_OPTIONS,
}
#: The plain plant: the unbalance forcing stepped at every step, the integrator's default options.
PLAIN_PLANT: dict = {"synchronous_response": "stepped", "integrator_options": {}}

_WHIRL_RECOVERY_V1 = {
    **V1_TASK,
    "damping_actuator": FoilDampingActuator(gain_range=V1_WHIRL_RECOVERY_GAIN_RANGE),
}

#: the retired v1 ids -> (entry point, max_episode_steps, default keyword arguments): not registered (the
#: ids refuse), built for the record only by :func:`~gfb_env.envs.retired.make_retired`
_V1_SPECS = {
    "gfb_env/RunUp-v1": ("gfb_env.envs.run_up:RunUpEnv", 250, V1_TASK),
    "gfb_env/RunUpRandomized-v1": ("gfb_env.envs.run_up_randomized:RunUpRandomizedEnv", 250, V1_TASK),
    "gfb_env/WhirlRecovery-v1": ("gfb_env.envs.whirl_recovery:WhirlRecoveryEnv", 200, _WHIRL_RECOVERY_V1),
}
#: the registered task ids -> (entry point, max_episode_steps, default keyword arguments): v1's tasks with
#: the v2 interface
_V2_SPECS = {
    "gfb_env/RunUp-v2": (
        "gfb_env.envs.run_up:RunUpEnv",
        250,
        {**V1_TASK, **FAST_PLANT_V2, "interface": INTERFACE_V2},
    ),
    "gfb_env/RunUpRandomized-v2": (
        "gfb_env.envs.run_up_randomized:RunUpRandomizedEnv",
        250,
        {**V1_TASK, **FAST_PLANT_V2, "interface": INTERFACE_V2},
    ),
    "gfb_env/WhirlRecovery-v2": (
        "gfb_env.envs.whirl_recovery:WhirlRecoveryEnv",
        200,
        {**_WHIRL_RECOVERY_V1, **FAST_PLANT_V2, "interface": INTERFACE_V2},
    ),
}
#: the native vector env of each task (``gymnasium.make_vec(id, num_envs=N)``; :mod:`gfb_env.envs.vector`)
_VECTOR_ENTRY_POINTS = {
    "gfb_env.envs.run_up:RunUpEnv": "gfb_env.envs.vector:RunUpVectorEnv",
    "gfb_env.envs.run_up_randomized:RunUpRandomizedEnv": "gfb_env.envs.vector:RunUpRandomizedVectorEnv",
    "gfb_env.envs.whirl_recovery:WhirlRecoveryEnv": "gfb_env.envs.vector:WhirlRecoveryVectorEnv",
}
#: the v2 tasks (issue 19: the information contract, :mod:`gfb_env.envs.interface_v2`)
V2_ENV_IDS = tuple(_V2_SPECS)
#: the current tasks, the ids to use: the v2 ids (the v0 and v1 ids are retired: :mod:`gfb_env.envs.retired`)
ENV_IDS = V2_ENV_IDS


def register_envs() -> None:
    """Register the tasks with Gymnasium, and the retired ids as refusals (no-op for ids already
    registered)."""
    for env_id, (entry_point, steps, kwargs) in _V2_SPECS.items():
        if env_id not in registry:
            register(
                id=env_id,
                entry_point=entry_point,
                vector_entry_point=_VECTOR_ENTRY_POINTS[entry_point],
                max_episode_steps=steps,
                kwargs=dict(kwargs),
            )
    for env_id in RETIRED_IDS:
        if env_id not in registry:
            retired = RetiredEntryPoint(env_id)
            register(id=env_id, entry_point=retired, vector_entry_point=retired)


register_envs()
