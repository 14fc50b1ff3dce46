"""The damping gain from the vibration monitor's 1x vectors (v2 observation, issue 19 s.3).

At a constant speed the residual unbalance drives a synchronous orbit whose 1x vector on probe ``k`` is
``Z_k = c (u_k . z(D))``: ``z = (z_xi, z_eta)`` the plant's linear response to a unit unbalance
(:func:`gfb_env.analysis.response.unbalance_response`, ``(i Lambda I - J) z = b``), ``u_k`` the probe's
documented direction, ``D = g x`` commanded the actual damping, ``c`` one unknown complex number (the
unbalance's size and angle, the clearance's scale).  The response is linear in the unbalance, so the
*ratios* ``Z(D_1) / Z(D_2)`` at one speed do not depend on ``c``; the probes' bias is a constant and drops
out of a 1x vector.  Stepping the commanded damping through a few levels while holding the speed and
fitting ``c`` per candidate ``g`` by least squares (the profile likelihood over ``c``: the same as
comparing the measured ratios with the model's) gives a likelihood over ``g`` with the monitor's
documented noise (``docs/machine.md``: 1x amplitude sd ``2 sigma sqrt(2/N)`` pk-pk per step, 0.077 um for
the 0.3 um probes and 120 samples).

The observation's entries (read by name): ``x_1x_pp``, ``x_1x_cos``, ``x_1x_sin`` (and ``y_``): the
amplitude in um pk-pk / C_nom um and the phase lag behind the key, ``signal = A cos(theta - lag)``, so
the complex zero-to-peak vector of :mod:`gfb_env.analysis.response`'s convention (``signal = Re(Z
e^{i theta})``) is ``Z = pp / 2 (cos lag - i sin lag)``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from gfb_env.model import GFBModel

__all__ = [
    "MONITOR_1X_ENTRIES",
    "monitor_1x_sd",
    "MonitorPhasors",
    "probe_responses",
    "OneXSegment",
    "OneXProbe",
]

#: the observation entries of the 1x vectors (both probes)
MONITOR_1X_ENTRIES = ("x_1x_pp", "x_1x_cos", "x_1x_sin", "y_1x_pp", "y_1x_cos", "y_1x_sin", "monitor_valid")


def monitor_1x_sd(
    noise_um: float, samples_per_step: int, clearance_um: float, inflation: float = 1.3
) -> float:
    """The sd of one component (real or imaginary) of one step's zero-to-peak 1x vector, in units of the
    nominal clearance: ``sigma sqrt(2 / N)`` (the long-record formula of ``docs/machine.md``), times
    ``inflation`` (the plant's measured 1x scatter is 1.1-1.4x the formula at 4.3-5.8 revolutions)."""
    if not (noise_um > 0 and samples_per_step > 0 and clearance_um > 0 and inflation > 0):
        raise ValueError(
            f"noise_um, samples_per_step, clearance_um, inflation must be positive, got "
            f"{noise_um!r}, {samples_per_step!r}, {clearance_um!r}, {inflation!r}"
        )
    return float(inflation * noise_um * math.sqrt(2.0 / samples_per_step) / clearance_um)


class MonitorPhasors:
    """Reads the two probes' complex 1x vectors from an observation, by the layout's names."""

    def __init__(self, layout):
        self._idx = {n: int(layout.index(n)) for n in MONITOR_1X_ENTRIES}

    def __call__(self, obs: np.ndarray) -> np.ndarray | None:
        """``[Z_x, Z_y]`` (zero-to-peak, units of C_nom); None where the monitor flags its record invalid."""
        o, i = np.asarray(obs, dtype=float), self._idx
        if o[i["monitor_valid"]] < 0.5:
            return None
        zx = 0.5 * o[i["x_1x_pp"]] * (o[i["x_1x_cos"]] - 1j * o[i["x_1x_sin"]])
        zy = 0.5 * o[i["y_1x_pp"]] * (o[i["y_1x_cos"]] - 1j * o[i["y_1x_sin"]])
        return np.array([zx, zy])


def probe_responses(
    model: GFBModel, state: np.ndarray, lam: float, dampings: np.ndarray, directions: np.ndarray
) -> np.ndarray:
    """The linear 1x response to a unit unbalance projected on each probe, ``u_k . (z_xi, z_eta)``, for
    each actual damping: shape ``(len(dampings), n_probes)``, complex (one sparse solve per damping)."""
    import scipy.sparse as sp
    import scipy.sparse.linalg as spla

    L = model.layout
    n = L.size
    b = np.zeros(n, dtype=complex)
    b[L.xi_dot_index] = -1j * lam * lam
    b[L.eta_dot_index] = lam * lam
    eye = 1j * lam * sp.identity(n, format="csc")
    u = np.asarray(directions, dtype=float)
    out = np.empty((len(dampings), u.shape[0]), dtype=complex)
    for j, d in enumerate(np.asarray(dampings, dtype=float)):
        J = model.jacobian(state, lam, float(d)).astype(complex)
        z = spla.spsolve((eye - J).tocsc(), b)
        out[j] = u[:, 0] * z[L.xi_index] + u[:, 1] * z[L.eta_index]
    return out


@dataclass
class OneXSegment:
    """The 1x vectors of :class:`OneXProbe` at one commanded damping ``d``."""

    d: float
    z: list[np.ndarray] = field(default_factory=list)

    def mean(self) -> np.ndarray:
        return np.mean(np.asarray(self.z), axis=0)


class OneXProbe:
    """Collects the monitor's 1x vectors per commanded damping (at one constant speed) and scores the
    candidate gains (module docstring)."""

    def __init__(self, sd_per_step: float):
        if not sd_per_step > 0:
            raise ValueError(f"sd_per_step must be positive, got {sd_per_step!r}")
        self.sd = float(sd_per_step)
        self.segments: list[OneXSegment] = []

    def add(self, d_cmd: float, z: np.ndarray) -> None:
        if not self.segments or self.segments[-1].d != d_cmd:
            self.segments.append(OneXSegment(float(d_cmd)))
        self.segments[-1].z.append(np.asarray(z, dtype=complex))

    def log_likelihood(self, responses: np.ndarray, model_error: float = 0.0) -> np.ndarray:
        """``-chi^2 / 2`` per candidate gain with the unbalance ``c`` fitted: ``responses`` of shape
        ``(n_gains, n_segments, n_probes)`` (:func:`probe_responses` at ``g x`` each segment's commanded
        damping); ``model_error``: a relative error of the model's response added to the noise."""
        w = np.array([sg.mean() for sg in self.segments])  # (n_seg, n_probes)
        n = np.array([len(sg.z) for sg in self.segments], dtype=float)[:, None]
        v = self.sd**2 / n + (model_error * np.abs(w)) ** 2
        M = np.asarray(responses)
        a = (np.conj(M) * w / v).sum(axis=(1, 2))
        bb = (np.abs(M) ** 2 / v).sum(axis=(1, 2))
        c = a / bb
        return -0.5 * (np.abs(w[None] - c[:, None, None] * M) ** 2 / v[None]).sum(axis=(1, 2))
