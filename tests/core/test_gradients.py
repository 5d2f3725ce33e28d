"""Reverse-mode gradients through a solver rollout against central finite differences.

L(r0) = E_kin after 20 steps of a small TGV (dx = 0.05, 400 particles, perturbed lattice, float64),
differentiated with `jax.grad` through `sph.rollout.scan_rollout` with respect to the initial
positions (initial velocities held fixed). Checked along random directions d:
grad L . d  vs  (L(r0 + eps d) - L(r0 - eps d)) / (2 eps),  eps = 1e-6.
The neighbour list is allocated once (with a generous capacity) and reused by every evaluation;
each evaluation asserts that it did not overflow. FD error: O(eps^2) truncation plus
O(1e-16 / eps) round-off, i.e. ~1e-10 relative (measured: 2e-10 .. 7e-8), far below the 1e-5 bound.
"""
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import sph
from sph.cases import tgv
from sph.lattice import cartesian, jitter
from sph.rollout import scan_rollout
from sph_test_helpers import kinetic_energy

pytestmark = pytest.mark.compile_bound  # its programs run a few steps: XLA -O0 (conftest._compile_bound)

DX = 0.05
N_STEPS = 20
EPS = 1e-6
# TVF exercises summation density and the full Adami momentum equation (the standard form is its
# subset); Riemann the continuity density and the Riemann solver
EFFECTS = {
    "tvf": sph.Effects(tvf=True),
    "riemann": sph.Effects(riemann=True, density_evolution=True),
}


def state_from_positions(solver, template, nbrs, r):
    """The state `init_fn` builds at positions `r` (wrapped into the box), traceable in `r`;
    `nbrs` must be a list valid at `r` (the caller checks overflow)."""
    r = jnp.mod(r, jnp.asarray(solver.scene.domain.box))
    return solver.state_at(r, template.u, nbrs)


@pytest.mark.parametrize("name", list(EFFECTS))
def test_grad_of_kinetic_energy_matches_finite_differences(name):
    r_init = jitter(cartesian([0.0, 0.0], [1.0, 1.0], DX), 0.1 * DX, seed=31, box=[1.0, 1.0])
    mat = sph.Material(eta=0.01, u_ref=1.0)
    solver = sph.build_solver(tgv.scene(DX, mat, EFFECTS[name], r=r_init), sph.Numerics(dtype="float64"))
    template, _ = solver.init_fn()
    # one list for every evaluation, with room for the perturbations and the 20 steps of motion
    nbrs = solver.neighbors.allocate(template.r, extra_capacity=8)
    # the helper reproduces init_fn at the unperturbed positions
    s0 = state_from_positions(solver, template, nbrs, template.r)
    for f in ("rho", "p", "dudt", "dvdt"):
        np.testing.assert_allclose(np.asarray(getattr(s0, f)), np.asarray(getattr(template, f)),
                                   rtol=1e-12, atol=1e-12)

    def loss_and_overflow(r):
        state, _, overflow = scan_rollout(solver.step_fn, state_from_positions(solver, template, nbrs, r),
                                          nbrs, N_STEPS)
        return kinetic_energy(state), overflow

    # one compiled function serves the gradient and the FD evaluations (its backward pass is cheap)
    value_and_grad = jax.jit(jax.value_and_grad(loss_and_overflow, has_aux=True))

    def loss(r):
        return value_and_grad(r)[0]

    r = template.r
    (l0, overflow), g = value_and_grad(r)
    assert not bool(overflow)
    assert np.all(np.isfinite(np.asarray(g)))
    assert float(jnp.linalg.norm(g)) > 0.0
    rng = np.random.default_rng(32)
    for _ in range(3):
        d = jnp.asarray(rng.normal(size=r.shape))
        d = d / jnp.linalg.norm(d)
        (lp, ovp), (lm, ovm) = loss(r + EPS * d), loss(r - EPS * d)
        assert not bool(ovp) and not bool(ovm)
        fd = (float(lp) - float(lm)) / (2 * EPS)
        ad = float(jnp.vdot(g, d))
        print(f"{name}: grad . d = {ad:.12g}, central FD = {fd:.12g}, rel. err {abs(ad - fd) / abs(fd):.2e}")
        assert ad == pytest.approx(fd, rel=1e-5), f"grad . d = {ad:.10g}, central FD = {fd:.10g}"


@pytest.mark.parametrize("segments", [4, 3])
def test_checkpointed_gradient_equals_plain(segments):
    """jax.checkpoint over segments recomputes the same steps: same gradient to round-off
    (20 steps in 4 segments of 5, and in 3 segments of 7 + a remainder of 6)."""
    r_init = jitter(cartesian([0.0, 0.0], [1.0, 1.0], DX), 0.1 * DX, seed=31, box=[1.0, 1.0])
    solver = sph.build_solver(tgv.scene(DX, sph.Material(eta=0.01), sph.Effects(tvf=True), r=r_init))
    template, _ = solver.init_fn()
    nbrs = solver.neighbors.allocate(template.r, extra_capacity=8)

    def loss(r, k):
        state, _, _ = scan_rollout(solver.step_fn, state_from_positions(solver, template, nbrs, r), nbrs, N_STEPS,
                                   segments=k)
        return kinetic_energy(state)

    g_plain = jax.jit(jax.grad(lambda r: loss(r, 0)))(template.r)
    g_ckpt = jax.jit(jax.grad(lambda r: loss(r, segments)))(template.r)
    np.testing.assert_allclose(np.asarray(g_ckpt), np.asarray(g_plain), rtol=1e-10, atol=1e-14)


def test_gradient_through_walls_matches_finite_differences():
    """The lid-driven cavity (moving lid, no-slip walls, dx = 0.1): d E_kin(10 steps) / d r0 of the
    fluid positions along random directions, AD vs central FD, float64."""
    from sph.cases import ldc
    solver = sph.build_solver(ldc.scene(0.1, sph.Material(eta=0.1), sph.Effects(walls="no_slip")))
    template, _ = solver.init_fn()
    nbrs = solver.neighbors.allocate(template.r, extra_capacity=8)
    fluid = jnp.asarray(template.tag == sph.FLUID)[:, None]

    def loss(r):
        state, _, overflow = scan_rollout(solver.step_fn, solver.state_at(r, template.u, nbrs), nbrs, 10)
        return kinetic_energy(state), overflow

    value_and_grad = jax.jit(jax.value_and_grad(loss, has_aux=True))
    (_, overflow), g = value_and_grad(template.r)
    assert not bool(overflow) and np.all(np.isfinite(np.asarray(g)))
    rng = np.random.default_rng(5)
    for _ in range(2):
        d = jnp.where(fluid, jnp.asarray(rng.normal(size=template.r.shape)), 0.0)  # walls stay put
        d = d / jnp.linalg.norm(d)
        fd = (float(value_and_grad(template.r + EPS * d)[0][0]) - float(value_and_grad(template.r - EPS * d)[0][0])) / (2 * EPS)
        assert float(jnp.vdot(g, d)) == pytest.approx(fd, rel=1e-5)


@pytest.mark.parametrize("effects", [
    pytest.param(dict(walls="no_slip"), id="standard"),
    pytest.param(dict(walls="no_slip", tvf=True), id="tvf"),
    pytest.param(dict(walls="no_slip", riemann=True, density_evolution=True), id="riemann"),
])
def test_float32_gradient_through_walls_is_finite_and_close_to_float64(effects):
    """Regression: in float32 a wall particle that touches only the far tail of a fluid kernel has a
    Shepard weight sum of ~1e-30, whose reciprocal's derivative overflowed and made every entry of
    the cavity's gradient NaN (make fig1, ldc float32). The float32 gradient of E_kin(5 steps) must
    be finite and agree with the float64 one (checked against FD above) to float32 accuracy of a
    short rollout: relative L2 below 1e-2."""
    from sph.cases import ldc
    grads = {}
    for dtype in ("float64", "float32"):
        solver = sph.build_solver(ldc.scene(0.1, sph.Material(eta=0.1), sph.Effects(**effects)),
                                  sph.Numerics(dtype=dtype))
        template, _ = solver.init_fn()
        nbrs = solver.neighbors.allocate(template.r, extra_capacity=8)

        def loss(r):
            state, _, _ = scan_rollout(solver.step_fn, solver.state_at(r, template.u, nbrs), nbrs, 5)
            return kinetic_energy(state)

        grads[dtype] = np.asarray(jax.jit(jax.grad(loss))(template.r), np.float64)
    assert np.all(np.isfinite(grads["float32"]))
    g64 = grads["float64"]
    assert np.linalg.norm(grads["float32"] - g64) < 1e-2 * np.linalg.norm(g64)
