"""Rendering of a GFB episode: the orbit in the clearance circle, the midplane pressure, and the speed
and damping history.  Matplotlib is imported only when something is drawn."""

from __future__ import annotations

import numpy as np

from gfb_env.envs.episode import Episode

__all__ = ["EpisodeRenderer"]


class EpisodeRenderer:
    """Draws an :class:`Episode` as an RGB array (``"rgb_array"``) or into a window (``"human"``)."""

    def __init__(self, mode: str, damping_range: tuple[float, float], fps: float):
        self.mode = mode
        self.damping_range = damping_range
        self.fps = fps
        self._fig = None

    def render(self, ep: Episode, state: np.ndarray, tau: float) -> np.ndarray | None:
        if self.mode == "rgb_array":
            from matplotlib.backends.backend_agg import FigureCanvasAgg
            from matplotlib.figure import Figure

            if self._fig is None:
                self._fig = Figure(figsize=(9.6, 3.2), dpi=80)
                FigureCanvasAgg(self._fig)
            self.draw(self._fig, ep, state, tau)
            self._fig.canvas.draw()
            return np.asarray(self._fig.canvas.buffer_rgba())[..., :3].copy()
        import matplotlib.pyplot as plt

        if self._fig is None:
            plt.ion()
            self._fig = plt.figure(figsize=(9.6, 3.2), dpi=80)
        self.draw(self._fig, ep, state, tau)
        self._fig.canvas.draw_idle()
        plt.pause(1.0 / self.fps)
        return None

    def draw(self, fig, ep: Episode, state: np.ndarray, tau: float) -> None:
        model, b = ep.model, ep.bearing
        fig.clf()
        ax1, ax2, ax3 = fig.add_subplot(1, 3, 1), fig.add_subplot(1, 3, 2), fig.add_subplot(1, 3, 3)
        th = np.linspace(0, 2 * np.pi, 200)
        ax1.plot(np.cos(th), np.sin(th), "k-", lw=1)
        ax1.plot(ep.orbit[0], ep.orbit[1], "r-", lw=0.8)
        xi, eta = model.layout.rotor(state)[:2]
        ax1.plot([xi], [eta], "ko", ms=4)
        lim = max(1.2, float(np.nanmax(np.abs(np.r_[ep.orbit[0], ep.orbit[1], 1.0]))) * 1.1)
        ax1.set(
            xlim=(-lim, lim),
            ylim=(lim, -lim),
            aspect="equal",
            xlabel="xi (C)",
            ylabel="eta (C, down)",
            title=f"orbit, H_min={ep.min_film_thickness:.3f}",
        )
        P = model.pressure_field(state)[:, model.grid.n_z // 2]
        phi = np.r_[model.grid.phi, 2 * np.pi]
        ax2.plot(np.degrees(phi), np.r_[P, P[0]], "g-")
        ax2.axhline(1.0, color="k", lw=0.5)
        ax2.set(xlabel="phi (deg)", ylabel="P (midplane)", title=f"tau={tau:.0f} ({b.seconds(tau):.3f} s)")
        h = ep.history
        t = np.array([b.seconds(x) for x in h.tau])
        ax3.plot(t, [b.speed_rpm_at(x) / 1000 for x in h.bearing_number], "b-", label="speed (krpm)")
        ax3.set(xlabel="t (s)", ylabel="speed (krpm)", title=str(ep.termination or ""))
        target = ep.task_info.get("target_speed_rpm")
        if target:
            ax3.axhline(target / 1000, color="b", ls=":", lw=0.8)
        ax4 = ax3.twinx()
        ax4.semilogy(t, h.foil_damping, "m-", label="D_W")
        ax4.set_ylim(*self.damping_range)
        ax4.set_ylabel("D_W", color="m")
        fig.tight_layout()

    def close(self) -> None:
        if self._fig is not None and self.mode == "human":
            import matplotlib.pyplot as plt

            plt.close(self._fig)
        self._fig = None
