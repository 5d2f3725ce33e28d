"""Smoothing kernels: normalization, derivative consistency, compact support, factory errors.

Expectations are independent of the implementation: the normalization is a scipy quadrature of the
radial integral (surface of the unit sphere x r^(d-1) W), dW/dr is checked against central finite
differences of W and against `jax.grad` of W.
"""
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy.integrate import quad

from sph.kernels import make_kernel

pytestmark = pytest.mark.compile_bound  # its programs run a few steps: XLA -O0 (conftest._compile_bound)

H = 0.7  # a non-unit smoothing length, so a wrong power of h in sigma or dW/dr shows up
CASES = [("quintic", 1), ("quintic", 2), ("quintic", 3),
         ("wendland_c2", 2), ("wendland_c2", 3),
         ("wendland_c4", 2), ("wendland_c4", 3)]
IDS = [f"{n}-{d}d" for n, d in CASES]
SPHERE = {1: 2.0, 2: 2.0 * np.pi, 3: 4.0 * np.pi}  # "surface" of the unit sphere in 1, 2, 3D


def _radii(k, n=157):
    """Radii covering (0, 1.2 cutoff), kept away from the breakpoints r = m h of the piecewise form."""
    r = np.linspace(1e-3, 1.2 * k.cutoff, n)
    breaks = k.h * np.arange(1, int(k.support) + 1)
    keep = np.min(np.abs(r[:, None] - breaks[None, :]), axis=1) > 1e-3 * k.h
    return r[keep]


@pytest.mark.parametrize("name,dim", CASES, ids=IDS)
def test_normalization(name, dim):
    k = make_kernel(name, H, dim)
    breaks = [k.h * m for m in range(1, int(k.support))]
    integral, err = quad(lambda r: SPHERE[dim] * r ** (dim - 1) * float(k.w(r)), 0.0, k.cutoff,
                         points=breaks or None, epsabs=0.0, epsrel=1e-12, limit=200)
    assert integral == pytest.approx(1.0, rel=1e-6, abs=0.0), f"{name} {dim}D integrates to {integral}"


@pytest.mark.parametrize("name,dim", CASES, ids=IDS)
def test_dwdr_matches_finite_differences(name, dim):
    k = make_kernel(name, H, dim)
    r = _radii(k)
    eps = 1e-6 * k.h
    fd = (np.asarray(k.w(r + eps)) - np.asarray(k.w(r - eps))) / (2.0 * eps)
    dwdr = np.asarray(k.dwdr(r))
    scale = np.max(np.abs(fd))
    worst = np.argmax(np.abs(dwdr - fd))
    assert np.max(np.abs(dwdr - fd)) < 1e-6 * scale, (
        f"{name} {dim}D: dW/dr({r[worst]:.4f}) = {dwdr[worst]:.6g} but the central difference of W "
        f"gives {fd[worst]:.6g} (ratio {dwdr[worst] / fd[worst]:.4f})")


@pytest.mark.parametrize("name,dim", CASES, ids=IDS)
def test_jax_grad_of_w_matches_dwdr(name, dim):
    k = make_kernel(name, H, dim)
    r = jnp.asarray(_radii(k))
    auto = jax.vmap(jax.grad(k.w))(r)
    np.testing.assert_allclose(np.asarray(k.dwdr(r)), np.asarray(auto), rtol=1e-10,
                               atol=1e-12 * float(jnp.max(jnp.abs(auto))))


@pytest.mark.parametrize("name,dim", CASES, ids=IDS)
def test_compact_support(name, dim):
    k = make_kernel(name, H, dim)
    assert k.cutoff == pytest.approx(k.support * H)
    # at r = cutoff, q = r / h may be one ulp below the support, leaving (support - q)^n ~ 1e-80:
    # zero to round-off; strictly beyond the cutoff the ramps are exactly zero
    w0 = float(k.w(0.0))
    assert abs(float(k.w(k.cutoff))) <= 1e-30 * w0
    assert abs(float(k.dwdr(k.cutoff))) <= 1e-30 * w0 / k.h
    outside = k.cutoff * np.array([1.0 + 1e-9, 1.01, 1.5, 3.0, 10.0])
    assert np.all(np.asarray(k.w(outside)) == 0.0)
    assert np.all(np.asarray(k.dwdr(outside)) == 0.0)
    # and the kernel is positive and non-increasing inside the support
    inside = np.linspace(0.0, 0.999 * k.cutoff, 200)
    assert np.all(np.asarray(k.w(inside)) > 0.0)
    assert np.all(np.asarray(k.dwdr(inside)) <= 0.0)


@pytest.mark.parametrize("name", ["gaussian", "Quintic", ""])
def test_make_kernel_rejects_unknown_name(name):
    with pytest.raises(ValueError) as exc:
        make_kernel(name, 1.0, 2)
    assert repr(name) in str(exc.value)


@pytest.mark.parametrize("name,dim", [("quintic", 4), ("quintic", 0), ("wendland_c2", 1),
                                      ("wendland_c4", 1), ("wendland_c4", 4)])
def test_make_kernel_rejects_bad_dim(name, dim):
    with pytest.raises(ValueError) as exc:
        make_kernel(name, 1.0, dim)
    assert str(dim) in str(exc.value)
