"""Scalar diagnostics of a particle state: kinetic energy, peak velocity, density error, finiteness.

All functions are jittable and take a `ParticleState`. Only fluid particles (tag == FLUID) enter
the kinetic energy, the peak velocity and the density error; the finiteness check covers every
particle and every floating-point field.

Velocity diagnostics use the transport velocity `v`, the velocity the particles actually move with
(identical to `u` without TVF), as JAX-SPH's validation does (its `get_val_max(state, "v")` and
`get_ekin`). With TVF the momentum velocity `u` also carries a standing component of about
-dt/2 a_b: at rest the pressure field settles so that it cancels the background-pressure shift, so
u_i is of order dt/2 |a_b| (measured ~8e-3 at dx = 0.02, p_b = p_ref) while the particles stand
still (v ~ 0). That component is numerical, not flow, and would dominate u_max of a decayed vortex.

The run-time errors are `sph.errors`' (`SimulationError` and its kinds), the per-step check that
raises them `sph.guard.StepGuard`.
"""
import jax.numpy as jnp
import numpy as np

from .state import FLUID, ParticleState


def _fluid(state: ParticleState):
    return state.tag == FLUID


def kinetic_energy(state: ParticleState):
    """E_kin = 1/2 sum_i m_i |v_i|^2 over fluid particles (transport velocity v, see module doc)."""
    e = 0.5 * state.mass * jnp.sum(state.v**2, axis=1)
    return jnp.sum(jnp.where(_fluid(state), e, 0.0))


def u_max(state: ParticleState):
    """max_i |v_i| over fluid particles (transport velocity v, see module doc)."""
    speed = jnp.sqrt(jnp.sum(state.v**2, axis=1))
    return jnp.max(jnp.where(_fluid(state), speed, 0.0))


def density_error(state: ParticleState, rho_ref: float):
    """max_i |rho_i / rho_ref - 1| over fluid particles (weak-compressibility check, ~Ma^2)."""
    err = jnp.abs(state.rho / rho_ref - 1.0)
    return jnp.max(jnp.where(_fluid(state), err, 0.0))


def _float_fields(state: ParticleState):
    names = [n for n in state.field_names() if jnp.issubdtype(getattr(state, n).dtype, jnp.floating)]
    return names, [getattr(state, n).reshape(state.n, -1) for n in names]


def nonfinite_mask(state: ParticleState):
    """(N,) bool: particle i has a NaN or inf in any floating-point field."""
    _, arrays = _float_fields(state)
    return jnp.any(jnp.concatenate([~jnp.isfinite(a) for a in arrays], axis=1), axis=1)


def first_nonfinite(state: ParticleState):
    """Index of the first particle with a non-finite field, or -1 when everything is finite."""
    bad = nonfinite_mask(state)
    return jnp.where(jnp.any(bad), jnp.argmax(bad), -1)


def nonfinite_fields(state: ParticleState, i: int) -> list:
    """Names of the fields that are non-finite at particle `i` (host side, for error messages)."""
    names, arrays = _float_fields(state)
    return [n for n, a in zip(names, arrays) if not np.all(np.isfinite(np.asarray(a[i])))]


def summary(state: ParticleState, rho_ref: float) -> dict:
    """All frame diagnostics at once (one jitted call per frame): u_max, e_kin, density_error,
    first_nonfinite."""
    return {"u_max": u_max(state), "e_kin": kinetic_energy(state),
            "density_error": density_error(state, rho_ref), "first_nonfinite": first_nonfinite(state)}
