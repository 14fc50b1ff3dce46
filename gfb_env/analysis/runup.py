"""Transient run-up (and coast-down) at a constant acceleration, and its waterfall (issue 12).

The speed ramps linearly in time: ``Lambda(tau) = Lambda_1 + r tau`` with the bearing-number rate
``r = dLambda/dtau = alpha (2 pi / 60) T^2`` for an acceleration ``alpha`` in rpm/s (``T`` the time
scale of the bearing).  :meth:`TrapezoidalIntegrator.advance` ramps Lambda linearly within each call,
so the run is integrated in chunks whose end values lie on the ramp (the ramp is exact, the chunks
only bound the memory of one call).  The journal starts at the static equilibrium of the first speed,
displaced by ``perturbation`` (units of C) so that the whirl has a seed to grow from once the
equilibrium loses stability (without one, only round-off would seed it).

Extension point (unbalance): the rotor equations have no forcing term yet.  When the forcing module
of the realism issue provides the unbalance (a 1x force ``m e Omega^2``), :func:`run_up` is where it
enters (one more argument passed to the integrator); the waterfall then shows the 1x line's response
and nothing else here changes.

The waterfall is the Hann-windowed amplitude spectrum (:func:`gfb_env.analysis.spectrum.amplitude_spectrum`)
of the linearly detrended ``xi`` over consecutive windows of ``window`` tau, each labelled by its mean
speed.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

from gfb_env.analysis.spectrum import amplitude_spectrum
from gfb_env.equilibrium import find_equilibrium
from gfb_env.integrator import Trajectory, TrapezoidalIntegrator
from gfb_env.model import GFBModel
from gfb_env.params import check_positive

__all__ = ["RunUpResult", "Waterfall", "bearing_number_rate", "run_up", "waterfall", "envelopes"]


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
    """

    trajectory: Trajectory
    leg: np.ndarray
    status: str
    message: str
    tau_ramp: float
    steps: int
    wall_time_s: float
    touchdown_tau: float | None = None


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
) -> RunUpResult:
    """Integrate ``Lambda`` from ``bearing_range[0]`` to ``[1]`` at ``rate`` per tau (and back with
    ``coast_down``), recording the rotor every ``record_interval``; stops at touchdown."""
    lo, hi = float(bearing_range[0]), float(bearing_range[1])
    if not (math.isfinite(lo) and math.isfinite(hi) and 0 < lo < hi):
        raise ValueError(f"bearing_range must satisfy 0 < min < max, got {bearing_range!r}")
    rate = check_positive("rate", rate)
    tau_ramp = (hi - lo) / rate
    s = find_equilibrium(model, lo)
    L = model.layout
    s = L.with_rotor(s, *(L.rotor(s)[:2] + np.asarray(perturbation, dtype=float)), 0.0, 0.0)
    integ = TrapezoidalIntegrator(model, s, lo, foil_damping, touchdown_film_thickness=touchdown)
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
            # (unbalance enters here once the forcing module exists: see the module docstring)
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
    return RunUpResult(
        trajectory=Trajectory.concatenate(parts),
        leg=np.concatenate(legs),
        status=status,
        message=message,
        tau_ramp=tau_ramp,
        steps=steps,
        wall_time_s=time.perf_counter() - t0,
        touchdown_tau=t_touch,
    )


def envelopes(res: RunUpResult, window: float) -> dict[str, np.ndarray]:
    """Per window of ``window`` tau (within one leg): mean tau and Lambda, leg, min/max of xi and eta,
    max eccentricity, min film thickness."""
    tr = res.trajectory
    if len(tr) < 2:
        raise ValueError("the run recorded fewer than 2 samples")
    dt = float(tr.tau[1] - tr.tau[0])
    n_win = max(2, int(round(window / dt)))
    keys = ("tau", "bearing_number", "leg", "xi_min", "xi_max", "eta_min", "eta_max", "eps_max", "hmin")
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
    return {k: np.asarray(v) for k, v in rows.items()}


@dataclass
class Waterfall:
    """Amplitude spectra of ``xi`` over consecutive windows: ``omega`` (rad per unit tau, shape (m,)),
    ``amplitude`` (units of C, shape (k, m)), and per window its mean ``bearing_number`` and ``leg``."""

    omega: np.ndarray
    amplitude: np.ndarray
    bearing_number: np.ndarray
    leg: np.ndarray


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
