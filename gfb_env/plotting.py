"""The figures of the analysis results (Agg backend, no screen needed): public, so a Python user draws what
the ``gfb`` command draws.  Each function returns its :class:`matplotlib.figure.Figure`; given a ``path`` it
saves the figure there and closes it.  The results call them from their ``plot()`` methods
(:meth:`gfb_env.analysis.campbell.CampbellDiagram.plot`, :meth:`gfb_env.analysis.runup.RunUpAnalysis.plot`,
:meth:`gfb_env.analysis.response.ResponseCurve.plot`, :meth:`gfb_env.analysis.schedule.RunUpSchedule.plot`).
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import TYPE_CHECKING

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.figure import Figure  # noqa: E402

from gfb_env.integrator import Trajectory  # noqa: E402

if TYPE_CHECKING:
    from gfb_env.analysis.campbell import CampbellDiagram
    from gfb_env.analysis.response import ResponseCurve, UnbalanceResponse
    from gfb_env.analysis.runup import RunUpResult, Waterfall
    from gfb_env.analysis.schedule import RunUpSchedule
    from gfb_env.params import BearingParameters

__all__ = [
    "plot_campbell",
    "plot_orbits",
    "plot_response",
    "plot_run_up_envelope",
    "plot_schedule",
    "plot_simulation",
    "plot_waterfall",
    "plt",
]


def _finish(fig: Figure, path: str | Path | None, dpi: int) -> Figure:
    """Save ``fig`` to ``path`` and close it (matplotlib keeps open figures alive), or return it open."""
    if path is not None:
        fig.savefig(path, dpi=dpi)
        plt.close(fig)
    return fig


def plot_simulation(tr: Trajectory, path: str | Path | None = None, title: str = "") -> Figure:
    """Orbit in the clearance circle (left) and xi, eta, min film, P(0, 0) over tau (right)."""
    fig = plt.figure(figsize=(11, 5.5), constrained_layout=True)
    gs = fig.add_gridspec(3, 2, width_ratios=[1, 1.6])
    ax = fig.add_subplot(gs[:, 0])
    th = np.linspace(0, 2 * np.pi, 200)
    ax.plot(np.sin(th), np.cos(th), "k--", lw=0.8, label="clearance circle")
    ax.plot(tr.xi, tr.eta, lw=0.6, color="tab:red")
    ax.plot(tr.xi[:1], tr.eta[:1], "o", color="tab:blue", label="start")
    ax.plot(tr.xi[-1:], tr.eta[-1:], "s", color="k", label="end")
    ax.set_aspect("equal")
    ax.invert_yaxis()  # eta points down, along gravity
    ax.set_xlabel(r"$\xi$ (horizontal, units of C)")
    ax.set_ylabel(r"$\eta$ (vertical, down, units of C)")
    ax.legend(loc="upper right", fontsize=8)
    ax.set_title("journal orbit")
    a1 = fig.add_subplot(gs[0, 1])
    a1.plot(tr.tau, tr.xi, lw=0.6, color="tab:red", label=r"$\xi$")
    a1.plot(tr.tau, tr.eta, lw=0.6, color="tab:blue", label=r"$\eta$")
    a1.set_ylabel("position")
    a1.legend(loc="upper left", fontsize=8)
    a2 = fig.add_subplot(gs[1, 1], sharex=a1)
    a2.plot(tr.tau, tr.min_film_thickness, lw=0.6, color="k")
    a2.set_ylabel(r"min $H$")
    a3 = fig.add_subplot(gs[2, 1], sharex=a1)
    if tr.probes.shape[1]:
        a3.plot(tr.tau, tr.probes[:, 0], lw=0.6, color="tab:green")
    a3.set_ylabel(r"$P(0,0)$")
    a3.set_xlabel(r"$\tau$")
    if title:
        fig.suptitle(title)
    return _finish(fig, path, 110)


def plot_campbell(
    cd: CampbellDiagram, path: str | Path | None = None, nondimensional: bool = False
) -> Figure:
    """The Campbell diagram (rotor-mode frequencies over speed with the 1x and 0.5x lines, unstable points
    in red) above the log decrement (with the onset): ``gfb campbell``'s ``campbell.png``.  Physical
    units (rpm, Hz) unless ``nondimensional`` (Lambda, rad per unit tau)."""

    if nondimensional:
        x, xl = cd.bearing_number, r"bearing number $\Lambda$"
        y, yl = cd.eigenvalues.imag, r"whirl frequency $\mathrm{Im}\,\lambda$ (rad per unit $\tau$)"
        one_x = cd.bearing_number
        x_on = cd.onset_bearing_number
    else:
        x, xl = cd.speed_rpm, "rotor speed (rpm)"
        y, yl = cd.frequency_hz, "damped natural frequency (Hz)"
        one_x = cd.speed_rpm / 60.0
        x_on = cd.onset_speed_rpm
    delta = cd.log_decrement
    fig, (a1, a2) = plt.subplots(2, 1, figsize=(8, 7.5), sharex=True, constrained_layout=True)
    colours = ["tab:blue", "tab:orange", "tab:green", "tab:purple", "tab:brown", "tab:pink"]
    for k in range(y.shape[1]):
        a1.plot(x, y[:, k], "-", color=colours[k], lw=1.5, label=f"rotor mode {k + 1}")
        bad = delta[:, k] < 0
        a1.plot(x[bad], y[bad, k], "o", ms=4, color="tab:red", label="unstable" if k == 0 else None)
        a2.plot(x, delta[:, k], "-", color=colours[k], lw=1.5, label=f"rotor mode {k + 1}")
    a1.plot(x, one_x, "k--", lw=1, label="1x (synchronous)")
    a1.plot(x, 0.5 * one_x, "k:", lw=1, label="0.5x")
    top = np.nanmax(y[:, 0]) if np.isfinite(y[:, 0]).any() else 1.0
    a1.set_ylim(0, 2.2 * top)
    a1.set_ylabel(yl)
    a1.legend(fontsize=8, loc="upper left")
    a1.grid(alpha=0.3)
    a1.set_title(
        f"Campbell diagram: {cd.structure} foil, K_W={cd.foil_stiffness:.3g}, D_W={cd.foil_damping:.3g}, "
        f"grid {cd.grid}",
        fontsize=10,
    )
    a2.axhline(0, color="k", lw=0.8)
    fin = delta[np.isfinite(delta)]
    if fin.size:
        a2.set_ylim(max(fin.min(), -3) - 0.3, min(fin.max(), 8) + 0.3)
    if x_on is not None:
        lab = f"onset {x_on:.4f}" if nondimensional else f"critical speed {x_on:.0f} rpm"
        for a in (a1, a2):
            a.axvline(x_on, color="tab:red", lw=1, ls="-.")
        a2.plot([x_on], [0], "o", color="tab:red", label=lab)
    a2.set_ylabel(r"logarithmic decrement $\delta = -2\pi\,\mathrm{Re}\lambda/\mathrm{Im}\lambda$")
    a2.set_xlabel(xl)
    a2.legend(fontsize=8, loc="upper right")
    a2.grid(alpha=0.3)
    return _finish(fig, path, 90)


def plot_response(
    curve: ResponseCurve, at: UnbalanceResponse | None = None, path: str | Path | None = None
) -> Figure:
    """The unbalance response over speed (Bode plot: amplitudes in um, phase lags; the orbit's
    semi-axes), the point ``at`` marked (default: the curve's peak): ``gfb response``'s ``response.png``."""
    at = curve.peak if at is None else at
    rows = np.array(curve.rows())
    bearing, unbalance = curve.bearing, curve.unbalance

    rpm = rows[:, 0]
    stable = rows[:, 9] > 0
    fig, axs = plt.subplots(3, 1, figsize=(8, 9), sharex=True, constrained_layout=True)
    for ax in axs:
        if not stable.all():
            ax.axvspan(rpm[~stable].min(), rpm.max(), color="0.9", label="unstable equilibrium")
    ax = axs[0]
    ax.semilogy(rpm, rows[:, 11], label=r"$\xi$ (horizontal)")
    ax.semilogy(rpm, rows[:, 12], label=r"$\eta$ (vertical)")
    ax.plot(bearing.speed_rpm_at(at.bearing_number), bearing.micrometres(at.eta_amplitude), "ko", ms=4)
    ax.set_ylabel("amplitude, 0-peak (um)")
    ax.legend(fontsize=8)
    ax.set_title(
        f"unbalance response, {curve.structure} foil, K_W={curve.foil_stiffness:.3g}, "
        f"U={unbalance.magnitude:.3g} ({bearing.micrometres(unbalance.magnitude):.3g} um)"
    )
    ax = axs[1]
    ax.plot(rpm, rows[:, 4], label=r"$\xi$")
    ax.plot(rpm, rows[:, 5], label=r"$\eta$")
    ax.set_ylabel("phase lag behind the\nunbalance force (deg)")
    ax.legend(fontsize=8)
    ax = axs[2]
    ax.plot(rpm, rows[:, 13], label="semi-major")
    ax.plot(rpm, rows[:, 14], label="semi-minor")
    back = rows[:, 8] == 0
    if back.any():
        ax.plot(rpm[back], rows[back, 13], "rx", ms=4, label="backward whirl")
    ax.set_ylabel("orbit semi-axes (um)")
    ax.set_xlabel("speed (rpm)")
    ax.legend(fontsize=8)
    return _finish(fig, path, 80)


def plot_waterfall(
    wf: Waterfall,
    bearing: BearingParameters,
    path: str | Path | None = None,
    nondimensional: bool = False,
    title: str = "",
    dominant_order: float | None = None,
) -> Figure:
    """Waterfall of the spectra of xi over speed (run-up and coast-down side by side) with the 1x and
    0.43x lines: ``gfb runup``'s ``waterfall.png``."""
    b, nondim, ratio = bearing, nondimensional, dominant_order

    legs = [leg for leg in (0, 1) if (wf.leg == leg).any()]
    fig, axes = plt.subplots(
        1, len(legs), figsize=(6 * len(legs), 6.5), squeeze=False, constrained_layout=True
    )
    hz = 1.0 / (2 * math.pi * b.time_scale_s)
    x = wf.omega if nondim else wf.omega * hz
    speeds = wf.bearing_number if nondim else np.array([b.speed_rpm_at(v) for v in wf.bearing_number])
    amp = wf.amplitude * (1.0 if nondim else b.clearance_m * 1e6)
    # at most 40 spectra a leg, the tallest peak 4 line spacings high
    n_lines = min(40, max(int(np.sum(wf.leg == leg)) for leg in legs))
    step = (speeds.max() - speeds.min()) / max(n_lines - 1, 1) if len(speeds) > 1 else 1.0
    scale = 4 * step / max(float(amp[:, 1:].max()), 1e-12)
    fmax = 1.6 * (speeds.max() if nondim else speeds.max() / 60.0)
    for ax, leg in zip(axes[0], legs):
        idx = np.nonzero(wf.leg == leg)[0]
        idx = idx[np.unique(np.linspace(0, len(idx) - 1, min(len(idx), 40)).astype(int))]
        for j in idx[::-1] if leg == 0 else idx:
            ax.fill_between(x, speeds[j], speeds[j] + scale * amp[j], color="white", zorder=j)
            ax.plot(x, speeds[j] + scale * amp[j], color="k", lw=0.6, zorder=j)
        sp = np.array([speeds.min(), speeds.max()])
        f1 = sp if nondim else sp / 60.0
        ax.plot(f1, sp, "r--", lw=1, label="1x", zorder=10_000)
        ax.plot(0.43 * f1, sp, "b--", lw=1, label="0.43x", zorder=10_000)
        ax.set_xlim(0, fmax)
        ax.set_xlabel(r"angular frequency $\omega$ (rad per unit $\tau$)" if nondim else "frequency (Hz)")
        ax.set_ylabel(r"$\Lambda$" if nondim else "rotor speed (rpm)")
        ax.set_title(
            ("run-up" if leg == 0 else "coast-down")
            + ("" if ratio is None else f" (dominant at top: {ratio:.2f}x)"),
            fontsize=9,
        )
        ax.legend(loc="lower right", fontsize=8)
    unit = "C" if nondim else "um"
    fig.suptitle(f"Waterfall of xi ({unit}, Hann windows): {title}", fontsize=10)
    return _finish(fig, path, 80)


def plot_orbits(
    res: RunUpResult,
    bearing: BearingParameters,
    orbit_rpm: list[float],
    window: float,
    path: str | Path | None = None,
    nondimensional: bool = False,
    title: str = "",
) -> Figure:
    """Orbits on the run-up at the speeds ``orbit_rpm`` (``window`` tau each): ``gfb runup``'s
    ``orbits.png``."""
    b, nondim = bearing, nondimensional

    tr = res.trajectory
    rpm = np.array([b.speed_rpm_at(v) for v in tr.bearing_number])
    up = res.leg == 0
    c = 1.0 if nondim else b.clearance_m * 1e6
    n = len(orbit_rpm)
    fig, axes = plt.subplots(1, n, figsize=(3.2 * n, 3.6), squeeze=False, constrained_layout=True)
    th = np.linspace(0, 2 * np.pi, 200)
    dt = float(tr.tau[1] - tr.tau[0])
    half = max(2, int(window / dt / 2))
    for ax, v in zip(axes[0], orbit_rpm):
        j = int(np.argmin(np.where(up, np.abs(rpm - v), np.inf)))
        i = slice(max(0, j - half), j + half)
        ax.plot(c * np.sin(th), c * np.cos(th), "k--", lw=0.7)
        ax.plot(c * tr.xi[i], c * tr.eta[i], lw=0.7, color="tab:red")
        ax.set_aspect("equal")
        ax.invert_yaxis()
        ax.set_title(f"Lambda={tr.bearing_number[j]:.3f}" if nondim else f"{rpm[j]:.0f} rpm", fontsize=9)
        ax.set_xlabel(r"$\xi$ (C)" if nondim else "x (um)")
    axes[0][0].set_ylabel(r"$\eta$ (C, down)" if nondim else "y (um, down)")
    fig.suptitle(f"Orbits on the run-up ({window:g} tau each): {title}", fontsize=9)
    return _finish(fig, path, 80)


def plot_run_up_envelope(
    env: dict[str, np.ndarray],
    bearing: BearingParameters,
    path: str | Path | None = None,
    nondimensional: bool = False,
    title: str = "",
    critical_bearing_number: float | None = None,
    synchronous: bool = False,
) -> Figure:
    """The paper's Fig. 5 from the window envelopes (:func:`gfb_env.analysis.runup.envelopes`): speed, xi
    and eta envelopes over time, and the whirl amplitude over speed with the linear critical speed (and,
    with ``synchronous``, the order-tracked 1x amplitudes): ``gfb runup``'s ``envelope.png``."""
    b, nondim, lam_c, sync = bearing, nondimensional, critical_bearing_number, synchronous

    c = 1.0 if nondim else b.clearance_m * 1e6
    t = env["tau"] if nondim else env["tau"] * b.time_scale_s
    sp = env["bearing_number"] if nondim else np.array([b.speed_rpm_at(v) for v in env["bearing_number"]])
    fig, ax = plt.subplots(4, 1, figsize=(8, 9), constrained_layout=True)
    ax[0].plot(t, sp, "k-")
    ax[0].set_ylabel(r"$\Lambda$" if nondim else "speed (rpm)")
    for a, name, col in ((ax[1], "xi", "tab:red"), (ax[2], "eta", "tab:blue")):
        a.plot(t, c * env[f"{name}_min"], color=col, lw=0.9)
        a.plot(t, c * env[f"{name}_max"], color=col, lw=0.9)
        a.set_ylabel(
            (f"$\\{name}$ envelope (C)") if nondim else f"{'x' if name == 'xi' else 'y'} envelope (um)"
        )
    for a in ax[:3]:
        a.sharex(ax[0])
        a.grid(alpha=0.3)
    ax[2].set_xlabel(r"$\tau$" if nondim else "time (s)")
    amp = env["whirl"] * c
    for leg, style, lab in ((0, "-", "run-up"), (1, "--", "coast-down")):
        m = env["leg"] == leg
        if m.any():
            ax[3].plot(sp[m], amp[m], "k" + style, lw=1.2, label=lab + (" (non-synchronous)" if sync else ""))
            if sync:  # the order-tracked 1x response beside the whirl
                ax[3].plot(sp[m], c * env["sync_xi"][m], "tab:red", ls=style, lw=1, label=f"1x x, {lab}")
                ax[3].plot(sp[m], c * env["sync_eta"][m], "tab:blue", ls=style, lw=1, label=f"1x y, {lab}")
    if lam_c is not None:
        xc = lam_c if nondim else b.speed_rpm_at(lam_c)
        lab = f"linear onset Lambda_c = {xc:.4f}" if nondim else f"linear critical speed {xc:.0f} rpm"
        ax[3].axvline(xc, color="tab:red", ls="-.", lw=1, label=lab)
    ax[3].set_xlabel(r"$\Lambda$" if nondim else "speed (rpm)")
    ax[3].set_ylabel("amplitude (C)" if nondim else "amplitude (um)")
    if sync:
        ax[3].set_yscale("log")  # the 1x orbit (~um) beside a whirl (~C)
    ax[3].legend(fontsize=8)
    ax[3].grid(alpha=0.3)
    fig.suptitle(f"Run-up envelopes (paper Fig. 5): {title}", fontsize=10)
    return _finish(fig, path, 80)


def plot_schedule(sch: RunUpSchedule, path: str | Path | None = None) -> Figure:
    """The schedule on the stability map: the critical speed over D_W with the margin, the fold of
    cycles (the hysteresis band shaded), the ramp at the chosen damping and the target: ``gfb
    schedule``'s ``schedule.png``."""
    b = sch.model.bearing
    krpm = np.vectorize(lambda lam: b.speed_rpm_at(lam) / 1000.0 if np.isfinite(lam) else np.nan)
    fig, ax = plt.subplots(figsize=(6.4, 4.2))
    ax.semilogx(sch.dampings, krpm(sch.critical_bearing_numbers), "k.-", label="critical speed (Lambda_c)")
    ax.semilogx(
        sch.dampings,
        krpm((1 - sch.margin) * sch.critical_bearing_numbers),
        "k:",
        lw=0.8,
        label=f"{sch.margin:.0%} margin",
    )
    if len(sch.fold_dampings):
        ax.semilogx(sch.fold_dampings, krpm(sch.fold_bearing_numbers), "rs", label="fold of cycles")
        ok = np.isfinite(sch.fold_bearing_numbers)
        for d, f in zip(sch.fold_dampings[ok], sch.fold_bearing_numbers[ok], strict=True):
            lc = float(np.interp(np.log(d), np.log(sch.dampings), sch.critical_bearing_numbers))
            ax.fill_between([d / 1.08, d * 1.08], krpm(f), krpm(lc), color="r", alpha=0.2, lw=0)
    d = sch.foil_damping
    curves = krpm(np.r_[sch.critical_bearing_numbers, (1 - sch.margin) * sch.critical_bearing_numbers])
    lo = float(np.nanmin(np.r_[curves, krpm(sch.end_bearing_number)])) * 0.97
    hi = float(np.nanmax(curves)) * 1.01
    ax.set_ylim(lo, hi)
    start = float(krpm(sch.start_bearing_number))
    ax.annotate(
        "",
        xy=(d, krpm(sch.end_bearing_number)),
        xytext=(d, max(start, lo)),
        arrowprops={"arrowstyle": "->", "color": "b", "lw": 2},
    )
    ax.text(d * 1.1, lo + 0.02 * (hi - lo), f"ramp from {start:.1f} krpm", color="b", fontsize=8)
    ax.plot([d], [krpm(sch.end_bearing_number)], "bo", label="schedule (ramp at D_W, hold)")
    ax.axhline(float(krpm(sch.target_bearing_number)), color="b", ls="--", lw=0.8, label="target")
    ax.set(
        xlabel="foil damping D_W",
        ylabel="speed (krpm)",
        title=f"run-up schedule: {'feasible' if sch.feasible else 'target infeasible'}, "
        f"K_W = {sch.model.foil_stiffness:.3g}, {sch.model.grid}",
    )
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=7, loc="lower left")
    fig.tight_layout()
    return _finish(fig, path, 100)
