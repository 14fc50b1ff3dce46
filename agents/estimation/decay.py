"""The decay meter: the decay rate of the whirl mode after a shock, from the per-step orbit envelope."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

__all__ = ["DecayEvent", "DecayMeter"]


@dataclass
class DecayEvent:
    """An open event of :class:`DecayMeter`: steps since the jump (``k``), the points kept ``(step, ln
    excess, Lambda, commanded damping)``, the previous envelope and the damping of the last step."""

    prev: float
    k: int = 0
    pts: list[tuple[int, float, float, float]] = field(default_factory=list)
    d_last: float | None = None


class DecayMeter:
    """The decay of the whirl mode after a shock, from the per-step orbit envelope.

    Keeps a floor (the quiet envelope: probe noise over ~120 samples plus the 1x unbalance orbit, an
    exponential average over quiet steps); a jump of ``jump`` above it opens an event; from ``skip``
    steps after the jump (the pulse lasts 5-15 ms, one or two steps) the excess ``envelope - floor``
    inside ``[lo, hi]`` (above the noise, below the amplitudes where the decay is visibly nonlinear) is
    fitted by a line in ``ln`` per step, one line per commanded damping in force (the agent may switch
    the damping during an event to measure two rates from one shock; the first point after a switch is
    dropped: the actuator's lag is about one step).  :meth:`update` returns, when an event closes, a list
    of ``(rate per step, mean Lambda, commanded damping, points)`` with at least ``min_points`` points."""

    def __init__(
        self, jump: float = 0.08, lo: float = 0.04, hi: float = 0.6, skip: int = 1, min_points: int = 2
    ):
        self.jump, self.lo, self.hi, self.skip, self.min_points = jump, lo, hi, skip, min_points
        self.floor: float | None = None
        self.event: DecayEvent | None = None

    def open_event(self, envelope: float) -> None:
        """Open an event now (a shock, or a collapsing whirl whose tail decays like a shock's transient)."""
        self.event = DecayEvent(prev=envelope)

    def update(self, envelope: float, lam: float, d_cmd: float) -> list[tuple[float, float, float, int]]:
        """Feed one step's envelope, Lambda and the damping command that was in force over the step."""
        if self.floor is None:
            self.floor = envelope
        if self.event is None:
            if envelope > self.floor + self.jump:
                self.open_event(envelope)
            else:
                self.floor = 0.8 * self.floor + 0.2 * min(envelope, self.floor + 0.02)
            return []
        ev = self.event
        ev.k += 1
        exc = envelope - self.floor
        if ev.k > self.skip and envelope > 1.3 * ev.prev:  # another shock: close, start anew
            res = self._close()
            self.open_event(envelope)
            return res
        ev.prev = envelope
        switched = ev.d_last is not None and abs(math.log(d_cmd / ev.d_last)) > 1e-9
        ev.d_last = d_cmd
        if ev.k > self.skip and self.lo < exc < self.hi and not switched:
            ev.pts.append((ev.k, math.log(exc), lam, d_cmd))
        if (exc < self.lo and ev.k > self.skip) or ev.k > 14:
            return self._close()
        return []

    @property
    def points(self) -> int:
        """Points of the open event (0 if none)."""
        return len(self.event.pts) if self.event is not None else 0

    def _close(self) -> list[tuple[float, float, float, int]]:
        ev, self.event = self.event, None
        out = []
        for d in sorted({p[3] for p in ev.pts}):
            pts = [p for p in ev.pts if p[3] == d]
            if len(pts) < self.min_points:
                continue
            k = np.array([p[0] for p in pts], dtype=float)
            y = np.array([p[1] for p in pts])
            slope = float(np.polyfit(k, y, 1)[0])
            out.append((slope, float(np.mean([p[2] for p in pts])), d, len(pts)))
        return out
