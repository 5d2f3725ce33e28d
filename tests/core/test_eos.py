"""Equations of state: reference point, inverse, reference pressure and sound speed.

The defining property of the weakly compressible EoS is dp/drho (rho_ref) = c_ref^2, checked with
`jax.grad` against the configured sound speed, independently of how p_ref is written.
"""
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import sph
from sph.eos import RiemannEoS, TaitEoS
from sph.cases import tgv

RHO = np.linspace(0.8, 1.2, 41)


def _eos_cases():
    cases = []
    for rho_ref, c_ref in [(1.0, 10.0), (1000.0, 35.0)]:
        for gamma in (1.0, 7.0):
            for p_bg in (0.0, 0.37 * rho_ref * c_ref**2):
                cases.append(pytest.param(TaitEoS(rho_ref, c_ref, gamma, p_bg), c_ref**2 * rho_ref / gamma,
                                          id=f"tait-rho{rho_ref:g}-c{c_ref:g}-g{gamma:g}-pbg{p_bg:g}"))
        for p_bg in (0.0, 0.37 * rho_ref * c_ref**2):
            cases.append(pytest.param(RiemannEoS(rho_ref, c_ref, p_bg), c_ref**2 * rho_ref,
                                      id=f"riemann-rho{rho_ref:g}-c{c_ref:g}-pbg{p_bg:g}"))
    return cases


@pytest.mark.parametrize("eos,p_ref", _eos_cases())
def test_reference_pressure(eos, p_ref):
    # p_ref = rho_ref c_ref^2 / gamma (Tait), rho_ref c_ref^2 (linear Riemann EoS, gamma = 1)
    assert eos.p_ref == pytest.approx(p_ref, rel=1e-14)


@pytest.mark.parametrize("eos,p_ref", _eos_cases())
def test_pressure_at_reference_density_is_background(eos, p_ref):
    assert float(eos.p(jnp.float64(eos.rho_ref))) == pytest.approx(eos.p_bg, abs=1e-12 * p_ref)


@pytest.mark.parametrize("eos,p_ref", _eos_cases())
def test_inverse_round_trip(eos, p_ref):
    rho = eos.rho_ref * jnp.asarray(RHO)
    np.testing.assert_allclose(np.asarray(eos.rho(eos.p(rho))), np.asarray(rho), rtol=1e-12)


@pytest.mark.parametrize("eos,p_ref", _eos_cases())
def test_sound_speed_at_reference_density(eos, p_ref):
    dpdrho = jax.grad(eos.p)(jnp.float64(eos.rho_ref))
    assert float(dpdrho) == pytest.approx(eos.c_ref**2, rel=1e-12)


@pytest.mark.parametrize("eos,p_ref", _eos_cases())
def test_pressure_increases_with_density(eos, p_ref):
    p = np.asarray(eos.p(eos.rho_ref * jnp.asarray(RHO)))
    assert np.all(np.diff(p) > 0)


@pytest.mark.parametrize("effects", [sph.Effects(), sph.Effects(riemann=True, density_evolution=True)],
                         ids=["tait", "riemann"])
def test_solver_eos_follows_numerics(effects):
    """build_solver: c_ref = c_ref_factor u_ref and p_bg = p_bg_factor p_ref (config docstrings)."""
    mat = sph.Material(rho_ref=2.0, eta=0.0, u_ref=1.5)
    num = sph.Numerics(c_ref_factor=12.0, p_bg_factor=0.25, gamma=1.0 if effects.riemann else 7.0)
    solver = sph.build_solver(tgv.scene(0.125, mat, effects), num)
    c_ref = 12.0 * 1.5
    assert float(jax.grad(solver.eos.p)(jnp.float64(2.0))) == pytest.approx(c_ref**2, rel=1e-12)
    p_ref = 2.0 * c_ref**2 / num.gamma
    assert float(solver.eos.p(jnp.float64(2.0))) == pytest.approx(0.25 * p_ref, rel=1e-12)
