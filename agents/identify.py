"""Identification of the drawn bearing from observations, and the rule that flies the table at the estimate.

RunUpRandomized-v1 hides the drawn bearing (clearance ``C``, foil stiffness factor ``f_K``, load ``F_L``);
the episode starts at the static equilibrium of that bearing at the documented start speed, and the
observation shows the journal position (in units of the nominal clearance) and the midplane pressure
probes of that equilibrium (with the sensors' noise and biases, ``docs/machine.md``).  Those numbers
depend on the three parameters smoothly, so an engineer with this package's model identifies the bearing
by least squares: :class:`BearingIdentifier` (a coarse 3 x 3 x 3 grid, then
``scipy.optimize.least_squares`` within the env's documented ranges, restarted from the next grid points
while the residual stays visible; ~60 equilibrium solves of ~5 ms on average).
:class:`IdentifyingAgent` then reads the env's published table (``env.table``,
:class:`~gfb_env.envs.run_up_randomized.BestStableSpeedTable`: ``lambda_best`` and ``d_opt`` of a bearing)
at the estimate from the first observation and flies the map-informed schedule (damping ``d_opt``, ramp at
the motor limit, hold at ``target_fraction * lambda_best``, capped as the env caps it) on the estimated
bearing; capped at the task's command it is the v1 rule ``identify_map_v1``
(:func:`gfb_agents.rules_v1.make_rule`).

What :class:`IdentifyingAgent` may read, as any user of the env: the observation and the env's documented
configuration (nominal bearing, grid, number of probes, start speed, parameter ranges, the published
table, action map, control interval, speed range) -- never the drawn parameters, the episode or the
simulator state (``env.unwrapped.episode``, ``_integ``).  It copies what it needs when it is built and
keeps no reference to the env.  On tasks without a drawn bearing it is the map-informed rule
(:class:`~gfb_agents.scripted.MapInformedAgent`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares

from gfb_agents.nominal_map import NominalMap
from gfb_agents.scripted import ControlSpec, MapInformedAgent, ScriptedPolicy, TrackerMemory
from gfb_env.envs.base import viscoelastic_model
from gfb_env.envs.units import N_ROTOR_OBS, OBS_ETA, OBS_XI
from gfb_env.equilibrium import EquilibriumError, find_equilibrium

__all__ = ["BearingEstimate", "BearingIdentifier", "IdentifyingAgent"]


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


@dataclass
class IdentifyingMemory(TrackerMemory):
    """:class:`IdentifyingAgent`'s memory: the schedule of this episode and the estimate it rests on."""

    setpoint: float = 0.0
    damping: float = 1.0
    estimate: BearingEstimate | None = None


class IdentifyingAgent(ScriptedPolicy):
    """Identify the drawn bearing from the first observation, then fly the
    map-informed schedule for it (the env's published table at the estimate).

    Reads only the observation and the env's documented configuration and table (module docstring);
    it keeps no reference to the env.  On tasks without a drawn bearing it is the map-informed rule.
    """

    def __init__(
        self, env, spec: ControlSpec | None = None, nmap: NominalMap | None = None, name: str = "identify_map"
    ):
        u = getattr(env, "unwrapped", env)
        nmap = nmap or NominalMap.from_env(u)
        super().__init__(name, spec or ControlSpec.from_env(u, nmap))
        # the nominal schedule, the fallback and the whole rule on nominal tasks: map_informed's own
        nominal = MapInformedAgent(self.spec, nmap)
        self.nominal_damping, self.nominal_setpoint_rpm = nominal.damping, nominal.setpoint_rpm
        self.randomized = all(
            hasattr(u, k) for k in ("table", "clearance_range_m", "stiffness_factor_range", "load_range_n")
        )
        self.identifier = BearingIdentifier(u) if self.randomized else None
        self.table = u.table if self.randomized else None  # the published BestStableSpeedTable
        self.target_fraction = float(getattr(u, "target_fraction", 0.95))
        self.max_speed_rpm = float(u.speed_range_rpm[1])
        self.control_interval = float(u.control_interval)
        self.nominal = u.nominal_bearing
        self.last_estimate: BearingEstimate | None = None

    def _new_memory(self) -> IdentifyingMemory:
        return IdentifyingMemory(
            rate=self.spec.rpm_per_step, setpoint=self.nominal_setpoint_rpm, damping=self.nominal_damping
        )

    def _estimate(self, obs: np.ndarray, m: IdentifyingMemory) -> BearingEstimate | None:
        """The bearing of this episode (None: the nominal schedule)."""
        return self.identifier.fit(obs) if self.identifier is not None else None

    def schedule_for(self, est: BearingEstimate) -> tuple[float, float, float]:
        """``(hold speed rpm, damping, rpm per control step)`` of the map-informed schedule on ``est``:
        the published table's ``target_fraction * lambda_best`` (capped at 98 % of the top speed, as the
        env caps its target) and ``d_opt``."""
        b = self.nominal.replace(clearance_m=est.clearance_m, external_load_per_bearing_n=est.load_n)
        row = self.table(est.clearance_m, est.stiffness_factor, est.load_n)
        lam = min(self.target_fraction * row["lambda_best"], 0.98 * b.bearing_number_at(self.max_speed_rpm))
        return (
            b.speed_rpm_at(lam),
            row["d_opt"],
            self.spec.actions.rpm_per_step(b, self.control_interval),
        )

    def _act(self, obs, rpm, m: IdentifyingMemory):
        if m.k == 0:
            est = self._estimate(obs, m)
            if est is not None:
                m.setpoint, m.damping, m.rate = self.schedule_for(est)
            m.estimate = self.last_estimate = est
        return [self.track(m, rpm, m.setpoint), self.spec.damping_action(m.damping)]
