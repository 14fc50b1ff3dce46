"""``recovery_detect``: ``recovery_reset`` that watches for friction-regime changes of the damping gain and
re-identifies ``g`` when one shows (issue 19 s.3, ``docs/task_redesign.md``, "A change-detecting rule").

With ``damping_regime_changes`` the damping effectiveness ``g`` jumps by a factor 1.5-2.5 at random
times; the actuator's indicated damping does not move.  ``recovery_reset`` identifies ``g`` once and then
runs at about 0.99 ``lambda_best`` with ``D_opt / g`` commanded; after a change the actual damping is off
the optimum by the factor, ``Lambda_c`` falls 2-10 % below ``lambda_best`` and the whirl mode grows out
of the probes' noise.  Where a change shows, measured on DEV seeds:

* **Not in the 1x vector.**  At the operating point the unbalance response is ~0.006 C (zero to peak)
  against a noise of ~0.001 C per component and step (17 %), and a 1.5x change of ``D_W`` around
  ``D_opt`` moves it by 1-3 % and 0.5-3 deg (the model's response): ~70 steps for one standard error.
* **In the sub-synchronous band** (``x_subsync_rms``, ``y_subsync_rms``): the level sits at the monitor's
  noise floor (~0.0015 C) while the plant is stable and grows at the whirl mode's rate
  ``60 sigma(Lambda, g D_cmd)`` per step (log) once it is not: 0.1-0.3 per step for a 1.6-2x change,
  so the level leaves the floor within ~4-15 steps.
* **The direction in the whirl frequency** (``subsync_ratio``): ``Lambda_c`` falls on both sides of
  ``D_opt``, but the whirl mode's frequency ratio ``Im(lambda) / Lambda`` rises monotonically with the
  actual damping (0.316 at ``D_W`` = 0.6 to 0.383 at 6 near ``lambda_best``; measured 0.325 at 1.2 and
  0.369 at 3.3, the model 0.326 and 0.368).  Growth rate and ratio together give ``g`` (both sides).

The detector (:class:`SubsyncCusum`) is a one-sided CUSUM on the increments of the log band level,
armed only once the level is ``arm`` times the floor (the probe model's noise floor, then a running low
quantile of the level at the operating point kept near it): ``S = max(0, S + clip(dl) - drift)``; it
alarms when ``S > threshold``, the level is ``alarm_level`` times the floor, and the last ``rises``
increments are all positive (an unstable mode keeps growing).  A rise of more than ``jump`` in one step is
a shock's pulse and holds the statistic off for a few steps (the ring-down of a stable plant then
decays); a second alarm catches a whirl that neither grows nor decays (``sustain_*``).  On an alarm the
rule replaces its posterior over ``g`` by the prior times the likelihood of the measured growth rate and
frequency ratio (the latest steps at the damping in force; :meth:`RecoveryDetectAgent.reidentify`), drops
the speed cap of the old regime and decides again: the new command ``D_opt / g'`` makes the plant stable
at the same speed, so a small whirl decays without a speed dip (one caught large, or a sustained one,
also backs the speed off until calm).  The whirl guard of ``margin_search`` (the envelope) stays as the
backstop for a change it catches first; then the same re-identification runs on what the band recorded.

Measured on DEV seeds 0-99 (``docs/task_redesign.md``): median detection delay 10 control steps, no false
alarm on the seeds without a change, and the oracle's headroom over it is IQM 0.02 at 1 change per second
(it scores as an oracle that learns of each change 10 steps late); on the plain task it plays as
``recovery_reset``.

Public interface only: the observation, the task's public configuration (nominal bearing, gain range,
the control clock) and the project's model (the whirl mode's eigenvalues on the nominal plant).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field

import numpy as np

from gfb_agents.estimation.gain import GainPosterior
from gfb_agents.rules.margin_search import Mode
from gfb_agents.rules.recovery import RecoveryMemory
from gfb_agents.rules.recovery_reset import RecoveryResetAgent
from gfb_env.analysis import jacobian_eigenvalues
from gfb_env.equilibrium import find_equilibrium
from gfb_env.model import GFBModel

__all__ = ["SubsyncCusum", "WhirlRatioTable", "DetectMemory", "RecoveryDetectAgent"]


class SubsyncCusum:
    """One-sided CUSUM on the growth of the sub-synchronous band level (module docstring).

    Args:
        drift: the CUSUM's reference growth per step (log; increments below it count against).
        threshold: the alarm level of the CUSUM statistic (log).
        arm: the statistic accumulates only while the level is at least this many floors.
        alarm_level: an alarm also needs the level at this many floors.
        rises: an alarm also needs this many positive increments in a row.
        clip: increments are clipped to ``[-clip, clip]`` (a shock's jump counts as one bounded rise).
        floor_window, floor_quantile: the floor: this quantile of the last ``floor_window`` levels seen
            while the statistic was zero (needs ``floor_min`` of them before any alarm).
    """

    def __init__(
        self,
        drift: float = 0.03,
        threshold: float = 0.5,
        arm: float = 2.0,
        alarm_level: float = 3.0,
        rises: int = 3,
        clip: float = 0.5,
        floor_window: int = 40,
        floor_quantile: float = 0.3,
        floor_min: int = 8,
        floor0: float | None = None,
        jump: float = 1.0,
        jump_holdoff: int = 5,
        sustain_steps: int = 10,
        sustain_level: float = 8.0,
        sustain_slope: float = -0.02,
    ):
        if not (drift >= 0 and threshold > 0 and 1 <= arm <= alarm_level and rises >= 1 and clip > 0):
            raise ValueError(
                f"SubsyncCusum needs drift >= 0, threshold > 0, 1 <= arm <= alarm_level, rises >= 1, "
                f"clip > 0; got {drift!r}, {threshold!r}, {arm!r}, {alarm_level!r}, {rises!r}, {clip!r}"
            )
        if not (0 < floor_quantile < 1 and floor_window >= floor_min >= 1):
            raise ValueError(
                f"floor_quantile must be in (0, 1) and floor_window >= floor_min >= 1, got "
                f"{floor_quantile!r}, {floor_window!r}, {floor_min!r}"
            )
        self.drift, self.threshold, self.arm, self.alarm_level = drift, threshold, arm, alarm_level
        self.rises, self.clip = int(rises), float(clip)
        self.floor_window, self.floor_quantile, self.floor_min = floor_window, floor_quantile, floor_min
        if floor0 is not None and not floor0 > 0:
            raise ValueError(f"floor0 must be positive or None, got {floor0!r}")
        self.floor0 = None if floor0 is None else float(floor0)
        if not (jump > clip and jump_holdoff >= 0):
            raise ValueError(
                f"jump must exceed clip and jump_holdoff be >= 0, got {jump!r}, {jump_holdoff!r}"
            )
        self.jump, self.jump_holdoff = float(jump), int(jump_holdoff)
        if sustain_steps < 0 or sustain_steps == 1:
            raise ValueError(f"sustain_steps must be 0 (off) or >= 2, got {sustain_steps!r}")
        self.sustain_steps, self.sustain_level = int(sustain_steps), float(sustain_level)
        self.sustain_slope = float(sustain_slope)
        self.reset()

    def reset(self) -> None:
        """Forget everything (a new episode)."""
        self.quiet: list[float] = []
        self.restart()

    def restart(self) -> None:
        """Start the statistic again (after an alarm, or after the operating point moved); the floor's
        samples are kept."""
        self.stat = 0.0
        self.prev: float | None = None
        self.up = 0
        self.off = 0
        self.recent: list[float] = []
        #: the last alarm's kind: "growth" (the CUSUM) or "sustained"
        self.kind: str | None = None

    @property
    def floor(self) -> float | None:
        if len(self.quiet) < self.floor_min:
            return self.floor0
        q = float(np.quantile(self.quiet[-self.floor_window :], self.floor_quantile))
        return q if self.floor0 is None else float(np.clip(q, 0.8 * self.floor0, 1.5 * self.floor0))

    def update(self, level: float) -> bool:
        """One step's band level (any unit, > 0); True when the detector alarms on it."""
        level = max(float(level), 1e-12)
        if self.prev is not None and math.log(level / self.prev) > self.jump:
            self.off = self.jump_holdoff  # a shock's pulse
        if self.off > 0:
            self.off -= 1
            self.stat, self.up, self.prev, self.recent = 0.0, 0, level, []
            return False
        floor = self.floor
        if self.stat == 0.0:
            self.quiet.append(level)
        if floor is None:
            self.prev = level
            return False
        if self.prev is not None:
            inc = math.log(level / self.prev)
            self.up = self.up + 1 if inc > 0 else 0
            if level >= self.arm * floor:
                self.stat = max(0.0, self.stat + float(np.clip(inc, -self.clip, self.clip)) - self.drift)
            else:
                self.stat = 0.0
        self.prev = level
        if self.stat > self.threshold and level >= self.alarm_level * floor and self.up >= self.rises:
            self.kind = "growth"
            return True
        if self._sustained(level, floor):
            self.kind = "sustained"
            return True
        return False

    def _sustained(self, level: float, floor: float) -> bool:
        if self.sustain_steps == 0:
            return False
        self.recent = (
            (self.recent + [level])[-self.sustain_steps :] if level >= self.sustain_level * floor else []
        )
        if len(self.recent) < self.sustain_steps:
            return False
        slope = float(np.polyfit(np.arange(self.sustain_steps, dtype=float), np.log(self.recent), 1)[0])
        return slope > self.sustain_slope


class WhirlRatioTable:
    """The whirl mode's frequency ratio ``|Im(lambda)| / Lambda`` of one plant on a grid of ``Lambda``
    and actual ``D_W`` (log-spaced), interpolated bilinearly in ``(Lambda, ln D_W)`` (as
    :class:`~gfb_agents.estimation.stability.StabilityTable`; the mode of the largest real part)."""

    def __init__(self, lambdas: np.ndarray, dampings: np.ndarray, ratio: np.ndarray):
        self.lambdas = np.asarray(lambdas, dtype=float)
        self.log_d = np.log(np.asarray(dampings, dtype=float))
        self.ratio = np.asarray(ratio, dtype=float)

    @classmethod
    def compute(
        cls,
        model: GFBModel,
        lam_lo: float,
        lam_hi: float,
        n_lambda: int = 5,
        damping_range: tuple[float, float] = (0.2, 15.0),
        n_damping: int = 25,
    ) -> WhirlRatioTable:
        lams = np.linspace(lam_lo, lam_hi, n_lambda)
        ds = np.geomspace(*damping_range, n_damping)
        r = np.empty((n_lambda, n_damping))
        s = None
        for i, lam in enumerate(lams):
            s = find_equilibrium(model, float(lam), guess=s)
            for j, d in enumerate(ds):
                r[i, j] = abs(jacobian_eigenvalues(model, s, float(lam), float(d))[0].imag) / lam
        return cls(lams, ds, r)

    def __call__(self, lam: float, d: np.ndarray) -> np.ndarray:
        """The ratio at ``Lambda`` (clipped to the grid) for actual dampings ``d``."""
        x = np.clip(np.log(np.asarray(d, dtype=float)), self.log_d[0], self.log_d[-1])
        j = np.clip(np.searchsorted(self.log_d, x) - 1, 0, len(self.log_d) - 2)
        w = (x - self.log_d[j]) / (self.log_d[j + 1] - self.log_d[j])
        cols = self.ratio[:, j] * (1 - w) + self.ratio[:, j + 1] * w
        lam = float(np.clip(lam, self.lambdas[0], self.lambdas[-1]))
        i = int(np.clip(np.searchsorted(self.lambdas, lam) - 1, 0, len(self.lambdas) - 2))
        u = (lam - self.lambdas[i]) / (self.lambdas[i + 1] - self.lambdas[i])
        return cols[i] * (1 - u) + cols[i + 1] * u


@dataclass
class BandSample:
    """One step's band reading at the operating point: the level (max of the probes, units of C_nom),
    the dominant ratio, the damping commanded over the step and the step's Lambda."""

    level: float
    ratio: float
    d: float
    lam: float


@dataclass
class DetectMemory(RecoveryMemory):
    """:class:`RecoveryDetectAgent`'s memory: ``recovery``'s plus the band's history since the last
    re-identification, the alarms (step indices) and the re-identified gains."""

    band: list[BandSample] = field(default_factory=list)
    alarms: list[int] = field(default_factory=list)
    reidentified: list[float] = field(default_factory=list)
    holdoff: int = 0
    whirls_seen: int = 0
    cusum: SubsyncCusum | None = None


class RecoveryDetectAgent(RecoveryResetAgent):
    """``recovery_detect`` (WhirlRecovery with regime changes): :class:`RecoveryResetAgent` plus a CUSUM
    on the sub-synchronous level's growth and a re-identification of ``g`` from the growth rate and the
    whirl frequency ratio on an alarm (module docstring).

    Args:
        env: the task's env (public configuration only).
        detector: the :class:`SubsyncCusum`'s keyword arguments.
        rate_sd: sd of a measured growth rate (log per step) against the model's ``60 sigma``.
        ratio_sd: sd of the measured band ratio against the model's whirl frequency ratio.
        fit_steps: at most this many of the latest growing steps (at the damping in force) are fitted.
        holdoff: steps after a re-identification before the detector runs again (the new damping's
            transient; the statistic restarts).
        min_rate: an alarm re-identifies only where the fitted growth rate (log per step) exceeds this.
        recover_envelope: an alarm with the orbit envelope above this (units of C), or a sustained
            whirl's alarm, also backs the speed off by ``backoff`` until calm (``margin_search``'s
            recovering, without its speed cap): below the fold the subcritical cycle collapses.
        **kw: :class:`RecoveryResetAgent`'s.
    """

    def __init__(
        self,
        env,
        detector: dict | None = None,
        rate_sd: float = 0.08,
        ratio_sd: float = 0.006,
        fit_steps: int = 6,
        holdoff: int = 3,
        min_rate: float = 0.0,
        recover_envelope: float = 0.3,
        name: str = "recovery_detect",
        **kw,
    ):
        super().__init__(env, name=name, **kw)
        if not (rate_sd > 0 and ratio_sd > 0 and fit_steps >= 2 and holdoff >= 0):
            raise ValueError(
                f"rate_sd, ratio_sd must be positive, fit_steps >= 2, holdoff >= 0; got {rate_sd!r}, "
                f"{ratio_sd!r}, {fit_steps!r}, {holdoff!r}"
            )
        u = getattr(env, "unwrapped", env)
        # the band's noise floor from the public probe model (docs/machine.md, vibration monitor): rank
        # 2 x 4 band frequencies over the step's 120 samples, in units of the nominal clearance
        floor0 = float(u.proximity_probes.noise_um) * math.sqrt(8 / 120) / (self.nominal.clearance_m * 1e6)
        self.detector_kw = {"floor0": floor0, **dict(detector or {})}
        SubsyncCusum(**self.detector_kw)  # bad settings: one clear error now
        self.rate_sd, self.ratio_sd = float(rate_sd), float(ratio_sd)
        self.fit_steps, self.holdoff, self.min_rate = int(fit_steps), int(holdoff), float(min_rate)
        self.recover_envelope = float(recover_envelope)
        layout = u.observation_layout
        self._band = (layout.index("x_subsync_rms"), layout.index("y_subsync_rms"))
        self._ratio = layout.index("subsync_ratio")
        self._valid = layout.index("monitor_valid")

    # -- tables -------------------------------------------------------------------------------
    def ratio_table(self) -> WhirlRatioTable:
        """The nominal plant's whirl frequency ratio near the operating speeds (computed once)."""
        if "ratio" not in self._tables:
            self._nominal_table()
            lb = self.nmap.lambda_best
            self._tables["ratio"] = WhirlRatioTable.compute(
                self._tables["nominal_model"], 0.86 * lb, 1.04 * lb
            )
        return self._tables["ratio"]

    def _new_memory(self) -> DetectMemory:
        base = super()._new_memory()
        m = DetectMemory(**{f.name: getattr(base, f.name) for f in dataclasses.fields(base)})
        m.cusum = SubsyncCusum(**self.detector_kw)
        return m

    def alarms(self, env_index: int = 0) -> list[int]:
        """The control steps (``k`` of the memory) of env ``env_index``'s alarms in this episode."""
        return list(self._mem[env_index].alarms) if env_index < len(self._mem) else []

    # -- the re-identification ----------------------------------------------------------------
    def change_log_likelihood(
        self, samples: list[BandSample], floor: float, gains: np.ndarray, min_rate: float | None = None
    ) -> np.ndarray | None:
        """Log-likelihood over ``gains`` of the latest steps at one commanded damping: the growth rate of
        the floor-corrected level (least squares) and its energy-weighted ratio; None where the fitted
        rate is not above ``min_rate`` (default the rule's: a decaying transient is no sign of a change)."""
        min_rate = self.min_rate if min_rate is None else min_rate
        d, lam = samples[-1].d, samples[-1].lam
        run = []
        for s in reversed(samples):
            if s.d != d or len(run) >= self.fit_steps:
                break
            run.append(s)
        run = run[::-1]
        sig = np.sqrt(np.maximum(np.array([s.level for s in run]) ** 2 - floor**2, (0.3 * floor) ** 2))
        ll = np.zeros(len(gains))
        actual = gains * d
        if len(run) >= 2:
            t = np.arange(len(run), dtype=float)
            rate = float(np.polyfit(t, np.log(sig), 1)[0])
            if rate <= min_rate:  # not growing (a decaying transient): no evidence of a change
                return None
            pred = self.step_tau(self.nominal) * self._tables["nominal"].growth_rate(lam, actual)
            ll += -0.5 * ((rate - pred) / self.rate_sd) ** 2
        strong = sig >= 2.0 * floor
        if strong.any():
            w = sig[strong] ** 2
            ratio = float(np.sum(w * np.array([s.ratio for s in run])[strong]) / np.sum(w))
            ll += -0.5 * ((ratio - self.ratio_table()(lam, actual)) / self.ratio_sd) ** 2
        return ll

    def reidentify(self, m: DetectMemory, floor: float, min_rate: float | None = None) -> bool:
        """A change: the posterior over ``g`` becomes the prior times the band's likelihood; the old
        regime's speed cap goes; decide again.  False (nothing done) where the band does not grow."""
        ll = self.change_log_likelihood(m.band, floor, m.post.gains, min_rate)
        if ll is None:
            return False
        post = GainPosterior(self.gain_range, n=len(m.post.gains))
        post.log_w = ll - ll.max()
        post.measurements.append(("regime_change", m.k))
        m.post = post
        m.reidentified.append(float(post.gains[int(np.argmax(ll))]))
        m.cap = math.inf
        m.dirty = True
        m.band = []
        m.holdoff = self.holdoff
        return True

    # -- the step -----------------------------------------------------------------------------
    def _band_step(self, obs: np.ndarray, rpm: float, m: DetectMemory) -> None:
        """Record this step's band reading; the detector runs on it at the operating point only
        (constant speed: the level of a run-up or of a speed change is not the operating point's)."""
        det = m.cusum
        o = np.asarray(obs, dtype=float)
        if o[self._valid] < 0.5:
            det.restart()
            return
        level = float(max(o[self._band[0]], o[self._band[1]]))
        m.band.append(BandSample(level, float(o[self._ratio]), float(m.d_prev or m.d_cmd), self._lam(m, rpm)))
        del m.band[: -4 * self.fit_steps]
        at_speed = m.setpoint is not None and abs(rpm - m.setpoint) <= 2e-3 * m.setpoint
        if not at_speed or m.holdoff > 0:
            m.holdoff = max(0, m.holdoff - 1)
            det.restart()
            return
        if det.update(level):
            m.alarms.append(m.k)
            # a sustained whirl may decay slowly (its slope above the detector's sustain_slope)
            self.reidentify(m, det.floor, det.sustain_slope if det.kind == "sustained" else None)
            det.restart()
            big = self.spec.observations.envelope(o) > self.recover_envelope or det.kind == "sustained"
            if big and m.mode is Mode.RUN:
                # caught late (a shock's transient grew): the orbit may already ride the subcritical
                # cycle that outlives the new damping's stability; back off below it as the guard does
                m.mode, m.calm, m.recover_rpm = Mode.RECOVER, 0, rpm * (1 - self.backoff)

    def _on_run(self, obs: np.ndarray, rpm: float, m: DetectMemory) -> list[float]:
        if m.k == 0 or not isinstance(m, DetectMemory):
            return super()._on_run(obs, rpm, m)
        self._band_step(obs, rpm, m)
        act = super()._on_run(obs, rpm, m)
        if m.whirl_count > m.whirls_seen:
            # the envelope's guard fired first: re-identify from what the band recorded (if it grew)
            m.whirls_seen = m.whirl_count
            det = m.cusum
            floor = det.floor
            if floor is not None and len(m.band) >= 2 and m.band[-1].level >= det.alarm_level * floor:
                m.alarms.append(m.k)
                self.reidentify(m, floor)
                det.restart()
        return act
