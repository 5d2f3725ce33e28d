"""A pass: one stage of the step, mapping the step's `Fields` to new ones, with what it reads and writes.

The step is an ordered list of passes (`sph.registry.PASSES`, built for a scene by `choose_passes`):
density, re-initialization, pressure, wall condition, forces, surface tension, heat. A pass that
sums over neighbours evaluates its terms in one sweep of the neighbour list (`Context.sweep`, in
blocks, `sph.blocks`), handing them exactly the fields it `reads` (`sph.views.Particles`): a term
that reads anything else raises `MissingField` naming it. `step_fn` runs every pass after the kick,
drift and neighbour update; `state_at` runs the passes that hold `at_rest` (those that evaluate the
state at given positions and velocities rather than advance it in time).

A new effect is one module holding its pass (a frozen dataclass with `build`, `reads`, `writes`,
`at_rest` and `__call__`) and one line in `sph.registry.PASSES`.
"""
from dataclasses import dataclass, fields
from functools import partial
from typing import Callable, ClassVar, Optional

import jax.numpy as jnp
import numpy as np

from . import blocks
from .fields import Fields
from .pairs import pair_geometry
from .views import Particles

ALL_READS = tuple(f.name for f in fields(Particles))
"""What a term that does not declare `reads` is given: every field a pass can provide."""


def reads_of(*terms) -> tuple:
    """The fields a set of terms reads, in order of first use (`term.reads`, else ALL_READS)."""
    out = []
    for term in terms:
        out += [n for n in getattr(term, "reads", ALL_READS) if n not in out]
    return tuple(out)


@dataclass(frozen=True, eq=False)
class Context:
    """What a pass may read besides the fields: the scene's constant per-particle arrays and the run's
    constants (`sph.constants.Constants`).

    fluid, wall   (N,) bool masks (tags FLUID; WALL or MOVING_WALL)
    normal        (N, dim) wall normals into the fluid (zeros without)
    T_fixed       (N,) bool, Dirichlet-temperature particles (none: all False)
    phase         (N,) int phase of every particle (`Scene.phase`)
    """

    c: object
    fluid: np.ndarray
    wall: np.ndarray
    normal: np.ndarray
    T_fixed: np.ndarray
    phase: np.ndarray
    geometry: Callable

    @classmethod
    def of(cls, scene, c) -> "Context":
        normal = scene.normal if scene.normal is not None else np.zeros_like(scene.r)
        t_fixed = scene.T_fixed if scene.T_fixed is not None else np.zeros(scene.n, bool)
        return cls(c=c, fluid=scene.fluid_mask, wall=scene.wall_mask, normal=normal, T_fixed=t_fixed,
                   phase=scene.phases, geometry=partial(pair_geometry, domain=scene.domain, margin=c.margin,
                                                       kernel=c.kernel))

    def body_force(self, r):
        """g at the positions r (zeros without a body force)."""
        return self.c.force(r) if self.c.force is not None else jnp.zeros_like(r)

    def value(self, f: Fields, name: str):
        """A field by name: derived (vol = m / rho, g), a scene constant, or one of `f`'s."""
        if name == "vol":
            return f.mass / f.rho
        if name == "g":
            return self.body_force(f.r)
        if name == "fluid":
            return jnp.asarray(self.fluid).astype(self.c.dtype)
        if name == "wall":
            return jnp.asarray(self.wall)
        if name in ("normal", "phase"):
            return jnp.asarray(getattr(self, name), self.c.dtype)
        return f.value(name) if hasattr(f, name) else None

    def sweep(self, term, idx, f: Fields, reads, **given):
        """Per-particle results of `term(pairs, i, j)` over the list `idx`, given the fields `reads`
        of `f` (and the arrays `given`, e.g. a pass's own intermediate `aux`)."""
        p = Particles(**{n: self.value(f, n) for n in reads if n not in given}, **given)
        return blocks.evaluate(term, p, idx, self.geometry)


class Pass:
    """Base of the passes. A subclass is a frozen dataclass that sets

    writes     the fields it writes (a class constant)
    at_rest    True if `state_at` runs it too (it evaluates, rather than advances, the state)
    reads      the fields it reads (a property where its terms decide)
    build(scene, numerics, c) -> the pass for a scene, or None where the scene does not declare it
    __call__(f, ctx, idx, step) -> Fields
    and, where its physics limits the time step, `dt_limits(scene, numerics, h) -> {name: dt}`.
    """

    writes: ClassVar[tuple] = ()
    at_rest: ClassVar[bool] = True

    @classmethod
    def build(cls, scene, numerics, c) -> Optional["Pass"]:
        raise NotImplementedError

    @staticmethod
    def dt_limits(scene, numerics, h) -> dict:
        return {}


def run(passes, f: Fields, ctx: Context, idx, step) -> Fields:
    """The passes in order over the fields (the neighbour list `idx`, the number of the step)."""
    for p in passes:
        f = p(f, ctx, idx, step)
    return f
