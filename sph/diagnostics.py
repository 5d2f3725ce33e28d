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

Run-time errors (`SimulationError` and its kinds `BlowUp`, `ParticleEscaped`, `NeighborOverflow`)
and the per-step `StepGuard` that raises them live here too, so that the rollouts and the driver
share them.
"""
import dataclasses
from dataclasses import dataclass, field
from typing import Callable, Optional

import jax
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


# ---------------------------------------------------------------------------------------------------
# Run-time errors and the per-step guard
# ---------------------------------------------------------------------------------------------------


class SimulationError(RuntimeError):
    """A run stopped because its state became unphysical. The message names the step, the particle
    and its position; `step` (the step that was refused), `particle` and `position` carry them, and
    `state` / `nbrs` the last good state (before that step) when known."""

    def __init__(self, msg: str, *, step=None, particle=None, position=None, state=None, nbrs=None):
        super().__init__(msg)
        self.step, self.particle, self.position = step, particle, position
        self.state, self.nbrs = state, nbrs


class BlowUp(SimulationError):
    """A field became NaN/inf, or a fluid speed exceeded the run's speed limit u_limit."""


class ParticleEscaped(SimulationError):
    """A fluid particle left the domain through a non-periodic side (beyond the wall layers or out of
    an open side of the box). Never taken: the neighbour search would wrap it around to the far side."""


class NeighborOverflow(SimulationError):
    """The neighbour list overflowed again and again although re-allocated (particles clumping)."""


def escaped_mask(r, tag, box, periodic):
    """(N,) bool: fluid particle outside [0, box) in a non-periodic dimension (NaN counts as outside)."""
    nonperiodic = ~np.asarray(periodic, bool)
    if not nonperiodic.any():
        return jnp.zeros(r.shape[0], bool)
    b = jnp.asarray(np.asarray(box, float), r.dtype)
    inside = (r >= 0) & (r < b)
    out = jnp.any(~inside & jnp.asarray(nonperiodic), axis=1)
    return out & (tag == FLUID)


@dataclass(frozen=True, eq=False)
class StepGuard:
    """The per-step check of a rollout (`sph.rollout.make_chunk(..., guard=...)`, `scan_rollout`):
    a step is refused when, after it, a fluid particle is outside the domain in a non-periodic
    dimension (`ParticleEscaped`), moves faster than `u_limit` (transport velocity v), or has a
    non-finite position or velocity (`BlowUp`). `reject` is one fused pass over the particles (a few
    compares per particle, well under 3 % of a step); `diagnose` explains a refused step on the host.

    Built by `sph.build_solver` (`solver.guard`, u_limit = c_ref); `with_limit(u)` changes the limit
    (math.inf: no speed limit; NaN and escapes are still refused).
    """

    box: tuple
    periodic: tuple
    u_limit: float
    c_ref: float
    dt: float
    dt_limits: dict
    fixed_dt: bool
    step_fn: Callable
    _jitted: dict = field(default_factory=dict, repr=False)

    def with_limit(self, u_limit: Optional[float]) -> "StepGuard":
        """The same guard with speed limit `u_limit` (None: keep c_ref)."""
        if u_limit is None:
            return self
        return dataclasses.replace(self, u_limit=float(u_limit))

    def reject(self, state):
        """Traceable: true if `state` (after a step) must not be taken."""
        # only r and v: both are known early in the step (before the neighbour update), so the check
        # does not wait for the end of the step; a NaN elsewhere reaches v one step later, and the
        # driver checks every field at the end of each chunk
        fluid = state.tag == FLUID
        speed2 = jnp.sum(state.v * state.v, axis=1)
        lim2 = jnp.asarray(self.u_limit, speed2.dtype) ** 2 if np.isfinite(self.u_limit) else jnp.inf
        bad = fluid & ~(speed2 <= lim2)  # NaN fails every comparison
        bad = bad | escaped_mask(state.r, state.tag, self.box, self.periodic)
        return jnp.any(bad)

    # -- host side -----------------------------------------------------------------------------
    def _step(self, state, nbrs, step):
        if "step" not in self._jitted:
            self._jitted["step"] = jax.jit(self.step_fn)
        return self._jitted["step"](state, nbrs, step)

    def dt_hint(self) -> str:
        """Likely cause, in terms of the time step: dt against its stability limits."""
        limits = {k: v for k, v in self.dt_limits.items() if k != "dt"}
        listed = ", ".join(f"{k} {v:.3g}" for k, v in limits.items())
        how = "numerics.dt (fixed)" if self.fixed_dt else "from the limits (numerics.cfl)"
        over = {k: self.dt / v for k, v in limits.items() if self.dt > v * (1 + 1e-9)}
        if over:
            k = max(over, key=over.get)
            return (f"dt = {self.dt:.3g} ({how}) is {over[k]:.3g}x the {k} limit (limits: {listed}): "
                    f"lower numerics.dt{' or remove it' if self.fixed_dt else ''}")
        return (f"dt = {self.dt:.3g} ({how}) is within its limits ({listed}); check the initial state "
                f"(overlapping or misplaced particles) and material.u_ref (c_ref = c_ref_factor u_ref = "
                f"{self.c_ref:.3g} must exceed the flow's speeds ~10x)")

    def diagnose(self, state, nbrs, step: int, why: str = "") -> SimulationError:
        """The error for a refused step `step` from the good `state`: takes the step once more
        unguarded and names the first offending particle, its position and the likely cause."""
        bad = self._step(state, nbrs, step)[0]
        where = f"at step {step} (t={step * self.dt:.6g})"
        tag = np.asarray(bad.tag)
        fluid = tag == FLUID
        r_before = np.asarray(state.r)
        i = int(first_nonfinite(bad))
        speed = np.where(fluid, np.linalg.norm(np.asarray(bad.v), axis=1), 0.0)
        esc = np.asarray(escaped_mask(bad.r, bad.tag, self.box, self.periodic))
        kw = dict(step=step, state=state, nbrs=nbrs)
        if i >= 0:
            return BlowUp(f"simulation blew up {where}: particle {i} has non-finite "
                          f"{', '.join(nonfinite_fields(bad, i))} (position before the step "
                          f"{r_before[i].tolist()}); {self.dt_hint()}", particle=i, position=r_before[i], **kw)
        if np.nanmax(speed, initial=0.0) > self.u_limit:
            i = int(np.argmax(speed))
            return BlowUp(f"simulation blew up {where}: particle {i} moves at |v| = {speed[i]:.4g} > u_limit = "
                          f"{self.u_limit:.4g} (c_ref = {self.c_ref:.4g}; position before the step "
                          f"{r_before[i].tolist()}); {self.dt_hint()}", particle=i, position=r_before[i], **kw)
        if esc.any():
            i = int(np.argmax(esc))
            r_i = np.asarray(bad.r)[i]
            axis = int(np.argmax(~((r_i >= 0) & (r_i < np.asarray(self.box)))))
            box = " x ".join(f"[0, {b:g})" for b in self.box)
            return ParticleEscaped(
                f"fluid particle {i} left the domain {where}: position {r_i.tolist()} is outside the box {box} "
                f"in dimension {axis} (not periodic), moving at |v| = {speed[i]:.4g}; the step is not taken (the "
                f"neighbour search would wrap it around to the far side). Close the domain with walls, make "
                f"that side periodic, or enlarge the box", particle=i, position=r_i, **kw)
        # nothing wrong with the fields: the list kept overflowing (or the chunk refused for a reason
        # this unguarded step does not reproduce); name the most crowded and the fastest particle
        idx = np.asarray(nbrs.idx)
        counts = np.sum(idx < idx.shape[0], axis=1)
        k, f = int(np.argmax(counts)), int(np.argmax(speed))
        return NeighborOverflow(
            f"neighbour list kept overflowing {where} although the fields stay finite{': ' + why if why else ''}; "
            f"particle {k} has the most neighbours ({counts[k]} of {idx.shape[1]} slots, at "
            f"{r_before[k].tolist()}), particle {f} is the fastest (|v| = {speed[f]:.4g}, at {r_before[f].tolist()}): "
            f"particles are clumping, typically the start of a blow-up; {self.dt_hint()}",
            particle=k, position=r_before[k], **kw)
