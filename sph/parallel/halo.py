"""Halo exchange: the copies of the neighbour slabs' particles within one halo width of a device's
faces, and the refresh of exactly the fields the next pass reads (`ExchangePlan`), by
`jax.lax.ppermute` inside `shard_map` (issue 40, item 1).

A device's rows in a step are [owned (capacity) | halo from the lower slab (H) | halo from the
upper slab (H)]. `build` picks, after the migration, the owned particles within the halo width of
the lower face (sent down) and of the upper face (sent up), as index lists of fixed capacity H with
an overflow flag; these lists hold until the next rebuild (`sph.parallel.driver`). Positions are
sent as they are: across the periodic wrap-around they stay in [0, L), and the pair geometry's
minimum image (`sph.domain.Domain.minimum_image`, the same as on one device) makes them periodic
images. At a rebuild the positions travel once more, before the neighbour list is built.

The plan. A pass evaluated on a halo row sees only part of that particle's neighbours, so what a
pass writes is wrong on halo rows until it is exchanged again. `ExchangePlan.of(passes)` walks the
pass list once (statically) and, before each pass that sums over neighbours, exchanges the fields
it reads (`reads`, derived fields mapped to what they come from: vol -> mass, rho; g -> r;
fluid, wall -> tag; u_visc -> u until a pass writes it) that an earlier pass of the step wrote; the
fields it reads that no earlier pass wrote go with the halo build. A pointwise pass (pressure,
heat: it reads its own row only) needs no exchange, and its result is right on halo rows when
everything it reads is. Only owned rows leave the step.
"""
from dataclasses import dataclass

import jax
import jax.numpy as jnp

from .. import eos, heat, surface_tension

POINTWISE = (eos.PressurePass, heat.HeatPass)
"""Passes that read only their own row (no neighbour sum)."""

CONSTANTS = ("normal", "phase")
"""Per-particle scene constants a term may read of a neighbour (they travel with the particle)."""

DERIVED = {"vol": ("mass", "rho"), "g": ("r",), "fluid": ("tag",), "wall": ("tag",)}
"""Fields a pass derives from others (`sph.passes.Context.value`)."""

FALLBACK = {"u_visc": "u", "v_stress": "v"}
"""Transients read as another field until a pass writes them (`sph.fields.FALLBACK`)."""


def sources(name: str, written) -> tuple:
    """The stored fields a read of `name` comes from, given the fields written so far this step."""
    if name in DERIVED:
        return DERIVED[name]
    if name in FALLBACK and name not in written:
        return (FALLBACK[name],)
    return (name,)


@dataclass(frozen=True)
class ExchangePlan:
    """initial: the fields sent with the halo build; before: for each pass, the fields exchanged
    just before it (module docstring)."""

    initial: tuple
    before: tuple

    @classmethod
    def of(cls, passes) -> "ExchangePlan":
        fresh, written, initial, before = set(), set(), [], []
        for p in passes:
            if isinstance(p, surface_tension.SurfaceTensionPass):
                raise NotImplementedError("sharded step: the surface-tension pass sums over neighbours twice, the "
                                          "second time over normals of its own first sum, which would need an "
                                          "exchange inside the pass; not supported on several devices yet")
            need = [s for n in p.reads for s in sources(n, written)]
            if isinstance(p, POINTWISE):
                before.append(())
                ok = all(n in fresh for n in need)
                fresh = fresh | set(p.writes) if ok else fresh - set(p.writes)
            else:
                send = []
                for n in dict.fromkeys(need):
                    if n in fresh:
                        continue
                    (send if n in written else initial).append(n)
                    fresh.add(n)
                before.append(tuple(send))
                fresh -= set(p.writes)
            written |= set(p.writes)
        return cls(initial=tuple(dict.fromkeys(initial)), before=tuple(before))

    def fields_per_step(self) -> tuple:
        """Every field exchanged in a step, in order (a field may come more than once)."""
        return self.initial + tuple(n for b in self.before for n in b)


@jax.tree_util.register_dataclass
@dataclass(frozen=True)
class Halo:
    """The halo of one device for one step.

    down_idx, up_idx     (H,) owned rows sent to the lower / upper slab (first n valid)
    down_ok, up_ok       (H,) bool, which of those are particles
    from_down, from_up   (H,) bool, which received rows (from the lower / upper slab) are particles
    """

    down_idx: jax.Array
    up_idx: jax.Array
    down_ok: jax.Array
    up_ok: jax.Array
    from_down: jax.Array
    from_up: jax.Array


def permute(tree, axis_name: str, perm):
    """`jax.lax.ppermute` of a pytree of (rows, ...) arrays as two messages: every floating leaf
    packed into one (rows, columns) array (differentiable: concatenation and slices), every other
    leaf (int, bool) into one int32 array. One collective per dtype instead of one per leaf: fewer
    operations to compile and fewer messages on the wire."""
    leaves, treedef = jax.tree_util.tree_flatten(tree)
    if not leaves:
        return tree
    rows = leaves[0].shape[0]
    floats = [i for i, x in enumerate(leaves) if jnp.issubdtype(x.dtype, jnp.floating)]
    others = [i for i, x in enumerate(leaves) if i not in floats]
    out = list(leaves)
    for group, dtype in ((floats, None), (others, jnp.int32)):
        if not group:
            continue
        cols = [leaves[i].reshape(rows, -1) for i in group]
        packed = jnp.concatenate([c if dtype is None else c.astype(dtype) for c in cols], axis=1)
        got = jax.lax.ppermute(packed, axis_name, perm)
        at = 0
        for i, c in zip(group, cols):
            x = got[:, at:at + c.shape[1]].reshape(leaves[i].shape)
            out[i] = x if dtype is None else (x != 0 if leaves[i].dtype == jnp.bool_ else x.astype(leaves[i].dtype))
            at += c.shape[1]
    return jax.tree_util.tree_unflatten(treedef, out)


def pick(mask, capacity: int):
    """(indices of the first `capacity` true entries, which of them are real, count of true entries)."""
    idx = jnp.nonzero(mask, size=capacity, fill_value=0)[0].astype(jnp.int32)
    n = jnp.sum(mask, dtype=jnp.int32)
    return idx, jnp.arange(capacity) < n, n


def build(decomp, axis_name: str, r, valid, capacity: int):
    """The halo of this device from its owned positions r (rows `valid`): (Halo, the largest number
    of particles to send to one side, for the overflow check)."""
    k = jax.lax.axis_index(axis_name)
    x = r[:, decomp.axis]
    lo = k.astype(r.dtype) * decomp.width
    hi = (k + 1).astype(r.dtype) * decomp.width
    reach = decomp.halo * (1.0 + 1e-9)   # a hair wide: a pair at exactly cutoff + skin is never cut
    near_down = valid & (x - lo < reach)
    near_up = valid & (hi - x < reach)
    if decomp.devices == 2 and decomp.periodic:
        # both neighbours are the one other device: a particle near both faces (a slab narrower than two
        # halo widths) goes once, with the lower face's copies; the minimum image makes it serve both sides
        near_up = near_up & ~near_down
    down_idx, down_ok, n_down = pick(near_down, capacity)
    up_idx, up_ok, n_up = pick(near_up, capacity)
    from_down = permute(up_ok, axis_name, decomp.perm(+1))
    from_up = permute(down_ok, axis_name, decomp.perm(-1))
    return Halo(down_idx, up_idx, down_ok, up_ok, from_down, from_up), jnp.maximum(n_down, n_up)


def exchange(decomp, axis_name: str, halo: Halo, arrays: dict, n_owned: int) -> dict:
    """Refresh the halo rows of `arrays` (name -> (owned + 2H, ...) rows) from their owners: one
    ppermute of all the fields up and one down. Rows that hold no particle keep their value."""
    if not arrays:
        return arrays
    up = {n: x[:n_owned][halo.up_idx] for n, x in arrays.items()}
    down = {n: x[:n_owned][halo.down_idx] for n, x in arrays.items()}
    got_down = permute(up, axis_name, decomp.perm(+1))      # from the lower slab
    got_up = permute(down, axis_name, decomp.perm(-1))      # from the upper slab
    h = halo.from_down.shape[0]
    out = {}
    for n, x in arrays.items():
        ok_d = halo.from_down.reshape((h,) + (1,) * (x.ndim - 1))
        ok_u = halo.from_up.reshape((h,) + (1,) * (x.ndim - 1))
        old_d, old_u = x[n_owned:n_owned + h], x[n_owned + h:]
        out[n] = jnp.concatenate([x[:n_owned], jnp.where(ok_d, got_down[n], old_d), jnp.where(ok_u, got_up[n], old_u)])
    return out


def extend(x, fill, h: int):
    """Owned rows x followed by 2 h halo rows of the padding value `fill` ((1, ...) rows)."""
    return jnp.concatenate([x, jnp.broadcast_to(jnp.asarray(fill, x.dtype), (2 * h,) + x.shape[1:])])
