"""The two sides of a pair: particle i (`Own`) and its neighbours j (`Nbr`), as SPH writes them.

A pass hands its terms the per-particle fields it has (`Particles`); a term reads `i.rho` (the block's
own densities, shape (B, 1), broadcast against its pairs) and `j.rho` (the neighbours' densities,
(B, K), gathered over the list), so that a formula reads like the paper:

    p_ij = (j.rho * i.p + i.rho * j.p) / (i.rho + j.rho)

Vector fields come as `PVec`s ((B, 1) or (B, K) components). A field the pass does not provide is
None, and reading it raises a one-line error that names the field (a term asked for physics the
scene did not declare).
"""
from dataclasses import dataclass, fields, replace
from typing import Optional

import jax
import jax.numpy as jnp

from .pairs import pair_geometry, take
from .pvec import PVec


@jax.tree_util.register_dataclass
@dataclass(frozen=True)
class Particles:
    """Per-particle inputs of a pass (None where the scene or the pass has none).

    r, u, v    (N, dim) positions, velocity, transport velocity
    u_visc     (N, dim) velocity of the viscous term (u, with u~ on walls, Adami 2012 eq. 23)
    v_stress   (N, dim) transport velocity of the TVF stress (v, with u~ on walls)
    rho, p     (N,) density, pressure
    mass, vol  (N,) mass, volume m / rho
    T          (N,) temperature
    fluid      (N,) 1.0 for fluid particles, 0.0 otherwise
    wall       (N,) bool, wall particle
    normal     (N, dim) wall normal (into the fluid)
    g          (N, dim) body force at the particle
    phase      (N,) phase (material index) of the particle, as a float (`Scene.phase`)
    aux        (N,) or (N, dim) an intermediate result a pass computed for its own next sweep
    """

    r: Optional[jax.Array] = None
    u: Optional[jax.Array] = None
    v: Optional[jax.Array] = None
    u_visc: Optional[jax.Array] = None
    v_stress: Optional[jax.Array] = None
    rho: Optional[jax.Array] = None
    p: Optional[jax.Array] = None
    mass: Optional[jax.Array] = None
    vol: Optional[jax.Array] = None
    T: Optional[jax.Array] = None
    fluid: Optional[jax.Array] = None
    wall: Optional[jax.Array] = None
    normal: Optional[jax.Array] = None
    g: Optional[jax.Array] = None
    phase: Optional[jax.Array] = None
    aux: Optional[jax.Array] = None

    def columns(self) -> "Particles":
        """Vector fields split into PVecs of (N,) columns, once per pass (not once per block)."""
        split = {f.name: PVec(x[:, a] for a in range(x.shape[1]))
                 for f in fields(self) if (x := getattr(self, f.name)) is not None and not isinstance(x, PVec)
                 and x.ndim == 2}
        return replace(self, **split)


class MissingField(AttributeError):
    """A term read a field its pass does not provide."""


class _Side:
    """Lazy, memoised access to the fields of one side of the pairs."""

    def __init__(self, particles: Particles):
        self._particles, self._seen = particles, {}

    def _field(self, name):
        x = getattr(self._particles, name)
        if x is None:
            raise MissingField(f"field {name!r} is not provided by this pass (the scene does not declare the "
                               f"physics that carries it)")
        return x

    def __getattr__(self, name):
        if name.startswith("_"):
            raise AttributeError(name)
        if name not in self._seen:
            x = self._field(name)
            self._seen[name] = PVec(self._one(c) for c in x.c) if isinstance(x, PVec) else self._one(x)
        return self._seen[name]


class Own(_Side):
    """Particle i: the rows start ... start + size of every field, shape (B, 1) (size None: all rows)."""

    def __init__(self, particles: Particles, start=0, size=None):
        super().__init__(particles)
        self._start, self._size = start, size

    def _one(self, x):
        if self._size is not None:
            x = jax.lax.dynamic_slice_in_dim(x, self._start, self._size)
        return x[:, None]


class Nbr(_Side):
    """The neighbours j of a block: every field gathered over the block's slots (B, K)."""

    def __init__(self, particles: Particles, j):
        super().__init__(particles)
        self._j = j

    def _one(self, x):
        return take(x, self._j)


def rows(x):
    """A term's per-row result as per-particle arrays: (B, 1) -> (B,), PVec -> (B, dim)."""
    if isinstance(x, PVec):
        return x.stack()
    return jnp.squeeze(x, -1)


def sides(pairs, **fields):
    """(i, j) over a whole neighbour list (`pairs` of every particle, e.g. `solver.pairs_fn`), from
    per-particle fields by name (`Particles`): for calling a physics function outside a step."""
    cols = Particles(**fields).columns()
    return Own(cols), Nbr(cols, pairs.j)


def whole_list_pairs(r, idx, domain, margin, kernel):
    """`Pairs` of every particle of (N, dim) positions `r` over the whole list `idx` (one block)."""
    cols = Particles(r=r).columns()
    return pair_geometry(Own(cols).r, cols.r, idx, domain, margin, kernel)
