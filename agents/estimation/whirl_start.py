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
    "STEP_ENTRIES",
    "FirstStepUpdate",
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


#: the first control step's entries that the update reads (by name, as the reset's)
STEP_ENTRIES = ("xi", "eta", "xi_dot", "eta_dot", "xi_extent", "eta_extent")


class FirstStepUpdate:
    """The likelihood of the reset observation *and* the first control step's over ``g``: a particle
    update through the exact first step.

    The plant is deterministic between the reset and the first observation but for the residual
    unbalance (unknown: its documented ISO grade range, any angle) and a rare base shock: for each gain
    of the table the ``phases_per_gain`` phases that fit the reset best are integrated over the step with
    the speed and the indicated damping the first observation reports (actual = g x indicated: the
    actuator's lag acts on ``ln D_W``, the same for every g).  The unbalance enters linearly (its response
    at the best particle, per unit vector), marginalised with its prior's second moment; the probes' and
    taps' per-episode biases are shared by both observations (a joint Gaussian); a shock in the step is a
    broad outlier component of probability ``outlier``.  Only gains whose reset likelihood lies within
    ``reset_cut`` (log) of the best get particles (the others keep the outlier branch: ~e^-12 of the
    best).  The step's conditional likelihood is tempered by ``temper``: with the unbalance linearised
    and the phases discrete it was ~2x too sharp (validation seeds), and the posterior's grid (0.027 in
    ln g) is coarser than its width.  Measured in docs/agents.md.
    """

    def __init__(
        self,
        env,
        table: WhirlStartTable,
        phases_per_gain: int = 3,
        outlier: float = 0.01,
        temper: float = 0.25,
        reset_cut: float = 12.0,
    ):
        u = getattr(env, "unwrapped", env)
        self.table = table
        self.reset_sensors = ResetSensorModel.from_env(u)
        self.k = int(phases_per_gain)
        if self.k < 1 or not 0.0 < outlier < 1.0:
            raise ValueError(f"phases_per_gain must be >= 1 and outlier in (0, 1), got {self.k}, {outlier}")
        self.outlier = float(outlier)
        if not (0.0 < temper <= 1.0 and reset_cut > 0.0):
            raise ValueError(f"temper must be in (0, 1] and reset_cut > 0, got {temper}, {reset_cut}")
        self.temper, self.reset_cut = float(temper), float(reset_cut)
        self.model = viscoelastic_model(u.grid, u.nominal_bearing)
        n_taps = int(u.n_pressure_probes)
        self.idx = self.model.layout.midplane_probe_indices(n_taps)
        self.state0 = np.asarray(u.constants["whirl"]["state"], dtype=float)
        self.lam, self.d0 = float(u.whirl_bearing_number), float(u.whirl_damping)
        self.control_interval, self.record_interval = float(u.control_interval), float(u.record_interval)
        self.touchdown, self.options = float(u.touchdown_film_thickness), u.config.integrator
        self.names1 = (*STEP_ENTRIES, *(f"pressure_{k}" for k in range(n_taps)))
        self.cov, self.offset1 = self._joint_errors(u, n_taps)
        self.unbalance_var = _unbalance_second_moment(u)

    # -- the sensors ----------------------------------------------------------------------------
    def _joint_errors(self, u, n_taps: int) -> tuple[np.ndarray, np.ndarray]:
        """Covariance of the errors of (reset entries, first-step entries), and the step's offset."""
        nb = u.nominal_bearing
        c_um = nb.clearance_m * 1e6
        probes, taps = u.proximity_probes, u.pressure_taps
        r0 = self.reset_sensors
        n0, n1 = len(r0.names), len(self.names1)
        cov = np.zeros((n0 + n1, n0 + n1))
        cov[:n0, :n0] = r0.covariance
        # the step: position and velocity as at the reset (bias + the last sample; the window's slope)
        cov[n0 : n0 + 4, n0 : n0 + 4] = r0.covariance[:4, :4]
        ext_mean, ext_var = _extent_errors(probes, c_um, self.record_interval, self.control_interval)
        cov[n0 + 4, n0 + 4] = cov[n0 + 5, n0 + 5] = ext_var
        kpa = 1e3 / nb.ambient_pressure_pa
        cov[n0 + 6 :, n0 + 6 :] = np.eye(n_taps) * (taps.noise_kpa**2 + taps.bias_spread_kpa**2) * kpa**2
        cov[n0 + 6 :, n0 + 6 :] += np.eye(n_taps) * float(u.observation_noise) ** 2
        cov[n0 + 4 : n0 + 6, n0 + 4 : n0 + 6] += np.eye(2) * float(u.observation_noise) ** 2
        cov[n0 : n0 + 4, n0 : n0 + 4] += np.eye(4) * float(u.observation_noise) ** 2
        # shared between the two observations: the probes' and the taps' per-episode biases
        inv = np.linalg.inv(probes.directions)
        shared_p = (probes.bias_spread_um / c_um) ** 2 * (inv @ inv.T)
        cov[0:2, n0 : n0 + 2] = cov[n0 : n0 + 2, 0:2] = shared_p
        shared_t = np.eye(n_taps) * taps.bias_spread_kpa**2 * kpa**2
        cov[4:n0, n0 + 6 :] = cov[n0 + 6 :, 4:n0] = shared_t
        offset = np.zeros(n1)
        offset[:2] = r0.offset[:2]
        offset[4:6] = ext_mean
        offset[6:] = r0.offset[4:]
        return cov, offset

    # -- the plant --------------------------------------------------------------------------------
    def _integrator(self, state: np.ndarray, d: float) -> TrapezoidalIntegrator:
        return TrapezoidalIntegrator(
            self.model, state, self.lam, d, touchdown_film_thickness=self.touchdown, options=self.options
        )

    def _step(self, state: np.ndarray, g: float, lam1: float, d_ind1: float, unbalance=None) -> np.ndarray:
        """The first step's noise-free entries from the start ``state`` (NaN if the plant failed)."""
        integ = self._integrator(state, g * self.d0)
        if unbalance is not None:
            integ.set_unbalance(unbalance)
        try:
            res = integ.advance(
                self.control_interval, lam1, g * d_ind1, record_interval=self.record_interval,
                record_indices=self.idx, raise_on_failure=False,
            )  # fmt: skip
        except (FloatingPointError, np.linalg.LinAlgError):
            return np.full(len(self.names1), np.nan)
        if not res.ok or res.touchdown is not None:
            return np.full(len(self.names1), np.nan)
        s = integ.state
        xi, eta, xd, ed = self.model.layout.rotor(s)
        return np.r_[
            xi,
            eta,
            xd,
            ed,
            res.xi_range[1] - res.xi_range[0],
            res.eta_range[1] - res.eta_range[0],
            s[self.idx],
        ]

    def log_likelihood(
        self, values0: np.ndarray, values1: np.ndarray, lam1: float, d_ind1: float
    ) -> tuple[np.ndarray, np.ndarray]:
        """``(ln p(obs_0, obs_1 | g), ln p(obs_0 | g))`` on the table's gains: ``values0`` the reset's
        entries ``table.names``, ``values1`` the first step's ``names1``, ``lam1`` and ``d_ind1`` the
        bearing number and indicated damping the first observation reports."""
        from gfb_env.forcing import Unbalance

        tab, r0s = self.table, self.reset_sensors
        v0, v1 = np.asarray(values0, dtype=float), np.asarray(values1, dtype=float)
        res0 = v0[None, None, :] - r0s.offset - tab.mean  # (n_g, n_phase, n0)
        prec0 = np.linalg.inv(r0s.covariance)
        q0 = np.einsum("gpi,ij,gpj->gp", res0, prec0, res0)
        ll_reset = reset_log_likelihood(tab, r0s, v0)
        n_g = len(tab.gains)
        best = np.argsort(q0, axis=1)[:, : self.k]  # (n_g, k) phase indices
        pred = np.full((n_g, self.k, len(self.names1)), np.nan)
        starts: dict[tuple[int, int], np.ndarray] = {}
        live = ll_reset >= ll_reset.max() - self.reset_cut
        for i, g in enumerate(tab.gains):
            if not live[i]:
                continue
            integ = self._integrator(self.state0, g * self.d0)
            for j in sorted(best[i]):
                ph = float(tab.phases[j])
                if ph > integ.tau:
                    integ.advance(ph)
                starts[(i, j)] = integ.state.copy()
        for i, g in enumerate(tab.gains):
            if not live[i]:
                continue
            for n, j in enumerate(best[i]):
                pred[i, n] = self._step(starts[(i, j)], float(g), lam1, d_ind1)
        # the unbalance's response (per unit vector) at the particle that fits the reset best
        fit = np.where(np.isfinite(pred[..., 0]), np.take_along_axis(q0, best, axis=1), np.inf)
        i0, n0_ = np.unravel_index(int(np.argmin(fit)), fit.shape)
        j0, g0 = int(best[i0, n0_]), float(tab.gains[i0])
        eps = 0.01
        jac = np.column_stack(
            [
                (self._step(starts[(i0, j0)], g0, lam1, d_ind1, Unbalance(eps, a)) - pred[i0, n0_]) / eps
                for a in (0.0, 0.5 * math.pi)
            ]
        )
        n0 = len(r0s.names)
        cov = self.cov.copy()
        if np.all(np.isfinite(jac)):
            cov[n0:, n0:] += self.unbalance_var * (jac @ jac.T)
        prec = np.linalg.inv(cov)
        _, logdet = np.linalg.slogdet(cov)
        r1 = v1[None, None, :] - self.offset1 - pred  # (n_g, k, n1)
        r = np.concatenate([res0[np.arange(n_g)[:, None], best], r1], axis=2)
        q = np.einsum("gki,ij,gkj->gk", r, prec, r)
        a = np.where(np.isfinite(q), -0.5 * q, -np.inf)
        top = np.max(a, axis=1, keepdims=True)
        top = np.where(np.isfinite(top), top, 0.0)
        # per gain: the sum over its phases, on the reset likelihood's scale (the same phase weights)
        ll_joint = top[:, 0] + np.log(np.sum(np.exp(a - top), axis=1) + 1e-300) - math.log(len(tab.phases))
        ll_joint = ll_joint - 0.5 * logdet
        # the reset likelihood on the same normalisation (its own covariance); the step's conditional
        # (tempered) against a broad density for a shock in the step
        _, logdet0 = np.linalg.slogdet(r0s.covariance)
        ll_reset_n = ll_reset - 0.5 * logdet0
        broad = -len(self.names1) * math.log(2.0)  # anything within ~2 (2 pi omitted, as elsewhere)
        cond = np.where(live & np.isfinite(ll_joint), ll_joint - ll_reset_n, -np.inf)
        ll = ll_reset_n + np.logaddexp(
            math.log(1 - self.outlier) + self.temper * cond, math.log(self.outlier) + broad
        )
        return ll, ll_reset


def _extent_errors(
    probes, c_um: float, record_interval: float, control_interval: float
) -> tuple[float, float]:
    """Mean and variance (C^2) of the extent's error of one step on a whirl-sized orbit (Monte Carlo of
    the documented probe model, seeded: the same numbers every time)."""
    if probes.noise_um == 0.0:
        return 0.0, 1e-12
    n = int(round(control_interval / record_interval))
    t = np.arange(1, n + 1) * record_interval
    xi = 0.5 * c_um * np.cos(2 * math.pi * t / 25.6)
    eta = 0.5 * c_um * np.sin(2 * math.pi * t / 25.6)
    rng = np.random.default_rng(0)
    e = np.array([probes.measurement_errors(rng, xi, eta, 1.0, np.zeros(2)).extent_um for _ in range(400)])
    e = e.ravel() / c_um
    return float(e.mean()), float(e.var()) + 1e-12


def _unbalance_second_moment(u) -> float:
    """``E[U^2] / 2`` (per component) of the residual unbalance the env's documented ``rotor_balance``
    draws (ISO grade log-uniform; 0 for a perfectly balanced rotor)."""
    rb = u.config.rotor_balance
    lo, hi = getattr(rb, "grade_range_mm_s", (0.0, 0.0)) or (0.0, 0.0)
    if hi <= 0.0:
        return 0.0
    from gfb_env.forcing import Unbalance

    ref = rb.reference_speed_rpm or u.speed_range_rpm[1]
    u_hi = Unbalance.from_iso1940(u.nominal_bearing, hi, ref).magnitude
    if hi == lo:
        return 0.5 * u_hi**2
    # U proportional to G, G log-uniform: E[G^2] = (hi^2 - lo^2) / (2 ln(hi / lo))
    m2 = (hi**2 - lo**2) / (2 * math.log(hi / lo)) * (u_hi / hi) ** 2
    return 0.5 * m2
