"""Transient run-up (and coast-down) at a constant acceleration, and its waterfall (issue 12).

The speed ramps linearly in time: ``Lambda(tau) = Lambda_1 + r tau`` with the bearing-number rate
``r = dLambda/dtau = alpha (2 pi / 60) T^2`` for an acceleration ``alpha`` in rpm/s (``T`` the time
scale of the bearing).  :meth:`TrapezoidalIntegrator.advance` ramps Lambda linearly within each call,
so the run is integrated in chunks whose end values lie on the ramp (the ramp is exact, the chunks
only bound the memory of one call).  The journal starts at the static equilibrium of the first speed,
displaced by ``perturbation`` (units of C) so that the whirl has a seed to grow from once the
equilibrium loses stability (without one, only round-off would seed it).

Unbalance: with ``unbalance`` (:class:`gfb_env.forcing.Unbalance`) the integrator carries the 1x
forcing ``U (theta'^2 sin theta - theta'' cos theta, ...)`` along the ramp (theta'' = r), so the
waterfall shows the 1x line's response.  The rotation angle of every sample is known in closed form
(``theta = Lambda_1 tau + r tau^2 / 2`` on the run-up, continued on the coast-down:
:attr:`RunUpResult.rotation_angle`), which gives the order-tracked 1x amplitude of each window
(:func:`envelopes`: least squares of ``c + d k + a cos theta - b sin theta``, the convention of
:func:`gfb_env.analysis.response.synchronous_components`) and separates the synchronous orbit from the
(subsynchronous) whirl: with an unbalance the whirl amplitude of a window is the half peak-to-peak of
xi minus its fitted 1x part.  Without one, nothing changes (bit for bit).

The waterfall is the Hann-windowed amplitude spectrum (:func:`gfb_env.analysis.spectrum.amplitude_spectrum`)
of the linearly detrended ``xi`` over consecutive windows of ``window`` tau, each labelled by its mean
speed.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from gfb_env.analysis.spectrum import amplitude_spectrum
from gfb_env.equilibrium import find_equilibrium
from gfb_env.forcing import Unbalance
from gfb_env.integrator import Trajectory, TrapezoidalIntegrator
from gfb_env.model import GFBModel
from gfb_env.params import BearingParameters, check_positive

if TYPE_CHECKING:
    from matplotlib.figure import Figure

__all__ = [
    "WHIRL_THRESHOLD",
    "RunUpAnalysis",
    "RunUpResult",
    "analyse_run_up",
    "Waterfall",
    "bearing_number_rate",
    "ramp_rotation_angle",
    "run_up",
    "waterfall",
    "envelopes",
]


def bearing_number_rate(model: GFBModel, acceleration_rpm_s: float) -> float:
    """``dLambda/dtau`` of a speed ramp of ``acceleration_rpm_s`` (rpm per second)."""
    b = model.bearing
    return b.bearing_number_at(check_positive("acceleration_rpm_s", acceleration_rpm_s)) * b.time_scale_s


@dataclass
class RunUpResult:
    """A run-up (and coast-down).

    Attributes:
        trajectory: the samples (``tau``, ``xi``, ``eta``, ..., ``bearing_number`` on the ramp).
        leg: 0 for run-up samples, 1 for coast-down samples.
        status: ``done``, ``touchdown`` or ``failed``; message: why it stopped early.
        tau_ramp: duration of one leg in tau.
        steps: accepted integrator steps; wall_time_s: wall time.
        rotation_angle: theta at each sample (without the unbalance phase), from the ramp in closed form.
        unbalance: the rotor's unbalance (None: none).
        final_rotation_angle: theta at the end as the integrator carried it, in [0, 2 pi).
    """

    trajectory: Trajectory
    leg: np.ndarray
    status: str
    message: str
    tau_ramp: float
    steps: int
    wall_time_s: float
    touchdown_tau: float | None = None
    rotation_angle: np.ndarray | None = None
    unbalance: Unbalance | None = None
    final_rotation_angle: float = 0.0


def ramp_rotation_angle(
    tau: np.ndarray, bearing_range: tuple[float, float], rate: float, tau_ramp: float
) -> np.ndarray:
    """theta(tau) = int Lambda dtau of the run-up (and coast-down) ramp, from theta(0) = 0."""
    lo, hi = bearing_range
    t = np.asarray(tau, dtype=float)
    up = np.minimum(t, tau_ramp)
    down = np.maximum(t - tau_ramp, 0.0)
    return lo * up + 0.5 * rate * up * up + hi * down - 0.5 * rate * down * down


def run_up(
    model: GFBModel,
    foil_damping: float,
    bearing_range: tuple[float, float],
    rate: float,
    coast_down: bool = False,
    perturbation: tuple[float, float] = (0.01, 0.0),
    record_interval: float = 0.5,
    touchdown: float = 0.01,
    chunk: float = 1000.0,
    progress: bool = False,
    unbalance: Unbalance | None = None,
) -> RunUpResult:
    """Integrate ``Lambda`` from ``bearing_range[0]`` to ``[1]`` at ``rate`` per tau (and back with
    ``coast_down``), recording the rotor every ``record_interval``; stops at touchdown.  ``unbalance``:
    the rotor's unbalance, on from tau = 0 (theta = 0 there)."""
    lo, hi = float(bearing_range[0]), float(bearing_range[1])
    if not (math.isfinite(lo) and math.isfinite(hi) and 0 < lo < hi):
        raise ValueError(f"bearing_range must satisfy 0 < min < max, got {bearing_range!r}")
    rate = check_positive("rate", rate)
    tau_ramp = (hi - lo) / rate
    s = find_equilibrium(model, lo)
    L = model.layout
    s = L.with_rotor(s, *(L.rotor(s)[:2] + np.asarray(perturbation, dtype=float)), 0.0, 0.0)
    integ = TrapezoidalIntegrator(
        model, s, lo, foil_damping, touchdown_film_thickness=touchdown, unbalance=unbalance
    )
    parts: list[Trajectory] = []
    legs: list[np.ndarray] = []
    status, message, steps, t_touch = "done", "", 0, None
    t0 = time.perf_counter()
    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(total=int(tau_ramp * (2 if coast_down else 1)), unit="tau", desc="run-up", leave=False)
    for leg, (a, b) in enumerate([(lo, hi), (hi, lo)][: 2 if coast_down else 1]):
        t_leg0 = integ.tau
        while integ.tau < t_leg0 + tau_ramp - 1e-9 and status == "done":
            t_end = min(integ.tau + chunk, t_leg0 + tau_ramp)
            lam_end = a + (b - a) * (t_end - t_leg0) / tau_ramp
            t_before = integ.tau
            res = integ.advance(
                t_end, bearing_number=lam_end, record_interval=record_interval, raise_on_failure=False
            )
            steps += res.steps
            parts.append(res.trajectory)
            legs.append(np.full(len(res.trajectory), leg, dtype=np.int8))
            if bar is not None:
                bar.update(int(res.tau - t_before))
            if res.status != "done":
                status = res.status
                message = res.message
                if res.touchdown is not None:
                    t_touch = res.touchdown.tau
                    message = f"touchdown (film below {touchdown:g} C) at tau={t_touch:.1f}"
    if bar is not None:
        bar.close()
    tr = Trajectory.concatenate(parts)
    return RunUpResult(
        trajectory=tr,
        leg=np.concatenate(legs),
        status=status,
        message=message,
        tau_ramp=tau_ramp,
        steps=steps,
        wall_time_s=time.perf_counter() - t0,
        touchdown_tau=t_touch,
        rotation_angle=ramp_rotation_angle(tr.tau, (lo, hi), rate, tau_ramp),
        unbalance=unbalance,
        final_rotation_angle=integ.rotation_angle,
    )


def _synchronous_fit(theta: np.ndarray, x: np.ndarray) -> tuple[complex, np.ndarray]:
    """``z = a + i b`` of ``x ~ c + d k + a cos theta - b sin theta`` and the fitted 1x part."""
    k = np.arange(len(x), dtype=float)
    cs, sn = np.cos(theta), -np.sin(theta)
    coef, *_ = np.linalg.lstsq(np.column_stack([np.ones_like(k), k, cs, sn]), x, rcond=None)
    return complex(coef[2], coef[3]), coef[2] * cs + coef[3] * sn


def envelopes(res: RunUpResult, window: float) -> dict[str, np.ndarray]:
    """Per window of ``window`` tau (within one leg): mean tau and Lambda, leg, min/max of xi and eta,
    max eccentricity, min film thickness, the order-tracked 1x amplitudes ``sync_xi``, ``sync_eta``
    (zero-to-peak) and the ``whirl`` amplitude (half peak-to-peak of xi; with an unbalance, of xi minus
    its fitted 1x part: the non-synchronous motion)."""
    tr = res.trajectory
    if len(tr) < 2:
        raise ValueError("the run recorded fewer than 2 samples")
    dt = float(tr.tau[1] - tr.tau[0])
    n_win = max(2, int(round(window / dt)))
    keys = (
        "tau", "bearing_number", "leg", "xi_min", "xi_max", "eta_min", "eta_max", "eps_max", "hmin",
        "sync_xi", "sync_eta", "whirl",
    )  # fmt: skip
    theta = res.rotation_angle
    if theta is None:
        raise ValueError("the run-up result has no rotation angle")
    rows: dict[str, list] = {k: [] for k in keys}
    for leg in np.unique(res.leg):
        idx_leg = np.nonzero(res.leg == leg)[0]
        for start in range(0, len(idx_leg), n_win):
            i = idx_leg[start : start + n_win]
            if len(i) < max(2, n_win // 2):
                continue
            rows["tau"].append(tr.tau[i].mean())
            rows["bearing_number"].append(tr.bearing_number[i].mean())
            rows["leg"].append(int(leg))
            rows["xi_min"].append(tr.xi[i].min())
            rows["xi_max"].append(tr.xi[i].max())
            rows["eta_min"].append(tr.eta[i].min())
            rows["eta_max"].append(tr.eta[i].max())
            rows["eps_max"].append(np.hypot(tr.xi[i], tr.eta[i]).max())
            rows["hmin"].append(tr.min_film_thickness[i].min())
            z_xi, x1 = _synchronous_fit(theta[i], tr.xi[i])
            z_eta, _ = _synchronous_fit(theta[i], tr.eta[i])
            rows["sync_xi"].append(abs(z_xi))
            rows["sync_eta"].append(abs(z_eta))
            # without an unbalance the whirl is the whole motion (unchanged by a fit of round-off)
            x = tr.xi[i] - x1 if res.unbalance is not None else tr.xi[i]
            rows["whirl"].append(0.5 * (x.max() - x.min()))
    return {k: np.asarray(v) for k, v in rows.items()}


@dataclass
class Waterfall:
    """Amplitude spectra of ``xi`` over consecutive windows: ``omega`` (rad per unit tau, shape (m,)),
    ``amplitude`` (units of C, shape (k, m)), and per window its mean ``bearing_number`` and ``leg``."""

    omega: np.ndarray
    amplitude: np.ndarray
    bearing_number: np.ndarray
    leg: np.ndarray

    def order_amplitude(self, order: float = 1.0) -> np.ndarray:
        """Per window, the height of the line at ``order`` x the mean speed: the largest bin within
        two bins of it, refined by the log-quadratic (Gaussian) interpolation over its neighbours
        (Gasior & Gonzalez; the Hann window's scalloping loss, up to 15 % on a bin, drops to ~1 %)."""
        dw = float(self.omega[1] - self.omega[0])
        out = np.zeros(len(self.bearing_number))
        for j, lam in enumerate(self.bearing_number):
            c = int(round(order * lam / dw))
            lo, hi = max(1, c - 2), min(len(self.omega) - 2, c + 2)
            if hi < lo:
                continue
            a = self.amplitude[j]
            k = lo + int(np.argmax(a[lo : hi + 1]))
            amp = a[k]
            if min(a[k - 1], a[k + 1]) > 0:
                la, lb, lc = np.log(a[k - 1]), np.log(a[k]), np.log(a[k + 1])
                den = la - 2 * lb + lc
                if den < 0:
                    p = 0.5 * (la - lc) / den
                    amp = float(np.exp(lb - 0.25 * (la - lc) * p))
            out[j] = amp
        return out


def waterfall(res: RunUpResult, window: float) -> Waterfall:
    """Hann-windowed spectra of ``xi`` over windows of ``window`` tau (each within one leg)."""
    tr = res.trajectory
    dt = float(tr.tau[1] - tr.tau[0])
    n_win = max(16, int(round(window / dt)))
    spectra, lams, legs, omega = [], [], [], None
    for leg in np.unique(res.leg):
        idx_leg = np.nonzero(res.leg == leg)[0]
        for start in range(0, len(idx_leg) - n_win + 1, n_win):
            i = idx_leg[start : start + n_win]
            # the equilibrium drifts with the speed: remove the linear trend, or its leakage hides
            # the low-frequency end of the spectrum
            k = np.arange(len(i))
            x = tr.xi[i] - np.polyval(np.polyfit(k, tr.xi[i], 1), k)
            sp = amplitude_spectrum(x, dt, fraction=1.0)
            omega = sp.omega
            spectra.append(sp.amplitude)
            lams.append(tr.bearing_number[i].mean())
            legs.append(int(leg))
    if omega is None:
        raise ValueError(f"the run is shorter than one waterfall window ({window:g} tau)")
    return Waterfall(omega, np.array(spectra), np.array(lams), np.array(legs))


# ------------------------------------------------------------------------------------------------
#: Half peak-to-peak of xi (units of C) over a window above which the journal counts as whirling.
WHIRL_THRESHOLD = 0.02


@dataclass(frozen=True)
class RunUpAnalysis:
    """A run-up and what an engineer reads off it (``gfb runup``'s summary and figures): the window
    envelopes (:func:`envelopes`) and the waterfall (:func:`waterfall`) of ``result``, the whirl onset
    on the run-up and its collapse on the coast-down, the dominant order at the top speed, the 1x
    (order-tracked) response, in the units of ``bearing``.  Made by :func:`analyse_run_up`.

    Attributes:
        result: the run; bearing: its dimensional bearing (rpm, um, s); window: the windows in tau.
        envelope: per window (:func:`envelopes`); waterfall: the spectra (:func:`waterfall`).
        critical_bearing_number: the linear onset Lambda_c (for the figures; ``None``: unknown).
        whirl_threshold: the whirl amplitude (units of C) that counts as whirling.
    """

    result: RunUpResult
    bearing: BearingParameters
    window: float
    envelope: dict[str, np.ndarray] = field(repr=False)
    waterfall: Waterfall = field(repr=False)
    critical_bearing_number: float | None = None
    whirl_threshold: float = WHIRL_THRESHOLD

    @property
    def _um(self) -> float:
        return self.bearing.clearance_m * 1e6

    @property
    def ok(self) -> bool:
        """The run went to its end or stopped at a touchdown (not an integration failure)."""
        return self.result.status in ("done", "touchdown")

    @property
    def speed_rpm(self) -> np.ndarray:
        """The speed of each sample in rpm."""
        return np.array([self.bearing.speed_rpm_at(x) for x in self.result.trajectory.bearing_number])

    @property
    def envelope_speed_rpm(self) -> np.ndarray:
        """The mean speed of each envelope window in rpm."""
        return np.array([self.bearing.speed_rpm_at(x) for x in self.envelope["bearing_number"]])

    @property
    def whirl_amplitude(self) -> np.ndarray:
        """Per window, the whirl amplitude (units of C; with an unbalance the non-synchronous part)."""
        return self.envelope["whirl"]

    def _whirling(self, leg: int) -> np.ndarray:
        return (self.whirl_amplitude > self.whirl_threshold) & (self.envelope["leg"] == leg)

    @property
    def whirl_onset_speed_rpm(self) -> float | None:
        """The first run-up window whose whirl amplitude exceeds :attr:`whirl_threshold` (rpm)."""
        up = self._whirling(0)
        return float(self.envelope_speed_rpm[np.argmax(up)]) if up.any() else None

    @property
    def whirl_collapse_speed_rpm(self) -> float | None:
        """The last coast-down window still whirling (rpm): below it the whirl has collapsed."""
        down = self._whirling(1)
        return float(self.envelope_speed_rpm[np.nonzero(down)[0][-1]]) if down.any() else None

    @property
    def top_speed_dominant_order(self) -> float:
        """The dominant line of the last run-up window, as a multiple of the rotor speed."""
        wf = self.waterfall
        j_top = int(np.nonzero(wf.leg == 0)[0][-1])
        k = 1 + int(np.argmax(wf.amplitude[j_top, 1:]))
        return float(wf.omega[k] / wf.bearing_number[j_top])

    @property
    def _top(self) -> int:
        return int(np.nonzero(self.envelope["leg"] == 0)[0][-1])

    @property
    def _synchronous(self) -> np.ndarray:
        return np.maximum(self.envelope["sync_xi"], self.envelope["sync_eta"])

    @property
    def top_speed_1x_speed_rpm(self) -> float:
        """The speed of the last run-up window (rpm), where :attr:`top_speed_1x_xi_um` is taken."""
        return float(self.envelope_speed_rpm[self._top])

    @property
    def top_speed_1x_xi_um(self) -> float:
        """The order-tracked 1x amplitude of x (zero-to-peak, um) at the top speed of the run-up."""
        return float(self.envelope["sync_xi"][self._top]) * self._um

    @property
    def top_speed_1x_eta_um(self) -> float:
        """The order-tracked 1x amplitude of y (zero-to-peak, um) at the top speed of the run-up."""
        return float(self.envelope["sync_eta"][self._top]) * self._um

    @property
    def max_1x_amplitude_um(self) -> float:
        """The largest order-tracked 1x amplitude (of x or y, zero-to-peak, um) over the run."""
        return float(self._synchronous[int(np.argmax(self._synchronous))]) * self._um

    @property
    def max_1x_speed_rpm(self) -> float:
        """The speed of :attr:`max_1x_amplitude_um` (rpm)."""
        return float(self.envelope_speed_rpm[int(np.argmax(self._synchronous))])

    @property
    def critical_speed_rpm(self) -> float | None:
        """The linear critical speed (rpm) of :attr:`critical_bearing_number`."""
        lam_c = self.critical_bearing_number
        return None if lam_c is None else self.bearing.speed_rpm_at(lam_c)

    @property
    def touchdown_speed_rpm(self) -> float | None:
        """The speed at the touchdown (rpm; ``None``: none)."""
        res = self.result
        if res.touchdown_tau is None:
            return None
        return float(np.interp(res.touchdown_tau, res.trajectory.tau, self.speed_rpm))

    def summary(self) -> dict:
        """The run's results in physical units (the keys of ``gfb runup --json`` from ``duration_tau`` to
        ``steps``)."""
        tr, um = self.result.trajectory, self._um
        return {
            "duration_tau": float(tr.tau[-1]),
            "duration_s": float(tr.tau[-1]) * self.bearing.time_scale_s,
            "status": self.result.status,
            "message": self.result.message,
            "touchdown_speed_rpm": self.touchdown_speed_rpm,
            "critical_speed_rpm": self.critical_speed_rpm,
            "whirl_onset_speed_rpm": self.whirl_onset_speed_rpm,
            "whirl_collapse_speed_rpm": self.whirl_collapse_speed_rpm,
            "max_whirl_amplitude_um": float(self.whirl_amplitude.max()) * um,
            "max_eccentricity_um": float(tr.eccentricity.max()) * um,
            "min_film_thickness_um": float(tr.min_film_thickness.min()) * um,
            "top_speed_dominant_order": self.top_speed_dominant_order,
            "top_speed_1x_speed_rpm": self.top_speed_1x_speed_rpm,
            "top_speed_1x_xi_um": self.top_speed_1x_xi_um,
            "top_speed_1x_eta_um": self.top_speed_1x_eta_um,
            "max_1x_amplitude_um": self.max_1x_amplitude_um,
            "max_1x_speed_rpm": self.max_1x_speed_rpm,
            "steps": self.result.steps,
        }

    def write_trajectory_csv(self, path: str | Path) -> Path:
        """The samples in physical units (``tau, time_s, speed_rpm, bearing_number, leg, xi_um, eta_um,
        min_film_thickness_um``): ``gfb runup``'s ``trajectory.csv``."""
        tr, b, um = self.result.trajectory, self.bearing, self._um
        np.savetxt(
            path,
            np.column_stack(
                [
                    tr.tau,
                    tr.tau * b.time_scale_s,
                    self.speed_rpm,
                    tr.bearing_number,
                    self.result.leg,
                    tr.xi * um,
                    tr.eta * um,
                    tr.min_film_thickness * um,
                ]
            ),  # fmt: skip
            delimiter=",",
            header="tau,time_s,speed_rpm,bearing_number,leg,xi_um,eta_um,min_film_thickness_um",
            comments="",
            fmt="%.8g",
        )
        return Path(path)

    def write_envelope_csv(self, path: str | Path) -> Path:
        """The window envelopes in physical units: ``gfb runup``'s ``envelope.csv``."""
        env, b, um = self.envelope, self.bearing, self._um
        np.savetxt(
            path,
            np.column_stack(
                [
                    env["tau"] * b.time_scale_s,
                    self.envelope_speed_rpm,
                    env["bearing_number"],
                    env["leg"],
                    env["xi_min"] * um,
                    env["xi_max"] * um,
                    env["eta_min"] * um,
                    env["eta_max"] * um,
                    env["eps_max"] * um,
                    env["hmin"] * um,
                    env["sync_xi"] * um,
                    env["sync_eta"] * um,
                    self.whirl_amplitude * um,
                ]
            ),  # fmt: skip
            delimiter=",",
            header="time_s,speed_rpm,bearing_number,leg,xi_min_um,xi_max_um,eta_min_um,eta_max_um,"
            "max_eccentricity_um,min_film_thickness_um,sync_xi_um,sync_eta_um,whirl_amplitude_um",
            comments="",
            fmt="%.8g",
        )
        return Path(path)

    def default_orbit_speeds_rpm(self) -> list[float]:
        """Four speeds spread over the recorded run-up (25, 50, 75 and 98 % of its speed range; ``gfb
        runup``'s default ``--orbit-rpm``) for :meth:`plot_orbits`."""
        lo, hi = (
            self.result.trajectory.bearing_number[0],
            float(np.max(self.result.trajectory.bearing_number)),
        )
        lo_rpm, hi_rpm = self.bearing.speed_rpm_at(float(lo)), self.bearing.speed_rpm_at(hi)
        return [lo_rpm + f * (hi_rpm - lo_rpm) for f in (0.25, 0.5, 0.75, 0.98)]

    def plot_waterfall(
        self, path: str | Path | None = None, nondimensional: bool = False, title: str = ""
    ) -> Figure:
        """The waterfall (:func:`gfb_env.plotting.plot_waterfall`)."""
        from gfb_env.plotting import plot_waterfall

        return plot_waterfall(
            self.waterfall, self.bearing, path, nondimensional, title, self.top_speed_dominant_order
        )

    def plot_orbits(
        self,
        orbit_rpm: list[float] | None = None,
        path: str | Path | None = None,
        nondimensional: bool = False,
        title: str = "",
    ) -> Figure:
        """Orbits at the speeds ``orbit_rpm`` on the run-up (default :meth:`default_orbit_speeds_rpm`)."""
        from gfb_env.plotting import plot_orbits

        speeds = self.default_orbit_speeds_rpm() if orbit_rpm is None else list(orbit_rpm)
        return plot_orbits(self.result, self.bearing, speeds, self.window, path, nondimensional, title)

    def plot_envelope(
        self, path: str | Path | None = None, nondimensional: bool = False, title: str = ""
    ) -> Figure:
        """The paper's Fig. 5 and the whirl amplitude over speed
        (:func:`gfb_env.plotting.plot_run_up_envelope`)."""
        from gfb_env.plotting import plot_run_up_envelope

        return plot_run_up_envelope(
            self.envelope, self.bearing, path, nondimensional, title, self.critical_bearing_number,
            self.result.unbalance is not None,
        )  # fmt: skip

    def plot(
        self,
        kind: str = "envelope",
        path: str | Path | None = None,
        nondimensional: bool = False,
        title: str = "",
    ) -> Figure:
        """One of the run-up figures: ``kind`` ``envelope`` (default), ``waterfall`` or ``orbits``."""
        figures = {"envelope": self.plot_envelope, "waterfall": self.plot_waterfall, "orbits": None}
        if kind not in figures:
            raise ValueError(f"kind must be one of {', '.join(figures)}, got {kind!r}")
        if kind == "orbits":
            return self.plot_orbits(None, path, nondimensional, title)
        return figures[kind](path, nondimensional, title)


def analyse_run_up(
    result: RunUpResult,
    bearing: BearingParameters,
    window: float = 256.0,
    critical_bearing_number: float | None = None,
    whirl_threshold: float = WHIRL_THRESHOLD,
) -> RunUpAnalysis:
    """The :class:`RunUpAnalysis` of a run-up: its envelopes and waterfall over windows of ``window`` tau.

    Raises:
        ValueError: a run shorter than one waterfall window or with fewer than 2 samples.
    """
    window = check_positive("window", window)
    return RunUpAnalysis(
        result,
        bearing,
        window,
        envelopes(result, window),
        waterfall(result, window),
        critical_bearing_number,
        check_positive("whirl_threshold", whirl_threshold),
    )
