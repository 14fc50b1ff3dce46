"""Matplotlib figures shared by the CLI and the experiments (Agg backend, no screen needed)."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from gfb_env.integrator import Trajectory  # noqa: E402


def plot_simulation(tr: Trajectory, path: str | Path, title: str = "") -> None:
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
    fig.savefig(path, dpi=110)
    plt.close(fig)
