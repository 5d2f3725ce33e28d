"""Migration after the drift: particles that left their slab move to their new owner (issue 40, item 1).

Each device finds its particles whose slab (`Decomposition.slab_of`) is now the lower or the upper
neighbour, gathers them into a send buffer of fixed capacity Q per side and `ppermute`s it; the
particles that stay are compacted to the front and the arrivals appended, then the padding rows are
reset to their finite fill. Three flags, never a silent drop: a send buffer too small (`migrate`),
the owned rows too few for stayers and arrivals (`owned`), and a particle that moved more than one
slab in a step (`far`, a refusal: the time step lets particles cross a whole slab).
"""
from dataclasses import replace

import jax
import jax.numpy as jnp

from .halo import permute, pick


def _rows(tree, idx):
    return jax.tree_util.tree_map(lambda x: x[idx], tree)


def _where_rows(ok, a, b):
    return jax.tree_util.tree_map(lambda x, y: jnp.where(ok.reshape(ok.shape + (1,) * (x.ndim - 1)), x, y), a, b)


def migrate(decomp, axis_name: str, shard, fill, q: int):
    """(the shard after migration, need: (largest send count, rows needed), far: count of particles
    that moved more than one slab). `fill` is `sph.parallel.layout.fill_row`."""
    k = jax.lax.axis_index(axis_name)
    d = decomp.devices
    m = shard.capacity
    slab = decomp.slab_of(shard.state.r[:, decomp.axis])
    valid = shard.valid
    up_slab, down_slab = (k + 1) % d if decomp.periodic else k + 1, (k - 1) % d if decomp.periodic else k - 1
    go_up = valid & (slab == up_slab) & (slab != k)
    go_down = valid & (slab == down_slab) & (slab != k) & ~go_up
    stay = valid & (slab == k)
    far = jnp.sum(valid & ~stay & ~go_up & ~go_down, dtype=jnp.int32)

    up_idx, up_ok, n_up = pick(go_up, q)
    down_idx, down_ok, n_down = pick(go_down, q)
    send_up = replace(_rows(shard, up_idx), valid=up_ok)
    send_down = replace(_rows(shard, down_idx), valid=down_ok)
    from_down = permute(send_up, axis_name, decomp.perm(+1))
    from_up = permute(send_down, axis_name, decomp.perm(-1))

    order = jnp.argsort(~stay, stable=True)
    kept = _rows(shard, order)
    n_keep = jnp.sum(stay, dtype=jnp.int32)
    n_d = jnp.sum(from_down.valid, dtype=jnp.int32)
    n_u = jnp.sum(from_up.valid, dtype=jnp.int32)
    slot = jnp.arange(q, dtype=jnp.int32)
    dest_d = jnp.where(from_down.valid, n_keep + slot, m)          # received rows are first in their buffer
    dest_u = jnp.where(from_up.valid, n_keep + n_d + slot, m)

    def place(x, a, b):
        return x.at[dest_d].set(a, mode="drop").at[dest_u].set(b, mode="drop")

    out = jax.tree_util.tree_map(place, kept, from_down, from_up)
    n_own = n_keep + n_d + n_u
    live = jnp.arange(m) < n_own
    out = _where_rows(live, out, jax.tree_util.tree_map(lambda f: jnp.broadcast_to(f, (m,) + f.shape[1:]), fill))
    out = replace(out, valid=live)
    return out, (jnp.maximum(n_up, n_down), n_own), far
