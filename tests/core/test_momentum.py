"""Momentum equation: SPH operators against analytical derivatives, and exact momentum balance.

* pressure term  -> -grad p / rho   for p = p0 + cos(2 pi x)
* viscous term   -> eta lap u / rho for u = (sin 2 pi y, 0)
on a periodic lattice at dx = 0.02 (50 particles per period), where the SPH error is second order
in k h; measured with the quintic kernel (h = dx): 0.3% (pressure) and 0.1% (viscous) of the
maximum. Tolerance 1%.
* sum_i m_i du_i/dt = 0 to round-off for any configuration (antisymmetric pair forces), standard,
  transport-velocity and Riemann forms.
* TVF background-pressure acceleration: zero on a perfect lattice, restoring for a displaced particle.
"""

import jax.numpy as jnp
import numpy as np
import pytest

from sph import momentum, riemann
from sph_test_helpers import jittered_lattice, lattice, per_particle, periodic_pairs

pytestmark = pytest.mark.compile_bound  # its programs run a few steps: XLA -O0 (conftest._compile_bound)

RHO = 1.0
K = 2.0 * np.pi
OPERATOR_CASES = [("quintic", 1.0, "adami"), ("quintic", 1.0, "riemann"), ("wendland_c4", 1.3, "adami")]
OPERATOR_IDS = [f"{k}-{f}" for k, _, f in OPERATOR_CASES]


@pytest.fixture(scope="module")
def fine_lattice():
    dx = 0.02
    return dx, jnp.asarray(lattice(dx))


def _lattice_pairs(fine_lattice, kernel="quintic", h_factor=1.0):
    """(dx, positions, N, pairs) of the fine periodic lattice with `kernel` at h = h_factor dx."""
    dx, r = fine_lattice
    return dx, r, r.shape[0], periodic_pairs(r, dx, kernel, h_factor)[1]


def _tol(kernel):
    """Second-order smoothing error ~ (k h)^2 at dx = 0.02: quintic (h = dx, 0.1-0.3% measured) 1%;
    Wendland C4 with h = 1.3 dx has (k h)^2 = 2.7% (about 1.8% measured), bound 3%."""
    return 1e-2 if kernel == "quintic" else 3e-2


def _accel(form, pairs, rho, p, u, mass, eta, eta_limiter=3.0):
    fields = dict(rho=rho, p=p, u=u, u_visc=u, v_stress=u, mass=mass, vol=mass / rho)
    if form == "adami":
        return per_particle(lambda pp, i, j: momentum.acceleration(pp, i, j, eta, tvf=False), pairs, **fields)
    return per_particle(lambda pp, i, j: riemann.acceleration(pp, i, j, eta, 10.0, eta_limiter), pairs, **fields)


@pytest.mark.parametrize("kernel,h_factor,form", OPERATOR_CASES, ids=OPERATOR_IDS)
def test_pressure_gradient(fine_lattice, kernel, h_factor, form):
    dx, r, n, pairs = _lattice_pairs(fine_lattice, kernel, h_factor)
    x = r[:, 0]
    p = 5.0 + jnp.cos(K * x)  # a background pressure must not matter on a lattice
    a = _accel(form, pairs, jnp.full((n,), RHO), p, jnp.zeros((n, 2)), jnp.full((n,), RHO * dx**2), 0.0)
    expected = jnp.stack([K * jnp.sin(K * x) / RHO, jnp.zeros(n)], axis=1)  # -grad p / rho
    err = float(jnp.max(jnp.abs(a - expected)) / (K / RHO))
    assert err < _tol(kernel), f"max |a + grad p / rho| / max |grad p / rho| = {err:.3g}"


@pytest.mark.parametrize("kernel,h_factor,form", OPERATOR_CASES, ids=OPERATOR_IDS)
def test_viscous_term(fine_lattice, kernel, h_factor, form):
    dx, r, n, pairs = _lattice_pairs(fine_lattice, kernel, h_factor)
    y = r[:, 1]
    eta = 0.01
    u = jnp.stack([jnp.sin(K * y), jnp.zeros(n)], axis=1)
    # Riemann: eta_limiter = 0 gives beta = 0, i.e. no Riemann dissipation, so that the viscous term
    # is checked alone (the dissipation is checked in test_riemann_dissipation_is_dissipative)
    a = _accel(form, pairs, jnp.full((n,), RHO), jnp.zeros(n), u, jnp.full((n,), RHO * dx**2), eta, 0.0)
    expected = jnp.stack([-eta * K**2 * jnp.sin(K * y) / RHO, jnp.zeros(n)], axis=1)  # eta lap u / rho
    err = float(jnp.max(jnp.abs(a - expected)) / (eta * K**2 / RHO))
    assert err < _tol(kernel), f"max |a - eta lap u / rho| / max |eta lap u / rho| = {err:.3g}"


def test_riemann_dissipation_is_dissipative(fine_lattice):
    """The Riemann pressure P* = p_avg + rho beta (U_L - U_R)/2 only removes kinetic energy:
    dE/dt = sum_i m_i u_i . a_i is negative for a shear flow at eta = 0, and more so as the
    limiter eta_lim (beta = min(eta_lim max(U_L - U_R, 0), c)) grows, up to beta = c without it."""
    dx, r, n, pairs = _lattice_pairs(fine_lattice)
    u = jnp.stack([jnp.sin(K * r[:, 1]), 0.3 * jnp.cos(K * r[:, 0])], axis=1)
    mass = jnp.full((n,), RHO * dx**2)
    rates = []
    for lim in (0.0, 1.0, 3.0, -1.0):
        a = _accel("riemann", pairs, jnp.full((n,), RHO), jnp.zeros(n), u, mass, 0.0, lim)
        rates.append(float(jnp.sum(mass[:, None] * u * a)))
    assert abs(rates[0]) < 1e-12 * abs(rates[-1])  # beta = 0, eta = 0: no force at all
    assert rates[0] > rates[1] > rates[2] > rates[3]


@pytest.fixture(scope="module")
def disordered():
    """A jittered lattice with random masses, densities, pressures, velocities and transport velocities."""
    dx = 0.05
    r = jittered_lattice(dx, 0.2, seed=11)
    n = len(r)
    rng = np.random.default_rng(12)
    _, pairs = periodic_pairs(r, dx)
    fields = dict(
        mass=jnp.asarray(dx**2 * (1.0 + 0.2 * rng.uniform(-1, 1, n))),
        rho=jnp.asarray(1.0 + 0.05 * rng.uniform(-1, 1, n)),
        p=jnp.asarray(rng.uniform(-1.0, 3.0, n)),
        u=jnp.asarray(rng.normal(size=(n, 2))),
    )
    fields["v"] = fields["u"] + jnp.asarray(0.1 * rng.normal(size=(n, 2)))
    return pairs, fields


def _relative_net_force(mass, a):
    """|sum_i m_i a_i| / sum_i m_i |a_i|."""
    total = jnp.sum(mass[:, None] * a, axis=0)
    return float(jnp.linalg.norm(total) / jnp.sum(mass * jnp.linalg.norm(a, axis=1)))


@pytest.mark.parametrize("form", ["standard", "tvf", "riemann", "riemann-no-limiter"])
def test_momentum_is_conserved_pairwise(disordered, form):
    pairs, f = disordered
    eta = 0.05
    fields = dict(rho=f["rho"], p=f["p"], u=f["u"], u_visc=f["u"], v_stress=f["v"], mass=f["mass"],
                  vol=f["mass"] / f["rho"])
    if form in ("standard", "tvf"):
        a = per_particle(lambda pp, i, j: momentum.acceleration(pp, i, j, eta, tvf=form == "tvf"), pairs, **fields)
    else:
        lim = 3.0 if form == "riemann" else -1.0
        a = per_particle(lambda pp, i, j: riemann.acceleration(pp, i, j, eta, 10.0, lim), pairs, **fields)
    assert _relative_net_force(f["mass"], a) < 1e-12


def _background(pairs, rho, mass, p_b):
    return per_particle(lambda pp, i, j: momentum.background_acceleration(pp, i, j, p_b), pairs,
                        rho=rho, mass=mass, vol=mass / rho)


def test_background_acceleration_is_antisymmetric(disordered):
    pairs, f = disordered
    a_b = _background(pairs, f["rho"], f["mass"], 2.5)
    assert _relative_net_force(f["mass"], a_b) < 1e-12


def test_background_acceleration_vanishes_on_lattice_and_restores_displaced_particle():
    dx, p_b = 0.05, 100.0
    r = lattice(dx)
    n = len(r)
    mass, rho = jnp.full((n,), dx**2), jnp.full((n,), 1.0)
    bg = _background

    _, pairs = periodic_pairs(r, dx)
    a_b = bg(pairs, rho, mass, p_b)
    # scale of a single pair contribution: p_b V^2/m |dW/dr| ~ p_b / (rho dx) * O(1)
    scale = float(max(jnp.max(jnp.sum(jnp.abs((2 * (dx**2) ** 2 / dx**2 * pairs.f) * c), axis=-1)) for c in pairs.dr.c))
    assert float(jnp.max(jnp.abs(a_b))) < 1e-12 * p_b * scale

    i = 210  # an interior lattice site (any site is interior in a periodic box)
    rng = np.random.default_rng(5)
    for _ in range(3):
        delta = rng.normal(size=2)
        delta *= 0.1 * dx / np.linalg.norm(delta)
        r_d = r.copy()
        r_d[i] += delta
        _, pairs_d = periodic_pairs(r_d, dx)
        a_i = np.asarray(bg(pairs_d, rho, mass, p_b)[i])
        cos = float(a_i @ delta / (np.linalg.norm(a_i) * np.linalg.norm(delta)))
        # the square lattice is isotropic to first order, so the restoring force is antiparallel
        assert cos < -0.99, f"background acceleration {a_i} is not restoring for displacement {delta}"
