"""The per-step guard of a rollout: a step after which the state is unphysical is refused, and
explained on the host (`StepGuard`, built by `sph.build_solver` as `solver.guard`)."""
import dataclasses
from dataclasses import dataclass, field
from typing import Callable, Optional

import jax
import jax.numpy as jnp
import numpy as np

from .diagnostics import first_nonfinite, nonfinite_fields
from .errors import BlowUp, NeighborOverflow, ParticleEscaped, SimulationError
from .state import FLUID


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
