"""The compiled superposition bookkeeping (gfb_env/envs/_superposition_kernels.py) against its numpy
reference: the superposed samples, the film and the ranges of one step, and the stepped motion less its 1x
(bit for bit where numpy's complex product is fused, as on AVX2/AVX-512; to rounding elsewhere)."""

from __future__ import annotations

import numpy as np
import pytest

from gfb_env.envs import _superposition_kernels as S


def _case(rng: np.random.Generator, n: int, k: int = 8, size: int = 300, span: float = 60.0) -> tuple:
    tau0 = 1234.5
    tau = tau0 + np.sort(rng.uniform(0.0, 60.0, n))
    rotor = 0.1 * rng.standard_normal((4, n))
    film = 0.5 + rng.uniform(0.0, 0.1, n)
    probes = 1.0 + 0.01 * rng.standard_normal((n, k))
    x0 = 1e-3 * (rng.standard_normal(size) + 1j * rng.standard_normal(size))
    x1 = x0 * (1.0 + 1e-3 * rng.standard_normal(size))
    idx = np.concatenate([np.arange(size - 4, size), rng.choice(size - 4, k, replace=False)]).astype(np.int64)
    h0 = np.complex128(1e-3 * complex(rng.standard_normal(), rng.standard_normal()))
    h1 = h0 * 1.001
    return (tau, rotor, film, probes, tau0, 123.4, 0.62, 3e-4, span, x0, x1, idx, h0, h1)


def _kernel(args: tuple) -> tuple:
    n, k = len(args[0]), args[3].shape[1]
    out_rotor, out_film, out_probes, ranges = (
        np.empty((4, n)),
        np.empty(n),
        np.empty((n, k)),
        np.full(5, -7.0),
    )
    S.superpose_kernel(*args, out_rotor, out_film, out_probes, ranges)
    return out_rotor, out_film, out_probes, ranges


@pytest.mark.parametrize("span", [60.0, 0.0])
def test_superpose_kernel_matches_numpy_reference(span: float) -> None:
    rng = np.random.default_rng(20)
    args = _case(rng, 120, span=span)
    rotor, film, probes, ranges = _kernel(args)
    ref_rotor, ref_film, ref_probes, ref_ranges = S.superpose_reference(*args)
    np.testing.assert_allclose(rotor, ref_rotor, rtol=1e-14, atol=1e-17)
    np.testing.assert_allclose(film, ref_film, rtol=1e-14, atol=1e-17)
    np.testing.assert_allclose(probes, ref_probes, rtol=1e-14, atol=1e-17)
    np.testing.assert_allclose(ranges, ref_ranges, rtol=1e-14, atol=1e-17)
    # the 1x was added: the samples moved (a kernel that copied its input would fail here)
    assert np.abs(rotor - args[1]).max() > 1e-5
    assert ranges[0] == film.min() and ranges[1] == rotor[0].min() and ranges[4] == rotor[1].max()


def test_superpose_kernel_empty_step_and_nan() -> None:
    rng = np.random.default_rng(3)
    _, _, _, ranges = _kernel(_case(rng, 0))
    assert (ranges == -7.0).all()  # no samples: the ranges untouched (the caller keeps the result's)
    args = list(_case(rng, 40))
    args[1] = args[1].copy()
    args[1][0, 5] = np.nan  # a NaN sample propagates into xi's range as numpy's min / max
    _, _, _, ranges = _kernel(tuple(args))
    _, _, _, ref = S.superpose_reference(*args)
    assert np.isnan(ranges[1]) and np.isnan(ranges[2]) and np.isnan(ref[1])
    np.testing.assert_allclose(ranges[[0, 3, 4]], np.array(ref)[[0, 3, 4]], rtol=1e-14)


def test_stepped_residual_kernel_matches_numpy_reference() -> None:
    rng = np.random.default_rng(4)
    tau, rotor, *_, x0, x1, idx, _, _ = _case(rng, 120)
    a = (
        tau,
        rotor[0],
        rotor[1],
        1234.5,
        5.0,
        0.6,
        -2e-4,
        60.0,
        x0[idx[0]],
        x1[idx[0]],
        x0[idx[1]],
        x1[idx[1]],
    )
    out = np.empty((2, len(tau)))
    S.stepped_residual_kernel(*a, out)
    ref = S.stepped_residual_reference(*a)
    np.testing.assert_allclose(out, ref, rtol=1e-14, atol=1e-17)
    assert np.abs(out - rotor[:2]).max() > 1e-5


def test_whirl_amplitude_kernel_matches_the_judges_amplitude() -> None:
    """The superposed response's deviation (compiled) is the judge's whirl amplitude to rounding, NaN
    where it is NaN (fewer than 3 samples, no time span, a NaN sample)."""
    from gfb_env.envs.base import _whirl_amplitude

    rng = np.random.default_rng(5)
    tau = 800.0 + np.linspace(0.0, 60.0, 120)
    xi = 0.3 + 1e-4 * tau + 2e-4 * np.cos(0.26 * tau) + 1e-6 * rng.standard_normal(120)
    eta = -0.5 - 3e-5 * tau + 2e-4 * np.sin(0.26 * tau)
    got, want = S.whirl_amplitude_kernel(tau, xi, eta), _whirl_amplitude(tau, xi, eta)
    assert want > 1e-4
    assert abs(got - want) <= 1e-9 * want
    assert np.isnan(S.whirl_amplitude_kernel(tau[:2], xi[:2], eta[:2]))
    assert np.isnan(S.whirl_amplitude_kernel(np.full(5, 3.0), xi[:5], eta[:5]))
    xi[7] = np.nan
    assert np.isnan(S.whirl_amplitude_kernel(tau, xi, eta)) and np.isnan(_whirl_amplitude(tau, xi, eta))
