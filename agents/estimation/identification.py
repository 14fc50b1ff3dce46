"""Identification of the drawn bearing from observations, and the rule that flies the table at the estimate.

RunUpRandomized-v1 hides the drawn bearing (clearance ``C``, foil stiffness factor ``f_K``, load ``F_L``);
the episode starts at the static equilibrium of that bearing at the documented start speed, and the
observation shows the journal position (in units of the nominal clearance) and the midplane pressure
probes of that equilibrium (with the sensors' noise and biases, ``docs/machine.md``).  Those numbers
depend on the three parameters smoothly, so an engineer with this package's model identifies the bearing
by least squares: :class:`BearingIdentifier` (a coarse 3 x 3 x 3 grid, then
``scipy.optimize.least_squares`` within the env's documented ranges, restarted from the next grid points
while the residual stays visible; ~60 equilibrium solves of ~5 ms on average).
:class:`~gfb_agents.rules.identify_map.IdentifyingAgent`
then reads the env's published table (``env.table``,
:class:`~gfb_env.envs.run_up_randomized.BestStableSpeedTable`: ``lambda_best`` and ``d_opt`` of a bearing)
at the estimate from the first observation and flies the map-informed schedule (damping ``d_opt``, ramp at
the motor limit, hold at ``target_fraction * lambda_best``, capped as the env caps it) on the estimated
bearing; capped at the task's command it is the v1 rule ``identify_map_v1``
(:func:`gfb_agents.ladder.build`).

What :class:`~gfb_agents.rules.identify_map.IdentifyingAgent` may read, as any user of the env:
 the observation and the env's documented
configuration (nominal bearing, grid, number of probes, start speed, parameter ranges, the published
table, action map, control interval, speed range) -- never the drawn parameters, the episode or the
simulator state (``env.unwrapped.episode``, ``_integ``).  It copies what it needs when it is built and
keeps no reference to the env.  On tasks without a drawn bearing it is the map-informed rule
(:class:`~gfb_agents.rules.map_informed.MapInformedAgent`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares

from gfb_env.envs.base import viscoelastic_model
from gfb_env.envs.units import N_ROTOR_OBS, OBS_ETA, OBS_XI
from gfb_env.equilibrium import EquilibriumError, find_equilibrium

__all__ = [
    "BearingEstimate",
    "BearingIdentifier",
    "POSITION_SD",
    "PRESSURE_SD",
    "identify_bearing",
    "refine_bearing",
]


@dataclass(frozen=True)
class BearingEstimate:
    """An identified bearing: ``C`` (m), ``f_K``, ``F_L`` (N), and the rms
    residual of the fit (observation units; 0 for a known bearing)."""

    clearance_m: float
    stiffness_factor: float
    load_n: float
    residual: float = 0.0
    solves: int = 0


class BearingIdentifier:
    """Least-squares fit of ``(C, f_K, F_L)`` of a randomised task to its first observation.

    Built from the env's documented configuration only (see the module docstring).  The prediction of
    the first observation for a candidate bearing is exactly what the env does at reset: the static
    equilibrium (:func:`~gfb_env.equilibrium.find_equilibrium`) of the viscoelastic model of the bearing
    ``nominal.replace(clearance_m=C, external_load_per_bearing_n=F_L)`` with ``K_W = f_K K_W,WA(C)`` at
    the start speed; position scaled by ``C / C_nom``, the midplane probes as they are.
    """

    def __init__(self, env):
        u = getattr(env, "unwrapped", env)
        self.nominal = u.nominal_bearing
        self.grid = u.grid
        self.n_probes = int(u.n_pressure_probes)
        self.start_speed_rpm = float(u.start_speed_rpm)
        self.bounds = np.array(
            [u.clearance_range_m, u.stiffness_factor_range, u.load_range_n], dtype=float
        )  # (3, 2): the documented ranges of the draw
        self.solves = 0

    def _unit(self, p: np.ndarray) -> np.ndarray:
        lo, hi = self.bounds[:, 0], self.bounds[:, 1]
        return (np.asarray(p, dtype=float) - lo) / np.where(hi > lo, hi - lo, 1.0)

    def _param(self, x: np.ndarray) -> np.ndarray:
        lo, hi = self.bounds[:, 0], self.bounds[:, 1]
        return lo + np.clip(x, 0.0, 1.0) * (hi - lo)

    def measured(self, obs: np.ndarray) -> np.ndarray:
        """The fitted entries of an observation: ``[xi, eta, P_0, ..., P_{k-1}]``."""
        obs = np.asarray(obs, dtype=float)
        return np.r_[obs[[OBS_XI, OBS_ETA]], obs[N_ROTOR_OBS : N_ROTOR_OBS + self.n_probes]]

    def predict(
        self, clearance_m: float, stiffness_factor: float, load_n: float, guess: np.ndarray | None = None
    ) -> tuple[np.ndarray, np.ndarray]:
        """Predicted fitted entries of the first observation and the equilibrium state."""
        b = self.nominal.replace(clearance_m=clearance_m, external_load_per_bearing_n=load_n)
        model = viscoelastic_model(self.grid, b, foil_stiffness=stiffness_factor * b.foil_stiffness)
        L = model.layout
        if guess is not None and len(guess) != L.size:
            guess = None
        self.solves += 1
        s = find_equilibrium(model, b.bearing_number_at(self.start_speed_rpm), guess=guess)
        xi, eta = L.rotor(s)[:2]
        scale = clearance_m / self.nominal.clearance_m
        return np.r_[xi * scale, eta * scale, s[L.midplane_probe_indices(self.n_probes)]], s

    def fit(
        self, obs: np.ndarray, coarse: int = 3, max_starts: int = 6, accept_rms: float = 1e-5
    ) -> BearingEstimate:
        """``(C, f_K, F_L)`` that reproduce the first observation ``obs`` best (within the ranges).

        Local fits from the ``max_starts`` best points of a ``coarse``-per-axis grid, in that order, until
        one reproduces the observation to ``accept_rms`` (rms over the fitted entries; a float32
        observation of the true draw gives ~1e-7); else the best of them."""
        return self.fit_measured(
            self.measured(obs), None, coarse, max_starts, accept_rms,
            x_scale=1.0, diff_step=1e-4, xtol=1e-10, ftol=1e-12, max_nfev=60,
        )  # fmt: skip

    def fit_measured(
        self,
        y: np.ndarray,
        weights: np.ndarray | None = None,
        coarse: int = 3,
        max_starts: int = 6,
        accept_rms: float = 1e-5,
        **least_squares_options,
    ) -> BearingEstimate:
        """The fit of :meth:`fit` to measured entries ``y`` (:meth:`measured`), each residual entry times
        ``weights`` (None: 1), stopping at a weighted rms below ``accept_rms``; ``least_squares_options``
        go to :func:`scipy.optimize.least_squares`."""
        self.solves = 0
        state: dict = {"guess": None}
        w = 1.0 if weights is None else np.asarray(weights, dtype=float)

        def residual(x: np.ndarray) -> np.ndarray:
            try:
                pred, s = self.predict(*self._param(x), guess=state["guess"])
            except EquilibriumError:
                return np.full(y.shape, 10.0) * w  # no equilibrium: as far from the data as it gets
            state["guess"] = s
            return (pred - y) * w

        # coarse grid in the unit cube: the starts of the local fit (smooth, but not convex: from a poor
        # start the fit can stall at a bound, e.g. the lowest load, with a visible residual)
        ticks = np.linspace(0.0, 1.0, coarse)
        starts = [np.array([a, b, c]) for a in ticks for b in ticks for c in ticks]
        cost = [float(np.sum(residual(x) ** 2)) for x in starts]
        sol = None
        for j in np.argsort(cost)[:max_starts]:
            state["guess"] = None
            trial = least_squares(residual, starts[j], bounds=(0.0, 1.0), **least_squares_options)
            if sol is None or trial.cost < sol.cost:
                sol = trial
            if np.sqrt(np.mean(sol.fun**2)) < accept_rms:
                break
        p = self._param(sol.x)
        rms = float(np.sqrt(np.mean(sol.fun**2)))
        return BearingEstimate(float(p[0]), float(p[1]), float(p[2]), rms, self.solves)


#: sensor errors in observation units (docs/machine.md, the MACHINE_V1 defaults): per-episode bias
#: (probes 1 um, taps 0.9 kPa) and per-observation noise (probes 0.3 um, taps 0.35 kPa), plus the 1x
#: unbalance orbit sampled at a random phase (up to 0.024 C)
POSITION_SD = (1.0 / 50.0, math.hypot(0.3 / 50.0, 0.015))
PRESSURE_SD = (0.9e3 / 101325.0, 0.35e3 / 101325.0)


def identify_bearing(
    identifier: BearingIdentifier, observations: list[np.ndarray], coarse: int = 3, max_starts: int = 4
) -> BearingEstimate:
    """Noise-aware identification of ``(C, f_K, F_L)`` from observations at the start speed.

    The observations are averaged (the noise and the 1x unbalance orbit average out; the per-episode
    probe and tap biases do not), and the residual of each fitted entry is weighted by the standard
    deviation of what is left (bias, and noise over the number of observations), so the pressure taps
    (bias 0.009 p0) count more than the probes (bias 0.02 C).  Same local fits as
    :meth:`BearingIdentifier.fit`."""
    n = len(observations)
    y = identifier.measured(np.mean(np.asarray(observations, dtype=float), axis=0))
    sd_pos = math.hypot(POSITION_SD[0], POSITION_SD[1] / math.sqrt(n))
    sd_p = math.hypot(PRESSURE_SD[0], PRESSURE_SD[1] / math.sqrt(n))
    wts = np.r_[np.full(2, 1.0 / sd_pos), np.full(len(y) - 2, 1.0 / sd_p)]
    # stop when chi^2 per entry is near 1 (rms below sqrt(1.5)): as good as the sensors allow
    return identifier.fit_measured(
        y, wts, coarse, max_starts, math.sqrt(1.5), diff_step=1e-3, xtol=1e-8, ftol=1e-10, max_nfev=40
    )


def refine_bearing(
    identifier: BearingIdentifier,
    points: list[tuple[float, np.ndarray, int]],
    start: BearingEstimate,
    max_nfev: int = 30,
) -> BearingEstimate:
    """Re-identify ``(C, f_K, F_L)`` from averaged observations at several speeds, the sensor biases
    eliminated.

    ``points``: ``(speed rpm, mean observation, number averaged)``, e.g. the start-speed average and
    quasi-static observations along the run-up (the equilibrium moves by ~0.3 C and ~0.3 p0 between
    Lambda = 0.45 and 0.65; a ramp at the motor limit lags it by ~1e-4 C).  The per-episode probe and tap
    biases are the same at every speed: per channel they are estimated (a Gaussian prior with the
    documented spread) and removed, so the fit rests on how the equilibrium *changes* with speed as well
    as on its absolute value.  Local least squares from ``start``."""
    nb = identifier.nominal
    y = np.array([identifier.measured(o) for _, o, _ in points])  # (n_points, n_entries)
    cnt = np.array([c for _, _, c in points], dtype=float)
    ne = y.shape[1]
    b_sd = np.r_[np.full(2, POSITION_SD[0]), np.full(ne - 2, PRESSURE_SD[0])]
    n_sd = np.r_[np.full(2, POSITION_SD[1]), np.full(ne - 2, PRESSURE_SD[1])]
    noise = (
        n_sd[None, :] / np.sqrt(cnt)[:, None] + np.r_[np.full(2, 0.002), np.full(ne - 2, 0.001)]
    )  # + model
    cache: dict = {"guesses": [None] * len(points)}

    def predictions(x: np.ndarray) -> np.ndarray:
        c, fk, fl = identifier._param(x)
        b = nb.replace(clearance_m=c, external_load_per_bearing_n=fl)
        model = viscoelastic_model(identifier.grid, b, foil_stiffness=fk * b.foil_stiffness)
        L = model.layout
        out = np.empty_like(y)
        scale = c / nb.clearance_m
        guess = None
        for i, (rpm, _, _) in enumerate(points):
            g0 = cache["guesses"][i] if cache["guesses"][i] is not None else guess
            s = find_equilibrium(model, b.bearing_number_at(rpm), guess=g0)
            cache["guesses"][i] = guess = s
            xi, eta = L.rotor(s)[:2]
            out[i] = np.r_[xi * scale, eta * scale, s[L.midplane_probe_indices(identifier.n_probes)]]
        return out

    def residual(x: np.ndarray) -> np.ndarray:
        try:
            r = predictions(x) - y
        except EquilibriumError:
            return np.full(y.size + ne, 1e3)
        w = 1.0 / noise**2
        # the bias of each channel: the posterior mean given the residuals and the prior spread
        bias = (w * r).sum(axis=0) / (w.sum(axis=0) + 1.0 / b_sd**2)
        return np.r_[((r - bias) / noise).ravel(), bias / b_sd]

    x0 = identifier._unit(np.array([start.clearance_m, start.stiffness_factor, start.load_n]))
    sol = least_squares(
        residual, x0, bounds=(0.0, 1.0), diff_step=1e-3, xtol=1e-8, ftol=1e-10, max_nfev=max_nfev
    )
    p = identifier._param(sol.x)
    return BearingEstimate(float(p[0]), float(p[1]), float(p[2]), float(np.sqrt(np.mean(sol.fun**2))))
