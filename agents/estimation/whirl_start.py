"""The likelihood of WhirlRecovery's reset observation over the hidden damping gain ``g``.

The task's documented start (``WhirlRecoveryEnv``'s class docstring, docs/envs.md): the stored limit-cycle
state at ``D_W = d_opt`` (``constants["whirl"]``, from ``data/task_constants.json``), advanced by a phase
uniform over one whirl period at ``Lambda_w`` under the actual damping ``g d_opt``.  The further ``g`` lies
from 1, the further the advanced state leaves the stored cycle, so the first observation (one position,
a 5-sample velocity and the midplane pressures, with the documented probe and tap errors of
docs/machine.md) tells ``g``: issue 19's audit found an rms error of about 0.2 in ``ln g`` against the
prior's 0.32.

:class:`WhirlStartTable` holds the noise-free observation of every (gain, phase) of a grid, computed once
from the public construction (one integration over one whirl period per gain: ~0.1 s for 41 gains, cached
per process); :class:`ResetSensorModel` the Gaussian error of those entries from the public sensor
configuration (probe bias and noise, the velocity estimator's window, tap bias and noise, the
observation noise); :func:`reset_log_likelihood` marginalises the phase (uniform) and returns ``ln
p(obs_0 | g)`` on the table's gains.  Only public configuration and the observation enter: no hidden
draw, no ``info``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from gfb_env.envs.base import viscoelastic_model
from gfb_env.integrator import TrapezoidalIntegrator

__all__ = [
    "ROTOR_ENTRIES",
    "ResetSensorModel",
    "WhirlStartTable",
    "reset_log_likelihood",
    "whirl_start_table",
]

#: the rotor entries of the reset observation that carry the start state (by name: the observation's
#: layout may add entries elsewhere, as v2's vibration monitor does)
ROTOR_ENTRIES = ("xi", "eta", "xi_dot", "eta_dot")

#: phase resolution of the table (tau): the velocity moves ~0.12 C/T per tau along the start orbit, so
#: 1/64 tau moves it by ~0.002, half the velocity noise's sd (0.0038): the phase sum is then smooth
PHASE_STEP = 1.0 / 64.0


def _entry_names(n_pressure_probes: int) -> tuple[str, ...]:
    return (*ROTOR_ENTRIES, *(f"pressure_{k}" for k in range(n_pressure_probes)))


@dataclass(frozen=True)
class WhirlStartTable:
    """Noise-free reset observations of the documented start, per gain and phase.

    Attributes:
        gains: the gains ``g`` (log-spaced over the task's prior range).
        phases: the start phases (tau), uniform over ``[0, period]``.
        mean: ``(n_gain, n_phase, n_entry)`` noise-free values of :attr:`names` (observation units).
        names: the observation entries of the last axis.
    """

    gains: np.ndarray
    phases: np.ndarray
    mean: np.ndarray
    names: tuple[str, ...]

    def __post_init__(self) -> None:
        if self.mean.shape != (len(self.gains), len(self.phases), len(self.names)):
            raise ValueError(f"mean must have shape (gains, phases, names), got {self.mean.shape}")

    @classmethod
    def compute(cls, env, n_gain: int = 41, phase_step: float = PHASE_STEP) -> WhirlStartTable:
        """From a WhirlRecovery env's public construction: ``constants["whirl"]`` (the stored cycle),
        ``whirl_bearing_number``, ``whirl_damping`` (d_opt, commanded at the start), ``whirl_period``,
        the actuator's documented ``gain_range``, the grid, the nominal bearing and the integrator
        options of the configuration.  ``ValueError`` if the env has no such start or no gain range."""
        u = getattr(env, "unwrapped", env)
        for name in ("constants", "whirl_bearing_number", "whirl_damping", "whirl_period"):
            if not hasattr(u, name):
                raise ValueError(f"env has no {name!r}: not a WhirlRecovery task")
        gain_range = u.damping_actuator.gain_range
        if gain_range is None:
            raise ValueError("damping_actuator.gain_range is None: the task draws no gain")
        if int(n_gain) < 2 or not (phase_step > 0 and math.isfinite(phase_step)):
            raise ValueError(f"n_gain must be >= 2 and phase_step > 0, got {n_gain!r}, {phase_step!r}")
        state0 = np.asarray(u.constants["whirl"]["state"], dtype=float)
        lam, d0, period = float(u.whirl_bearing_number), float(u.whirl_damping), float(u.whirl_period)
        model = viscoelastic_model(u.grid, u.nominal_bearing)
        n_taps = int(u.n_pressure_probes)
        idx = model.layout.midplane_probe_indices(n_taps)
        gains = np.geomspace(*gain_range, int(n_gain))
        n_phase = int(math.ceil(period / phase_step)) + 1
        phases = np.linspace(0.0, period, n_phase)
        step = phases[1] - phases[0]
        names = _entry_names(n_taps)
        mean = np.empty((len(gains), n_phase, len(names)))
        xi, eta, xd, ed = model.layout.rotor(state0)
        first = np.r_[xi, eta, xd, ed, state0[idx]]
        for i, g in enumerate(gains):
            integ = TrapezoidalIntegrator(
                model, state0, lam, g * d0,
                touchdown_film_thickness=u.touchdown_film_thickness, options=u.config.integrator,
            )  # fmt: skip
            res = integ.advance(phases[-1] + 0.5 * step, record_interval=step, record_indices=idx)
            tr = res.trajectory
            rows = np.column_stack([tr.xi, tr.eta, tr.xi_dot, tr.eta_dot, tr.probes])
            # the record grid is anchored at tau = 0: phase 0 (the stored state) may or may not be in it
            if len(tr.tau) and abs(tr.tau[0]) < 1e-9:
                rows = rows[1:]
            if len(rows) < n_phase - 1:
                raise ValueError(f"the start at g = {g:.3g} ended early ({res.status}): no table")
            mean[i, 0] = first
            mean[i, 1:] = rows[: n_phase - 1]
        return cls(gains, phases, mean, names)


@dataclass(frozen=True)
class ResetSensorModel:
    """The Gaussian error of the reset observation's rotor and pressure entries (observation units),
    from the public sensor configuration (docs/machine.md).

    Per probe axis the position error is the episode's bias plus the last sample's noise; the velocity
    error the least-squares slope of the noise over the last ``velocity_window`` samples (which share that
    last sample: they correlate); the taps' error bias plus noise; all independent between probes and
    taps, rotated from the probes' (X, Y) frame to (xi, eta).

    Attributes: offset (the errors' mean), covariance (their covariance), names (the entries).
    """

    offset: np.ndarray
    covariance: np.ndarray
    names: tuple[str, ...]

    @classmethod
    def from_env(cls, env) -> ResetSensorModel:
        u = getattr(env, "unwrapped", env)
        nb = u.nominal_bearing
        c_um = nb.clearance_m * 1e6
        probes, taps = u.proximity_probes, u.pressure_taps
        n_taps = int(u.n_pressure_probes)
        names = _entry_names(n_taps)
        inv = np.linalg.inv(probes.directions)
        rot = inv @ inv.T  # an iid (X, Y) error's covariance in (xi, eta), per unit variance
        # the velocity estimator: slope over the last w samples, record_interval apart (tau)
        w = int(probes.velocity_window)
        t = (np.arange(w) - 0.5 * (w - 1)) * float(u.record_interval)
        tt = float(t @ t)
        s2, b2 = (probes.noise_um / c_um) ** 2, (probes.bias_spread_um / c_um) ** 2
        block = np.array([[b2 + s2, s2 * t[-1] / tt], [s2 * t[-1] / tt, s2 / tt]])  # (position, velocity)
        cov = np.zeros((len(names), len(names)))
        cov[:4, :4] = np.kron(block, rot)  # order xi, eta, xi_dot, eta_dot
        kpa = 1e3 / nb.ambient_pressure_pa
        cov[4:, 4:] = np.eye(n_taps) * (taps.noise_kpa**2 + taps.bias_spread_kpa**2) * kpa**2
        cov += np.eye(len(names)) * float(u.observation_noise) ** 2
        offset = np.zeros(len(names))
        offset[:2] = inv @ np.asarray(probes.bias_um, dtype=float) / c_um
        offset[4:] = taps.bias_kpa * kpa
        return cls(offset, cov, names)


_TABLES: dict = {}


def whirl_start_table(env) -> WhirlStartTable:
    """:meth:`WhirlStartTable.compute` of ``env``'s task, computed once per process per construction."""
    u = getattr(env, "unwrapped", env)
    w = u.constants["whirl"]
    key = (
        repr(u.grid), repr(u.nominal_bearing), repr(u.config.integrator), float(u.touchdown_film_thickness),
        float(u.whirl_bearing_number), float(u.whirl_damping), float(u.whirl_period),
        tuple(u.damping_actuator.gain_range), int(u.n_pressure_probes),
        np.asarray(w["state"], dtype=float).tobytes(),
    )  # fmt: skip
    if key not in _TABLES:
        _TABLES[key] = WhirlStartTable.compute(u)
    return _TABLES[key]


def reset_log_likelihood(
    table: WhirlStartTable, sensors: ResetSensorModel, values: np.ndarray, temper: float = 1.0
) -> np.ndarray:
    """``ln p(values | g)`` on ``table.gains`` (up to a constant), the phase marginalised (uniform over
    the table's phases, trapezoid weights); ``values``: the reset observation's entries ``table.names``.
    ``temper`` (0-1] scales the Gaussian's exponent (a tempered likelihood, against model error)."""
    if table.names != sensors.names:
        raise ValueError(f"table entries {table.names} differ from the sensor model's {sensors.names}")
    v = np.asarray(values, dtype=float)
    if v.shape != (len(table.names),):
        raise ValueError(f"values must have shape ({len(table.names)},), got {v.shape}")
    prec = np.linalg.inv(sensors.covariance)
    r = v[None, None, :] - sensors.offset - table.mean  # (n_g, n_phase, n_entry)
    q = np.einsum("gpi,ij,gpj->gp", r, prec, r)
    a = -0.5 * float(temper) * q
    wts = np.ones(len(table.phases))
    wts[[0, -1]] = 0.5
    top = a.max(axis=1, keepdims=True)
    return top[:, 0] + np.log(np.exp(a - top) @ wts / wts.sum())
