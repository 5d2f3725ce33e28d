"""Particle reordering by cell, so that the neighbours of a particle stay close in memory.

The pair sums gather the neighbours' fields, x[j] for the K neighbour slots of every particle. A run
starts in the scene's order, usually a lattice's, in which a particle's neighbours are a few rows
(and rows of rows) away; as the flow carries the particles, neighbours drift apart in the arrays
and the gathers miss the cache. `sph.simulate.run` (numerics.reorder_every) therefore sorts the
particles by cell every so often: the fluid particles are permuted among the fluid slots, in
x-major order of cells of side dx (a lattice comes back in lattice order), and every other
particle (walls, temperature-fixed particles) keeps its slot. Only fluid particles move between
slots because the solver carries per-particle constants (wall masks, wall normals, fixed
temperatures) baked into its step; those are identical for all such particles
(`movable_mask`), so the permuted state is a valid state of the same solver.

A permutation `perm` (an index array) takes slot i of the new arrays from slot perm[i] of the old
ones; `order` composes the permutations since the start (slot i holds the scene's particle
order[i]), and `restore(state, order)` brings a state back to the scene's order (for the writer,
the checkpoint and the caller), so trajectories and every output keep the scene's particle order.
"""
import jax
import jax.numpy as jnp
import numpy as np

from .state import FLUID


def movable_mask(scene) -> np.ndarray:
    """Particles that may change slots: fluid particles without a fixed temperature (the solver's
    per-particle constants are the same for all of them). Walls keep their slots."""
    mask = np.asarray(scene.tag) == FLUID
    if getattr(scene, "T_fixed", None) is not None:
        mask &= ~np.asarray(scene.T_fixed, bool)
    if getattr(scene, "normal", None) is not None:
        mask &= ~np.any(np.asarray(scene.normal) != 0.0, axis=1)
    return mask


def cell_permutation(r, movable, cell: float) -> np.ndarray:
    """perm (N,) sorting the `movable` particles among their own slots by their cell (side `cell`,
    x-major: x, then y, then z; cells centred on the lowest coordinates, so that a lattice of spacing
    `cell` is one particle per cell), other particles in place; ties keep their current order."""
    r = np.asarray(r, np.float64)
    slots = np.flatnonzero(movable)
    perm = np.arange(r.shape[0])
    if slots.size < 2:
        return perm
    rm = r[slots]
    c = np.floor((rm - rm.min(axis=0)) / cell + 0.5).astype(np.int64)  # cells centred on the lowest
                                                                          # particle: a lattice is not cut at its rows
    span = c.max(axis=0) + 1
    key = np.zeros(slots.size, np.int64)
    for a in range(r.shape[1]):
        key = key * span[a] + c[:, a]
    perm[slots] = slots[np.argsort(key, kind="stable")]
    return perm


def permute(state, perm):
    """The state with every per-particle field taken in the order `perm`."""
    perm = jnp.asarray(perm)
    n = state.r.shape[0]
    return jax.tree_util.tree_map(lambda x: x[perm] if x.ndim and x.shape[0] == n else x, state)


def restore(state, order):
    """The state in the scene's order, given `order` (slot i holds the scene's particle order[i])."""
    if order is None:
        return state
    return permute(state, np.argsort(order))


def compose(order, perm) -> np.ndarray:
    """`order` after applying `perm` (None: the scene's order)."""
    return np.asarray(perm) if order is None else np.asarray(order)[np.asarray(perm)]
