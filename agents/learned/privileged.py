"""The privileged vector of an episode, for learning methods that use what the simulator knows at training
time only (issue 21): the asymmetric actor-critic's critic and the teacher of the teacher-student scheme.

The vector is built from the env's privileged channel (:mod:`gfb_env.envs.privileged`):
``env.unwrapped.hidden_parameters()`` (every hidden draw of the episode) and, optionally, the true
quantities of ``info["privileged"]`` (the env made with ``privileged_info=True``).  It is never part of what
a deployed policy receives: the deployed actor (:class:`gfb_agents.learned.asymmetric.DeployedActor`) takes
the public observation only.

Entries, in this fixed order (:data:`EPISODE_FIELDS`; a group the task does not draw -- the bearing on a
task with the nominal bearing, the unbalance of a balanced rotor -- gives zeros and its ``*_drawn`` flag 0,
so one layout serves every task id):

=========================  ======================================================================
``ln_damping_gain``        ln g, the damping effectiveness (actual D_W = g x commanded)
``bearing_drawn``          1 where the task draws the bearing, else 0 (and the four below are 0)
``clearance_um``           the drawn radial clearance C, um
``stiffness_factor``       the drawn foil stiffness factor f_K
``load_n``                 the drawn static load per bearing F_L, N
``foil_stiffness``         the resulting nondimensional K_W
``unbalance_drawn``        1 where the rotor has a residual unbalance, else 0
``balance_grade_mm_s``     its ISO 1940 grade G, mm/s
``unbalance_um``           its magnitude U, um
``unbalance_cos_phase``    cos of its phase (the angle as a point on the circle: no jump at 2 pi)
``unbalance_sin_phase``    sin of its phase
``probe_bias_x_um``        the X probe's offset of the episode, um
``probe_bias_y_um``        the Y probe's offset of the episode, um
=========================  ======================================================================

The SB3 wrapper that puts the vector beside the observation in training is
:class:`gfb_agents.learned.vec_env.PrivilegedVecEnv` (this module needs no SB3 nor torch).

These are drawn at reset and fixed for the episode, so the vector of an ended episode (for the value of
its last observation) is the one cached at its reset.  Left out: the base shocks (drawn step by step; not
known ahead even to the oracle), the sensor noise of each observation (white: nothing to learn), the task's
start draws (they act only through the first observations).

Optional step-varying entries (:data:`STEP_QUANTITIES`, names of ``info["privileged"]``, appended in the
order given; they need ``privileged_info=True``): the true noise-free journal state ``xi``, ``eta``,
``xi_dot``, ``eta_dot`` (units of C, C / T), ``eccentricity``, the judge's ``whirl_amplitude`` and
``min_film_thickness`` (units of C), the actual ``bearing_number`` Lambda and ``foil_damping`` D_W.  An
ended episode's entries are those of its last step's info.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

__all__ = [
    "EPISODE_FIELDS",
    "STEP_QUANTITIES",
    "OBS_KEY",
    "PRIVILEGED_KEY",
    "episode_vector",
    "privileged_names",
    "check_quantities",
]

EPISODE_FIELDS: tuple[str, ...] = (
    "ln_damping_gain",
    "bearing_drawn",
    "clearance_um",
    "stiffness_factor",
    "load_n",
    "foil_stiffness",
    "unbalance_drawn",
    "balance_grade_mm_s",
    "unbalance_um",
    "unbalance_cos_phase",
    "unbalance_sin_phase",
    "probe_bias_x_um",
    "probe_bias_y_um",
)
STEP_QUANTITIES: tuple[str, ...] = (
    "xi",
    "eta",
    "xi_dot",
    "eta_dot",
    "eccentricity",
    "whirl_amplitude",
    "min_film_thickness",
    "bearing_number",
    "foil_damping",
)
#: the keys of the training observation (a ``gymnasium.spaces.Dict``)
OBS_KEY, PRIVILEGED_KEY = "obs", "privileged"


def check_quantities(quantities: Sequence[str]) -> tuple[str, ...]:
    """``quantities`` as a tuple, each one of :data:`STEP_QUANTITIES` and none twice (ValueError)."""
    q = tuple(quantities)
    bad = [x for x in q if x not in STEP_QUANTITIES]
    if bad:
        raise ValueError(f"privileged quantities {bad} unknown; known: {list(STEP_QUANTITIES)}")
    if len(set(q)) != len(q):
        raise ValueError(f"privileged quantities {list(q)} name one twice")
    return q


def privileged_names(quantities: Sequence[str] = ()) -> tuple[str, ...]:
    """The names of the vector's entries, in order: :data:`EPISODE_FIELDS` then ``quantities``."""
    return EPISODE_FIELDS + check_quantities(quantities)


def episode_vector(hidden: Mapping[str, Any]) -> np.ndarray:
    """The :data:`EPISODE_FIELDS` entries (float32) of one episode's ``hidden_parameters()`` dict."""
    g = float(hidden["damping_gain"])
    if not g > 0:
        raise ValueError(f"damping_gain must be positive, got {g!r}")
    b, u = hidden.get("bearing"), hidden.get("unbalance")
    bias = (hidden.get("sensors") or {}).get("probe_bias_um") or (0.0, 0.0)
    if len(bias) != 2:
        raise ValueError(f"sensors.probe_bias_um must hold the (X, Y) offsets, got {bias!r}")
    v = [math.log(g)]
    v += (
        [0.0] * 5
        if b is None
        else [1.0, b["clearance_um"], b["stiffness_factor"], b["load_n"], b["foil_stiffness"]]
    )
    if u is None:
        v += [0.0] * 5
    else:
        ph = float(u["phase_rad"])
        v += [1.0, u["balance_grade_mm_s"], u["magnitude_um"], math.cos(ph), math.sin(ph)]
    v += [float(bias[0]), float(bias[1])]
    return np.asarray(v, dtype=np.float32)
