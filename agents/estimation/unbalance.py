"""The unbalance probe: the synchronous (1x) orbit of the residual unbalance demodulated at a few commanded
dampings, and the gain it implies.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from gfb_env.model import GFBModel

__all__ = ["PROBE_CHANNEL_SD", "TAP_SD", "unbalance_vectors", "ProbeSegment", "UnbalanceProbe"]


#: noise of one observation in the channels the unbalance probe demodulates (docs/machine.md defaults:
#: probes 0.3 um per sample -> 0.006 C; velocity 0.0038 C/T; taps 0.35 kPa -> 0.00345 p0)
PROBE_CHANNEL_SD = (0.006, 0.006, 0.0038, 0.0038)
TAP_SD = 0.35e3 / 101325.0


def unbalance_vectors(
    model: GFBModel,
    state: np.ndarray,
    lam: float,
    dampings: np.ndarray,
    n_probes: int,
    position_scale: float = 1.0,
    velocity_scale: float = 1.0,
) -> np.ndarray:
    """The linear 1x response to a unit unbalance (:func:`gfb_env.analysis.response.unbalance_response`:
    ``(i Lambda I - J) z = b``) in the observation's channels ``[xi, eta, xi', eta', P_0..P_{n-1}]`` for
    each actual damping: shape ``(len(dampings), 4 + n_probes)``, complex."""
    import scipy.sparse as sp
    import scipy.sparse.linalg as spla

    L = model.layout
    n = L.size
    b = np.zeros(n, dtype=complex)
    b[L.xi_dot_index] = -1j * lam * lam
    b[L.eta_dot_index] = lam * lam
    idx = np.r_[L.xi_index, L.eta_index, L.xi_dot_index, L.eta_dot_index, L.midplane_probe_indices(n_probes)]
    scale = np.r_[position_scale, position_scale, velocity_scale, velocity_scale, np.ones(n_probes)]
    eye = 1j * lam * sp.identity(n, format="csc")
    out = np.empty((len(dampings), len(idx)), dtype=complex)
    for j, d in enumerate(np.asarray(dampings, dtype=float)):
        J = model.jacobian(state, lam, float(d)).astype(complex)
        out[j] = spla.spsolve((eye - J).tocsc(), b)[idx] * scale
    return out


@dataclass
class ProbeSegment:
    """The samples of :class:`UnbalanceProbe` at one commanded damping ``d``: observation indices and
    the demodulated channels."""

    d: float
    k: list[int] = field(default_factory=list)
    y: list[np.ndarray] = field(default_factory=list)


class UnbalanceProbe:
    """Demodulate the 1x unbalance orbit at a few commanded dampings and infer the damping gain.

    At a constant speed the residual unbalance drives a synchronous orbit ``Re(c z(g D) e^{i theta_k})``
    in every channel (positions, velocities, pressure taps), ``theta_k = k phi`` at the k-th
    observation (``phi = omega_0 x control step``), ``c`` the unknown unbalance (size and phase, one
    complex number), ``z`` the plant's linear response (:func:`unbalance_vectors`).  The orbit's size
    and phase change with the actual damping (on the nominal bearing at Lambda = 0.45 |xi| halves from
    D_W = 0.1 to 3, the phase of eta turns by ~50 deg): the *ratios* between dampings do not depend on
    ``c``, so ``g`` follows from a least-squares fit of ``c`` per candidate ``g`` (chi^2 with the
    documented sensor noise).  Each segment's samples are regressed on ``[1, cos theta_k, sin theta_k]``
    (the constant absorbs the equilibrium and the sensor biases)."""

    def __init__(self, n_probes: int):
        self.n_probes = int(n_probes)
        self.segments: list[ProbeSegment] = []

    def channels(self, obs: np.ndarray) -> np.ndarray:
        return np.r_[obs[0:4], obs[8 : 8 + self.n_probes]].astype(float)

    def add(self, d_cmd: float, k: int, obs: np.ndarray) -> None:
        if not self.segments or self.segments[-1].d != d_cmd:
            self.segments.append(ProbeSegment(d_cmd))
        self.segments[-1].k.append(k)
        self.segments[-1].y.append(self.channels(obs))

    def amplitudes(self, phi: float) -> tuple[np.ndarray, np.ndarray]:
        """Complex 1x amplitudes ``w = A - iB`` (segments x channels) and their per-component variance."""
        sd = np.r_[PROBE_CHANNEL_SD, np.full(self.n_probes, TAP_SD)]
        w, var = [], []
        for seg in self.segments:
            th = phi * np.asarray(seg.k, dtype=float)
            X = np.column_stack([np.ones_like(th), np.cos(th), np.sin(th)])
            coef, *_ = np.linalg.lstsq(X, np.asarray(seg.y), rcond=None)
            w.append(coef[1] - 1j * coef[2])
            cov = np.linalg.pinv(X.T @ X)
            var.append(0.5 * (cov[1, 1] + cov[2, 2]) * sd**2)
        return np.array(w), np.array(var)

    def best_phase_step(self, phi0: float, rel: float = 0.0, n: int = 1) -> float:
        """The phase step per observation: ``phi0``, or (``rel > 0``, an uncertain time scale) the one in
        ``phi0 (1 +- rel)`` with the most coherent 1x power."""
        if rel <= 0:
            return phi0
        best, arg = -1.0, phi0
        for phi in np.linspace(phi0 * (1 - rel), phi0 * (1 + rel), n):
            w, var = self.amplitudes(phi)
            power = float(np.sum(np.abs(w) ** 2 / var))
            if power > best:
                best, arg = power, phi
        return arg

    def log_likelihood(self, phi: float, vectors: np.ndarray, model_error: float = 0.0) -> np.ndarray:
        """``-chi^2 / 2`` per candidate gain: ``vectors`` of shape ``(n_gains, n_segments, channels)``
        (the model at ``g x`` each segment's commanded damping); ``model_error``: a relative error of the
        model's response added to the noise (an identified plant)."""
        w, var = self.amplitudes(phi)
        out = np.empty(vectors.shape[0])
        for i, M in enumerate(vectors):
            v = var + (model_error * np.abs(w)) ** 2
            a = (np.conj(M) * w / v).sum()
            bb = (np.abs(M) ** 2 / v).sum()
            c = a / bb
            out[i] = -0.5 * float((np.abs(w - c * M) ** 2 / v).sum())
        return out
