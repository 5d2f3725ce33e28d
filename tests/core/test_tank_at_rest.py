"""A tank at rest (sph.cases.tank.at_rest, the public recipe): standard SPH settles; Riemann SPH with
the dam break's settings does not, by a known mechanism, and stays bounded. Bounds from the
measurements of 2026-12-06 (dx = H / 10, t = 10 sqrt(H/g)), each about 3x: a regression in either
direction fails. See sph.cases.tank.AT_REST_EFFECTS for the evidence."""
import jax
import numpy as np

import sph
from sph import simulate
from sph.cases import tank

DX, H = 0.05, 0.5


def _settle(method):
    sc, nm, start = tank.at_rest(DX, width=1.0, height=H, method=method)
    solver = sph.build_solver(sc, nm)
    t_end = 10 * np.sqrt(H)
    res = simulate.run(solver, *start(solver), t_end, max(1, solver.n_steps(t_end) // 20), progress=False)
    u = np.asarray(res.u_max) / np.sqrt(H)
    rise = (np.asarray(res.state.r)[sc.fluid_mask, 1].max() - sc.r[sc.fluid_mask, 1].max()) / DX
    return u, rise


def _surface_rate(method):
    """Mean drho/dt of the fluid within a kernel support of the free surface, first step from the
    hydrostatic start."""
    sc, nm, start = tank.at_rest(DX, width=1.0, height=H, method=method)
    solver = sph.build_solver(sc, nm)
    s0, nbrs = start(solver)
    s1, _ = jax.jit(solver.step_fn)(s0, nbrs, 1)
    f = sc.fluid_mask
    top = sc.r[f, 1] - tank.offset(DX) > H - 3 * DX
    return float(np.mean((np.asarray(s1.rho) - np.asarray(s0.rho))[f][top]) / solver.dt)


def test_standard_sph_settles():
    u, rise = _settle("sph")
    assert np.all(np.isfinite(u))
    assert u[-5:].max() < 2e-4          # measured 6e-5 sqrt(gH) over the last quarter
    assert abs(rise) < 0.05             # the surface stays put (measured 0.002 dx)


def test_riemann_sph_does_not_settle_but_stays_bounded():
    u, rise = _settle("riemann")
    assert np.all(np.isfinite(u))
    assert 0.005 < u[-1] < 0.04         # measured 0.0128 sqrt(gH) at t = 10 sqrt(H/g)
    assert 0.3 < rise < 1.5             # measured 0.70 dx


def test_the_riemann_continuity_equation_is_not_at_rest_at_a_hydrostatic_free_surface():
    sph_rate, riemann_rate = _surface_rate("sph"), _surface_rate("riemann")
    assert riemann_rate > 5e-3                               # measured +1.5e-2
    assert riemann_rate > 30 * abs(sph_rate)                 # measured 140x
