"""A designed run-up schedule for one bearing: which foil damping, how fast, and how high is safe.

The method, for a viscoelastic foil (paper Sect. 3.2-3.4):

1. ``Lambda_c(D_W)`` on a log grid of dampings (:func:`~gfb_env.analysis.task_constants.
   critical_bearing_numbers_on_grid`: one equilibrium per Lambda serves every damping).
2. At the dampings with the highest ``Lambda_c`` the fold of cycles ``Lambda_fold(D_W)`` (shooting and
   continuation, :func:`~gfb_env.analysis.periodic.fold_bearing_number`; where the unstable cycles
   reach contact without folding, the lowest of them: the band's lower edge): below the fold no whirl
   cycle exists; between the fold and ``Lambda_c`` (the hysteresis band) the equilibrium is stable but a
   large enough disturbance or unbalance throws the rotor onto the whirl.
3. The safe speed of a damping is ``min((1 - margin) Lambda_c, Lambda_fold)``: a margin from the linear
   stability boundary *and* outside the hysteresis band (where the fold could not be computed, or
   ``fold_dampings=0``, only the margin applies and the summary says so).  The schedule takes the damping
   with the highest safe speed, ramps at the given acceleration to the target (or, if the target is above
   the safe speed, to the safe speed: the target is reported infeasible) and holds.
4. The schedule is verified by a transient run from the slightly perturbed equilibrium at the start
   speed: ramp, then hold; the largest whirl amplitude in the hold and the smallest film thickness of the
   whole run are reported.  With an unbalance (:class:`gfb_env.forcing.Unbalance`, on from the start of
   the ramp) the rotor also vibrates at 1x; the last window of the hold is then split by least squares
   into the synchronous orbit (``c + a cos theta - b sin theta`` per coordinate, the convention of
   :func:`gfb_env.analysis.response.synchronous_components`) and the rest: the whirl amplitude is the rest
   (does the rotor whirl?), the 1x amplitudes and the total vibration are reported beside it.
"""

from __future__ import annotations

import csv
import math
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from gfb_env.analysis.maps import optimum_from_curve
from gfb_env.analysis.periodic import ShootingError, fold_bearing_number
from gfb_env.analysis.response import synchronous_components
from gfb_env.analysis.stability import StabilityAnalysisError, critical_bearing_number
from gfb_env.analysis.task_constants import critical_bearing_numbers_on_grid
from gfb_env.equilibrium import find_equilibrium
from gfb_env.forcing import Unbalance
from gfb_env.integrator import TrapezoidalIntegrator
from gfb_env.model import GFBModel, Structure
from gfb_env.params import check_positive

if TYPE_CHECKING:
    from matplotlib.figure import Figure

__all__ = [
    "STABLE_WHIRL_AMPLITUDE",
    "RunUpSchedule",
    "ScheduleVerification",
    "design_run_up_schedule",
    "verify_schedule",
]

#: The verified run counts as stable when its non-synchronous motion over the last 500 tau of the hold
#: stays below this (units of C): the environments' stability threshold; a developed whirl is 0.3-1.2 C,
#: the decaying start perturbation and the equilibrium's drift are orders of magnitude smaller.
STABLE_WHIRL_AMPLITUDE = 0.05


@dataclass(frozen=True)
class ScheduleVerification:
    """A transient run of a schedule (units of C unless named).

    Attributes:
        status: the integrator's end status (``done``, ``touchdown`` or ``failed``).
        max_whirl_amplitude: half the largest peak-to-peak of xi or eta over the last window of the
            hold; with an unbalance, of xi and eta minus their fitted 1x orbit (the non-synchronous
            motion: the whirl, or what is left of the start's perturbation).
        min_film_thickness: smallest film thickness over the whole run.
        max_eccentricity: largest eccentricity over the whole run.
        tau: rotor time simulated; steps: integrator steps; wall_time_s: wall time.
        unbalance: U of the run (0: none).
        synchronous_xi, synchronous_eta: zero-to-peak 1x amplitudes over the last window (0 without an
            unbalance).
        max_vibration_amplitude: half the largest peak-to-peak of xi or eta over the last window, 1x
            included (equal to ``max_whirl_amplitude`` without an unbalance).
    """

    status: str
    max_whirl_amplitude: float
    min_film_thickness: float
    max_eccentricity: float
    tau: float
    steps: int
    wall_time_s: float
    unbalance: float = 0.0
    synchronous_xi: float = 0.0
    synchronous_eta: float = 0.0
    max_vibration_amplitude: float = math.nan

    @property
    def stable(self) -> bool:
        """The run went to its end and its whirl stayed below :data:`STABLE_WHIRL_AMPLITUDE`."""
        return self.status == "done" and self.max_whirl_amplitude < STABLE_WHIRL_AMPLITUDE


@dataclass(frozen=True)
class RunUpSchedule:
    """A designed run-up (see the module docstring).  Speeds in Lambda; :meth:`path` in physical units.

    Attributes:
        model: the viscoelastic plant it was designed for.
        dampings, critical_bearing_numbers: the stability curve ``Lambda_c(D_W)``.
        fold_dampings, fold_bearing_numbers: where the fold was computed (NaN: no fold found).
        foil_damping: the chosen D_W; critical_bearing_number and fold_bearing_number there.
        margin: relative margin below ``Lambda_c``.
        safe_bearing_number: ``min((1 - margin) Lambda_c, Lambda_fold)`` at the chosen damping.
        target_bearing_number: asked for; end_bearing_number: where the schedule goes (the target or,
            if infeasible, the safe speed); start_bearing_number: where it starts.
        feasible: the target is at or below the safe speed.
        rate: ramp in dLambda/dtau; hold_tau: hold at the end speed.
        notes: what the design could not establish.
    """

    model: GFBModel
    dampings: np.ndarray
    critical_bearing_numbers: np.ndarray
    fold_dampings: np.ndarray
    fold_bearing_numbers: np.ndarray
    foil_damping: float
    critical_bearing_number: float
    fold_bearing_number: float
    margin: float
    safe_bearing_number: float
    target_bearing_number: float
    end_bearing_number: float
    start_bearing_number: float
    feasible: bool
    rate: float
    hold_tau: float
    notes: tuple[str, ...] = field(default=())

    @property
    def ramp_tau(self) -> float:
        return (self.end_bearing_number - self.start_bearing_number) / self.rate

    @property
    def margin_to_critical(self) -> float:
        """``1 - Lambda_end / Lambda_c`` at the chosen damping."""
        return 1.0 - self.end_bearing_number / self.critical_bearing_number

    @property
    def margin_to_fold(self) -> float | None:
        """``1 - Lambda_end / Lambda_fold`` (``None``: no fold known at the chosen damping)."""
        if not math.isfinite(self.fold_bearing_number):
            return None
        return 1.0 - self.end_bearing_number / self.fold_bearing_number

    def speed_rpm(self, bearing_number: float) -> float | None:
        """The speed (rpm) of a bearing number of this schedule (``None`` for NaN: not found)."""
        return self.model.bearing.speed_rpm_at(bearing_number) if math.isfinite(bearing_number) else None

    def stability_curve(self) -> list[tuple[float, float | None, float | None]]:
        """``(foil_damping, critical_speed_rpm, fold_speed_rpm)`` at each damping of the design (the fold
        only where it was computed and found)."""
        fold_of = dict(zip(self.fold_dampings.tolist(), self.fold_bearing_numbers.tolist(), strict=True))
        return [
            (float(d), self.speed_rpm(lc), self.speed_rpm(fold_of.get(float(d), math.nan)))
            for d, lc in zip(self.dampings, self.critical_bearing_numbers, strict=True)
        ]

    def write_path_csv(self, path: str | Path) -> Path:
        """:meth:`path` as ``time_s, speed_rpm, foil_damping`` (``gfb schedule``'s ``schedule.csv``)."""
        path, p = Path(path), self.path()
        with path.open("w", newline="") as fh:
            w = csv.writer(fh)
            w.writerow(["time_s", "speed_rpm", "foil_damping"])
            for row in zip(p["time_s"], p["speed_rpm"], p["foil_damping"], strict=True):
                w.writerow([f"{x:.8g}" for x in row])
        return path

    def write_stability_curve_csv(self, path: str | Path) -> Path:
        """:meth:`stability_curve` (``gfb schedule``'s ``stability_curve.csv``; empty cells: none)."""
        path = Path(path)
        with path.open("w", newline="") as fh:
            w = csv.writer(fh)
            w.writerow(["foil_damping", "critical_speed_rpm", "fold_speed_rpm"])
            for d, *cells in self.stability_curve():
                w.writerow([f"{d:.6g}"] + ["" if c is None else f"{c:.1f}" for c in cells])
        return path

    def plot(self, path: str | Path | None = None) -> Figure:
        """The schedule on the stability map (:func:`gfb_env.plotting.plot_schedule`)."""
        from gfb_env.plotting import plot_schedule

        return plot_schedule(self, path)

    def path(self, n: int = 101) -> dict[str, np.ndarray]:
        """The schedule sampled at ``n`` points: ``time_s``, ``speed_rpm``, ``foil_damping``."""
        b = self.model.bearing
        tau = np.linspace(0.0, self.ramp_tau + self.hold_tau, n)
        lam = np.minimum(self.start_bearing_number + self.rate * tau, self.end_bearing_number)
        return {
            "time_s": np.array([b.seconds(t) for t in tau]),
            "speed_rpm": np.array([b.speed_rpm_at(x) for x in lam]),
            "foil_damping": np.full(n, self.foil_damping),
        }


def design_run_up_schedule(
    model: GFBModel,
    target_bearing_number: float,
    margin: float = 0.05,
    rate: float = 2e-5,
    start_bearing_number: float | None = None,
    damping_range: tuple[float, float] = (0.1, 10.0),
    n_dampings: int = 13,
    fold_dampings: int = 3,
    hold_tau: float = 2000.0,
    lam_step: float = 0.01,
) -> RunUpSchedule:
    """Design the schedule (module docstring).  ``fold_dampings``: at how many of the dampings with the
    highest ``Lambda_c`` the fold is computed (0: none; each costs a shooting continuation, seconds
    on 31x7 to a minute on 79x7)."""
    if model.structure is not Structure.VISCOELASTIC:
        raise ValueError(
            f"structure must be viscoelastic (D_W is the design variable), got {model.structure}"
        )
    lam_t = check_positive("target_bearing_number", target_bearing_number)
    if not (math.isfinite(margin) and 0 <= margin < 0.5):
        raise ValueError(f"margin must lie in [0, 0.5), got {margin!r}")
    rate = check_positive("rate", rate)
    check_positive("hold_tau", hold_tau)
    dmin, dmax = (check_positive("damping_range", d) for d in damping_range)
    if not dmin < dmax:
        raise ValueError(f"damping_range must satisfy 0 < min < max, got {damping_range!r}")
    if not 3 <= n_dampings <= 60:
        raise ValueError(f"n_dampings must lie in [3, 60], got {n_dampings!r}")
    if not 0 <= fold_dampings <= n_dampings:
        raise ValueError(f"fold_dampings must lie in [0, n_dampings], got {fold_dampings!r}")
    notes: list[str] = []
    ds = np.geomspace(dmin, dmax, n_dampings)
    lam_lo = 0.5 * lam_t if start_bearing_number is None else 0.9 * start_bearing_number
    lam_hi = max(2.0, 2 * lam_t)
    lc = critical_bearing_numbers_on_grid(model, ds, lam_min=lam_lo, lam_max=lam_hi, lam_step=lam_step)
    if np.all(np.isnan(lc)):
        raise ValueError(
            f"the equilibrium is stable for every damping up to Lambda = {lam_hi:g}: no design needed"
        )
    lc_fill = np.where(np.isnan(lc), np.inf, lc)
    # the fold at the most promising dampings (highest Lambda_c), each with its refined Lambda_c
    order = np.argsort(-lc_fill)[:fold_dampings]
    fd, fl, crit = [], [], {}
    for j in sorted(order):
        d = float(ds[j])
        try:
            cp = critical_bearing_number(model, d, bearing_range=(lam_lo, lam_hi))
            crit[j] = cp.critical_bearing_number
            fr = fold_bearing_number(model, d, critical=crit[j])
            # the band's lower edge: the fold, or where the unstable cycles reach contact (no fold)
            band = fr.band_lower_bearing_number
            fold = band if band < crit[j] else None
        except (ShootingError, StabilityAnalysisError) as exc:
            notes.append(f"fold at D_W={d:.3g} not found ({type(exc).__name__}: {exc})")
            fold = None
        fd.append(d)
        fl.append(math.nan if fold is None else float(fold))
    fold_at = dict(zip(fd, fl, strict=True))

    def safe(j: int) -> float:
        lam_c = crit.get(j, float(lc_fill[j]))
        s = (1.0 - margin) * lam_c
        f = fold_at.get(float(ds[j]), math.nan)
        return min(s, f) if math.isfinite(f) else s

    if fold_dampings:
        best = max(order, key=safe)
    else:
        d_opt, _ = optimum_from_curve(ds, lc)
        best = int(np.argmin(np.abs(np.log(ds / d_opt))))
        notes.append(
            "no fold computed: only the margin from Lambda_c applies, the hysteresis band is unknown"
        )
    d_star = float(ds[best])
    lam_c = crit.get(best, float(lc_fill[best]))
    fold = fold_at.get(d_star, math.nan)
    if fold_dampings and not math.isfinite(fold):
        notes.append(
            f"no fold of cycles at the chosen D_W={d_star:.3g}: only the margin from Lambda_c applies"
        )
    lam_safe = safe(best)
    feasible = lam_t <= lam_safe
    lam_end = lam_t if feasible else lam_safe
    lam0 = 0.5 * lam_end if start_bearing_number is None else float(start_bearing_number)
    if not 0 < lam0 < lam_end:
        raise ValueError(f"the start speed must lie below the end speed {lam_end:.4g}, got {lam0!r}")
    return RunUpSchedule(
        model=model,
        dampings=ds,
        critical_bearing_numbers=lc,
        fold_dampings=np.array(fd),
        fold_bearing_numbers=np.array(fl),
        foil_damping=d_star,
        critical_bearing_number=lam_c,
        fold_bearing_number=fold,
        margin=float(margin),
        safe_bearing_number=lam_safe,
        target_bearing_number=lam_t,
        end_bearing_number=lam_end,
        start_bearing_number=lam0,
        feasible=feasible,
        rate=rate,
        hold_tau=float(hold_tau),
        notes=tuple(notes),
    )


def verify_schedule(
    schedule: RunUpSchedule,
    perturbation: float = 0.01,
    touchdown: float = 0.01,
    window: float = 500.0,
    unbalance: Unbalance | None = None,
) -> ScheduleVerification:
    """Run the schedule: from the equilibrium at the start speed displaced by ``perturbation`` C, ramp
    (Lambda linear in tau) at the chosen damping, then hold; the whirl amplitude is half the largest
    peak-to-peak of xi or eta over the last ``window`` tau of the hold.  ``unbalance``: the rotor's
    unbalance, on from the start (theta = 0); the whirl amplitude is then that of the motion left after
    removing the fitted 1x orbit (module docstring)."""
    if unbalance is not None and not isinstance(unbalance, Unbalance):
        raise ValueError(f"unbalance must be an Unbalance or None, got {type(unbalance).__name__}")
    window = check_positive("window", window)
    model, sch = schedule.model, schedule
    L = model.layout
    s = find_equilibrium(model, sch.start_bearing_number)
    s = L.with_rotor(s, *(L.rotor(s)[:2] + np.array([perturbation, 0.0])), 0.0, 0.0)
    integ = TrapezoidalIntegrator(
        model,
        s,
        sch.start_bearing_number,
        sch.foil_damping,
        touchdown_film_thickness=touchdown,
        unbalance=unbalance,
    )
    lam = sch.end_bearing_number
    # 16 samples a revolution resolve the 1x line (and anything slower) for the fit
    dt_rec = 2.0 * math.pi / (16.0 * lam) if unbalance is not None else None
    sync_xi = sync_eta = 0.0
    t0 = time.perf_counter()
    steps, min_h, max_e = 0, math.inf, 0.0
    res = integ.advance(sch.ramp_tau, bearing_number=sch.end_bearing_number, raise_on_failure=False)
    steps += res.steps
    min_h, max_e = min(min_h, res.min_film_thickness), max(max_e, res.max_eccentricity)
    amp = vib = math.nan
    if res.status == "done":
        hold_end = sch.ramp_tau + sch.hold_tau
        if sch.hold_tau > window:
            res = integ.advance(hold_end - window, raise_on_failure=False)
            steps += res.steps
            min_h, max_e = min(min_h, res.min_film_thickness), max(max_e, res.max_eccentricity)
        if res.status == "done":
            tau0, theta0 = integ.tau, integ.rotation_angle
            res = integ.advance(hold_end, record_interval=dt_rec, raise_on_failure=False)
            steps += res.steps
            min_h, max_e = min(min_h, res.min_film_thickness), max(max_e, res.max_eccentricity)
            amp = 0.5 * max(res.xi_range[1] - res.xi_range[0], res.eta_range[1] - res.eta_range[0])
            vib = amp
            if unbalance is not None and res.status == "done":
                tr = res.trajectory
                theta = theta0 + lam * (tr.tau - tau0)  # constant speed in the hold
                orb = synchronous_components(tr.tau, theta, tr.xi, tr.eta)
                sync_xi, sync_eta = abs(orb.xi), abs(orb.eta)
                rest_xi = tr.xi - (orb.xi.real * np.cos(theta) - orb.xi.imag * np.sin(theta))
                rest_eta = tr.eta - (orb.eta.real * np.cos(theta) - orb.eta.imag * np.sin(theta))
                amp = 0.5 * max(np.ptp(rest_xi), np.ptp(rest_eta))
    return ScheduleVerification(
        status=str(res.status),
        max_whirl_amplitude=float(amp),
        min_film_thickness=float(min_h),
        max_eccentricity=float(max_e),
        tau=integ.tau,
        steps=steps,
        wall_time_s=time.perf_counter() - t0,
        unbalance=0.0 if unbalance is None else unbalance.magnitude,
        synchronous_xi=float(sync_xi),
        synchronous_eta=float(sync_eta),
        max_vibration_amplitude=float(vib),
    )
