"""Pair geometry over a dense neighbour list: the one place where neighbour data is gathered.

With jax-md's Dense format, `idx` has shape (N, K) and is padded with N. Every pairwise sum is then a
gather plus a reduction over the last axis, which needs no scatter-add. Vector pair quantities are
stored component-major, (dim, N, K), so every component is a contiguous (N, K) slab that XLA
vectorizes well (twice as fast on CPU as an (N, K, dim) layout). Padded slots get a distance beyond
the kernel support, so W = dW/dr = 0 there and no masking is needed in the physics; distances use a
safe square root so gradients stay finite.

`row_blocked` (below) evaluates a function of the pairs in blocks of particles, so that the pair
arrays stay in cache; the solver runs the pair work of every step through it.
"""
import math
from dataclasses import dataclass

import jax
import jax.numpy as jnp


@jax.tree_util.register_dataclass
@dataclass(frozen=True)
class Pairs:
    """Neighbour geometry of every particle i with its K neighbour slots j.

    j    (N, K) neighbour index (padding clipped to a valid index, see `mask`)
    mask (N, K) true for real neighbours
    dr   (dim, N, K) r_i - r_j (minimum image; arbitrary but finite in padded slots)
    d    (N, K) |r_ij| (beyond the kernel support in padded slots)
    w    (N, K) W(|r_ij|)
    f    (N, K) dW/dr / |r_ij|, the scalar factor of most SPH pair terms
    """

    j: jax.Array
    mask: jax.Array
    dr: jax.Array
    d: jax.Array
    w: jax.Array
    f: jax.Array

    def gather(self, x):
        """x_j of a per-particle scalar for every pair: (N,) -> (N, K)."""
        return take(x, self.j)

    def gather_vec(self, x):
        """x_j of a per-particle vector, component-major: (N, dim) -> (dim, N, K)."""
        x_t = x.T
        return jnp.stack([take(x_t[a], self.j) for a in range(x_t.shape[0])])

    @staticmethod
    def own_vec(x):
        """x_i of a per-particle vector broadcast against pairs: (N, dim) -> (dim, N, 1)."""
        return x.T[:, :, None]

    @staticmethod
    def sum_vec(x):
        """Sum a component-major pair vector over neighbours: (dim, N, K) -> (N, dim)."""
        return jnp.sum(x, axis=-1).T

    @property
    def e(self):
        """Unit vectors e_ij = r_ij / |r_ij| (dim, N, K)."""
        return self.dr / self.d

    @property
    def grad_w(self):
        """Kernel gradient with respect to r_i: dW/dr e_ij (dim, N, K)."""
        return self.f * self.dr


def take(x, j):
    """x[j] for a 1D array x and indices 0 <= j < len(x): a bare XLA gather (`x[j]` first maps
    negative indices, three more operations per pair and gathered field; 2D step 15 % faster)."""
    dn = jax.lax.GatherDimensionNumbers(offset_dims=(), collapsed_slice_dims=(0,), start_index_map=(0,))
    return jax.lax.gather(x, j[..., None], dn, slice_sizes=(1,), mode=jax.lax.GatherScatterMode.PROMISE_IN_BOUNDS)


def cdot(a, b):
    """Component-wise dot product of two component-major pair vectors: (dim, N, K) -> (N, K).

    Written as an explicit sum over the few components: XLA fuses it, whereas a reduction over the
    leading axis is lowered to a separate, several times slower reduce on CPU.
    """
    out = a[0] * b[0]
    for k in range(1, a.shape[0]):
        out = out + a[k] * b[k]
    return out


def pair_geometry(r, idx, domain, margin, kernel) -> Pairs:
    """Gather positions over the neighbour list and evaluate the kernel for every pair.

    `domain.minimum_image(delta, axis, margin)` wraps each component as the neighbour search does.
    """
    n = r.shape[0]
    mask = idx < n
    j = jnp.where(mask, idx, 0)
    r_t = r.T
    dr = jnp.stack([domain.minimum_image(r_t[a][:, None] - take(r_t[a], j), a, margin) for a in range(r.shape[1])])
    far = 2.0 * kernel.cutoff
    d = jnp.sqrt(jnp.where(mask, cdot(dr, dr), far * far))
    dw = kernel.dwdr(d)
    return Pairs(j=j, mask=mask, dr=dr, d=d, w=kernel.w(d), f=dw / d)


# ---------------------------------------------------------------------------------------------------
# Row blocking: a per-particle function of the pairs evaluated in cache-sized blocks of particles
# ---------------------------------------------------------------------------------------------------
#
# Written over the whole (N, K) list, every pair quantity of a step (dr, |r|, W, dW/dr, the gathered
# neighbour fields, the pair terms) is an (N, K) array that XLA's CPU backend materialises between
# its fusions: at 50^3 particles and K = 231 slots each is 230 MB, and a step streams dozens of them
# through memory (2.7 GB peak). `row_blocked` evaluates the same function for blocks of B particles
# at a time (a `lax.map` over blocks), so that the pair arrays of one block (B x K, ~ BLOCK_PAIRS
# slots) stay in cache and are never all allocated at once: TGV, float64, standard SPH, time per
# step 1.4x shorter than unblocked at 32^3 and 50^3, peak memory at 50^3 1.1 GB instead of 2.7 GB.
# The physics modules are unchanged: the function is traced once over the full arrays, and its
# jaxpr is re-evaluated block by block.
#
# Inside a block, pair vectors that the physics stacks component-major ((dim, B, K), `gather_vec`,
# `dr`) are kept as their dim separate (B, K) components (`_Split`), so that XLA sees the same
# scalar slabs as a hand-written kernel would (stacked, the block step is 2x slower).
#
# In the jaxpr every value is either *global* (per particle or constant: computed once, over all N
# particles) or *local* (depends on the neighbour list `idx`, the seed, row by row: computed per
# block, its row axis sliced to the block's B rows). A local equation takes the block's rows of its
# global operands (`lax.dynamic_slice` along the row axis), except the operand of a gather (x[j]:
# the neighbours' values), which it needs whole. When a gather needs a local value whole (the
# momentum equation gathering the density that the summation just produced), that value is
# materialised: the blocks end there (one *pass*), their per-particle results are concatenated, and
# the next pass over the blocks recomputes whatever pair quantities it needs (the geometry is
# cheaper to recompute from cache than to stream from memory). The same holds for any operation
# that is not row-local (a reduction over particles, a sort, a cond): its local operands are
# materialised and it runs over all N particles. Every row is computed with exactly the operations
# of the unblocked function, so results agree to round-off (summation order within XLA's fusions).
# Blocks are B consecutive rows, B evened out over the blocks (ceil(N / ceil(N / B)): 6400 rows at a
# target of 5242 are two blocks of 3200, not 5242 + 5242); when B does not divide N, the last block is
# shifted back to end at row N (it overlaps the one before, and only its new rows are kept), so no
# row is padded or fabricated.

BLOCK_PAIRS = 1 << 18
"""Target neighbour slots per block (B = BLOCK_PAIRS // K rows); a list with at most one block's
worth of particles is evaluated unblocked. 2^18 (B ~ 1100 rows in 3D, 5000 in 2D) was the fastest of
2^16 ... 2^19 on this CPU (2 cores, 2 MB L2, 32 MB L3) at 20^3 and 50^3 and as fast at 32^3 and 2D
dx 0.01 (2D dx 0.02, 2500 particles, is one block). Module-level so that tests and benchmarks can
change it."""

_INLINE = frozenset({"jit", "pjit", "closed_call", "core_call"})
_ELEMENTWISE = frozenset(
    "abs acos acosh add and asin asinh atan atan2 atanh cbrt ceil clamp convert_element_type copy copy_p cos "
    "cosh div eq erf erf_inv erfc exp exp2 expm1 floor ge gt integer_pow is_finite le log log1p logistic lt "
    "max min mul ne neg nextafter not or pow reduce_precision rem round rsqrt select_n sign sin sinh sqrt "
    "square stop_gradient sub tan tanh xor".split())
_REDUCE = frozenset({"reduce_sum", "reduce_max", "reduce_min", "reduce_prod", "reduce_and", "reduce_or",
                     "argmax", "argmin"})


class _NotLocal(Exception):
    """An equation that cannot be evaluated row block by row block (it then runs over all rows)."""


@dataclass(frozen=True)
class _Lit:
    val: object


@dataclass
class _Eqn:
    prim: object
    params: dict
    ins: list
    outs: list


def _flatten_jaxpr(closed, in_ids, new_id, avals, consts, eqns):
    """Append the equations of `closed` (nested jit calls inlined) to `eqns`, with integer variable
    ids; returns the atoms (ids or _Lit) of its outputs."""
    from jax.extend.core import Literal

    env = {}
    jaxpr = closed.jaxpr
    for v, c in zip(jaxpr.constvars, closed.consts):
        i = new_id(v.aval)
        consts[i] = c
        env[v] = i
    for v, a in zip(jaxpr.invars, in_ids):
        env[v] = a

    def read(x):
        return _Lit(x.val) if isinstance(x, Literal) else env[x]

    for e in jaxpr.eqns:
        ins = [read(x) for x in e.invars]
        if e.primitive.name in _INLINE and "jaxpr" in e.params:
            outs = _flatten_jaxpr(e.params["jaxpr"], ins, new_id, avals, consts, eqns)
            for v, a in zip(e.outvars, outs):
                env[v] = a
            continue
        outs = [new_id(v.aval) for v in e.outvars]
        for v, a in zip(e.outvars, outs):
            env[v] = a
        eqns.append(_Eqn(e.primitive, dict(e.params), ins, outs))
    return [read(v) for v in jaxpr.outvars]


def _bind(prim, params, vals):
    out = prim.bind(*vals, **prim.get_bind_params(params))
    return list(out) if prim.multiple_results else [out]


class _Split(list):
    """A block value held as its components along a short leading axis (the dim components of a
    pair vector, `sph.pairs` stacks them): each component is an array of the remaining shape. Inside
    a block the physics then runs on separate (B, K) slabs, as a hand-written kernel would, instead
    of (dim, B, K) stacks that XLA copies together and reduces in a separate, slower pass."""


def _join(v):
    return jnp.stack(v) if isinstance(v, _Split) else v


def _components(v, c):
    """Operand v of a component-wise operation on c components."""
    if isinstance(v, _Split):
        return list(v)
    if jnp.ndim(v) == 0:
        return [v] * c
    if v.shape[0] == 1:
        return [jax.lax.index_in_dim(v, 0, 0, keepdims=False)] * c
    return [jax.lax.index_in_dim(v, k, 0, keepdims=False) for k in range(c)]


_SPLIT_REDUCE = {"reduce_sum": jnp.add, "reduce_max": jnp.maximum, "reduce_min": jnp.minimum}


def _apply_split(prim, params, vals):
    """prim(*vals) inside a block, keeping pair vectors split into components where it can."""
    name = prim.name
    if name == "stack" and params["axis"] == 0 and not any(isinstance(v, _Split) for v in vals) \
            and len({jnp.shape(v) for v in vals}) == 1 and len(vals) <= 4:
        return _Split(vals)
    split = [v for v in vals if isinstance(v, _Split)]
    if not split:
        return _bind(prim, params, vals)[0]
    c = len(split[0])
    if name in _ELEMENTWISE and all(len(v) == c for v in split) and all(
            not hasattr(v, "shape") or isinstance(v, _Split) or jnp.ndim(v) == 0 or v.shape[0] in (1, c) for v in vals):
        comps = [_components(v, c) for v in vals]
        return _Split(_bind(prim, params, [cs[k] for cs in comps])[0] for k in range(c))
    (v,) = vals if len(vals) == 1 else (None,)
    if v is not None:
        if name == "slice":
            start, limit = params["start_indices"], params["limit_indices"]
            strides = params["strides"]
            shape0 = jnp.shape(v[0])
            if (strides is None or all(st == 1 for st in strides)) and all(
                    a == 0 and z == d for a, z, d in zip(start[1:], limit[1:], shape0)):
                return _Split(v[start[0]:limit[0]])
        elif name == "squeeze":
            dims = params["dimensions"]
            if 0 in dims and c == 1:
                rest = tuple(d - 1 for d in dims if d != 0)
                return jax.lax.squeeze(v[0], rest) if rest else v[0]
            if 0 not in dims:
                return _Split(jax.lax.squeeze(x, tuple(d - 1 for d in dims)) for x in v)
        elif name in _SPLIT_REDUCE:
            axes = params["axes"]
            rest = tuple(d - 1 for d in axes if d != 0)
            parts = [_bind(prim, {**params, "axes": rest}, [x])[0] if rest else x for x in v]
            if 0 not in axes:
                return _Split(parts)
            out = parts[0]
            for x in parts[1:]:
                out = _SPLIT_REDUCE[name](out, x)
            return out
        elif name == "transpose" and params["permutation"][0] == 0:
            perm = tuple(d - 1 for d in params["permutation"][1:])
            return _Split(jax.lax.transpose(x, perm) for x in v)
        elif name == "broadcast_in_dim" and params["broadcast_dimensions"][:1] == (0,) and params["shape"][0] == c:
            dims = tuple(d - 1 for d in params["broadcast_dimensions"][1:])
            sub = {**params, "shape": tuple(params["shape"][1:]), "broadcast_dimensions": dims}
            return _Split(_bind(prim, sub, [x])[0] for x in v)
    return _bind(prim, params, [_join(x) for x in vals])[0]


def _local_rule(e, avals, axis_of, n, b):
    """Row axes of the operands and of the output of a local equation, and its params for a block of
    b rows. axis_of(atom) is the row axis of a local operand, None for a global one. Returns
    (out_axis, operand axes (slice a global operand along it; None: take it whole), params)."""
    name, params = e.prim.name, e.params
    if len(e.outs) != 1:
        raise _NotLocal(name)
    out_shape = avals[e.outs[0]].shape
    local_axes = {axis_of(a) for a in e.ins if axis_of(a) is not None}
    if name in _ELEMENTWISE or name == "concatenate":
        if len(local_axes) != 1:
            raise _NotLocal(name)
        ax = local_axes.pop()
        if name == "concatenate" and params["dimension"] == ax:
            raise _NotLocal(name)
        return ax, [ax] * len(e.ins), params
    if name == "stack":
        if len(local_axes) != 1:
            raise _NotLocal(name)
        (ax,) = local_axes
        out = ax + 1 if params["axis"] <= ax else ax
        return out, [ax] * len(e.ins), params
    if name == "gather":
        op, idx = e.ins[0], e.ins[1]
        dn = params["dimension_numbers"]
        if axis_of(idx) is None or dn.operand_batching_dims or len(e.ins) != 2:
            raise _NotLocal(name)
        ia = axis_of(idx)
        ivd = len(avals[idx].shape) - 1 if isinstance(idx, int) else None
        if ia == ivd:
            raise _NotLocal(name)
        k = ia - (1 if ia > ivd else 0)                       # which batch dimension of the indices
        batch_out = [d for d in range(len(out_shape)) if d not in dn.offset_dims]
        return batch_out[k], [None, ia], params
    if len(local_axes) != 1:
        raise _NotLocal(name)
    (ax,) = local_axes
    if name == "broadcast_in_dim":
        if len(e.ins) != 1:
            raise _NotLocal(name)
        out = params["broadcast_dimensions"][ax]
        shape = list(params["shape"])
        shape[out] = b
        return out, [ax], {**params, "shape": tuple(shape)}
    if name == "transpose":
        return list(params["permutation"]).index(ax), [ax], params
    if name == "squeeze":
        dims = params["dimensions"]
        if ax in dims:
            raise _NotLocal(name)
        return ax - sum(d < ax for d in dims), [ax], params
    if name in _REDUCE:
        axes = params["axes"]
        if ax in axes:
            raise _NotLocal(name)
        return ax - sum(d < ax for d in axes), [ax], params
    if name == "slice":
        start, limit, strides = params["start_indices"], params["limit_indices"], params["strides"]
        if start[ax] != 0 or limit[ax] != n or (strides is not None and strides[ax] != 1):
            raise _NotLocal(name)
        limit = list(limit)
        limit[ax] = b
        return ax, [ax], {**params, "limit_indices": tuple(limit)}
    if name == "reshape" and params.get("dimensions") is None and len(e.ins) == 1:
        shape = avals[e.ins[0]].shape
        pre, post = math.prod(shape[:ax]), math.prod(shape[ax + 1:])
        for o in range(len(out_shape)):
            if out_shape[o] == n and math.prod(out_shape[:o]) == pre and math.prod(out_shape[o + 1:]) == post:
                sizes = list(params["new_sizes"])
                sizes[o] = b
                return o, [ax], {**params, "new_sizes": tuple(sizes)}
        raise _NotLocal(name)
    raise _NotLocal(name)


def row_blocked(fn, block_rows: int, local_argnums=(0,)):
    """fn evaluated in blocks of `block_rows` rows (see the notes above). The leaves of the arguments
    `local_argnums` (the neighbour list idx, shape (N, K)) are the row-local seeds; every other
    argument is global. Same signature and results as fn (to round-off); differentiable."""

    def blocked(*args):
        seeds = [args[i] for i in local_argnums]
        n = int(jax.tree_util.tree_leaves(seeds)[0].shape[0])
        b = int(block_rows)
        if b >= n:
            return fn(*args)
        b = -(-n // -(-n // b))   # even blocks: the fewest blocks of <= block_rows rows, equal sizes
        closed, out_shape = jax.make_jaxpr(fn, return_shape=True)(*args)
        flat_args = jax.tree_util.tree_leaves(args)
        local_in = set()
        pos = 0
        for k, a in enumerate(args):
            m = len(jax.tree_util.tree_leaves(a))
            if k in local_argnums:
                local_in.update(range(pos, pos + m))
            pos += m
        out_flat = _evaluate_blocked(closed, flat_args, local_in, n, b)
        return jax.tree_util.tree_unflatten(jax.tree_util.tree_structure(out_shape), out_flat)

    return blocked


def _evaluate_blocked(closed, flat_args, local_in, n, b):
    avals, consts, eqns = [], {}, []

    def new_id(aval):
        avals.append(aval)
        return len(avals) - 1

    in_ids = [new_id(v.aval) for v in closed.jaxpr.invars]
    out_atoms = _flatten_jaxpr(closed, in_ids, new_id, avals, consts, eqns)

    # -- analysis: local values (row axis, earliest pass), when globals are ready ------------------
    axis, stage, ready = {}, {}, {}
    seeds = set()
    lazy = {}                 # global broadcasts of a scalar: re-emitted at a block's shape
    materialize = set()       # local values needed over all rows (available after their pass)
    for i, a in enumerate(in_ids):
        if i in local_in:
            if avals[a].shape[:1] != (n,):
                raise ValueError(f"row_blocked: a local argument has shape {avals[a].shape}, not ({n}, ...)")
            axis[a], stage[a] = 0, -1
            seeds.add(a)
        else:
            ready[a] = 0
    for c in consts:
        ready[c] = 0

    def axis_of(x):
        return axis.get(x) if isinstance(x, int) else None

    def whole(x):
        """The pass before which x is available over all rows (materialising a local value)."""
        if not isinstance(x, int):
            return 0
        if x in axis:
            if x not in seeds:
                materialize.add(x)
            return stage[x] + 1
        return ready[x]

    plans = {}
    for k, e in enumerate(eqns):
        if any(axis_of(x) is not None for x in e.ins):
            try:
                out_axis, in_axes, params = _local_rule(e, avals, axis_of, n, b)
            except _NotLocal:
                pass
            else:
                s = 0
                for x, ia in zip(e.ins, in_axes):
                    s = max(s, stage[x] if (axis_of(x) is not None and ia is not None) else whole(x))
                axis[e.outs[0]], stage[e.outs[0]] = out_axis, s
                plans[k] = (in_axes, params)
                continue
        r = max([whole(x) for x in e.ins] + [0])
        for o in e.outs:
            ready[o] = r
        if (e.prim.name == "broadcast_in_dim" and len(e.ins) == 1 and isinstance(e.ins[0], int)
                and avals[e.ins[0]].shape == ()):
            lazy[e.outs[0]] = k
    for x in out_atoms:
        whole(x)

    # global equations actually needed (lazy broadcasts consumed by blocks are re-emitted there)
    used = {x for x in out_atoms if isinstance(x, int)} | materialize
    for k in range(len(eqns) - 1, -1, -1):
        e = eqns[k]
        if k in plans:
            for x, ia in zip(e.ins, plans[k][0]):
                if isinstance(x, int):
                    used.add(eqns[lazy[x]].ins[0] if (x in lazy and ia is not None) else x)
        elif any(o in used for o in e.outs):
            used.update(x for x in e.ins if isinstance(x, int))

    producer = {o: k for k, e in enumerate(eqns) for o in e.outs}
    n_pass = max([stage[m] + 1 for m in materialize] + [0])
    targets = [sorted(m for m in materialize if stage[m] == t) for t in range(n_pass)]

    # -- evaluation ---------------------------------------------------------------------------------
    genv = dict(consts)
    whole_local = {}          # seeds and materialised local values
    for i, (a, v) in enumerate(zip(in_ids, flat_args)):
        (whole_local if i in local_in else genv)[a] = v

    def gval(x):
        if isinstance(x, _Lit):
            return x.val
        return whole_local[x] if x in axis else genv[x]

    pending = sorted((ready[e.outs[0]], k) for k, e in enumerate(eqns)
                     if k not in plans and e.outs and any(o in used for o in e.outs))
    gi = 0
    nb = -(-n // b)
    last = n - (nb - 1) * b   # rows of the last block not already in the block before
    for t in range(n_pass + 1):
        while gi < len(pending) and pending[gi][0] <= t:
            e = eqns[pending[gi][1]]
            gi += 1
            for o, v in zip(e.outs, _bind(e.prim, e.params, [gval(x) for x in e.ins])):
                genv[o] = v
        if t == n_pass:
            break
        need, todo = set(), list(targets[t])
        while todo:
            v = todo.pop()
            if v in need or v in whole_local:
                continue
            need.add(v)
            k = producer[v]
            for x, ia in zip(eqns[k].ins, plans[k][0]):
                if axis_of(x) is not None and ia is not None:
                    todo.append(x)
        eqn_order = sorted({producer[v] for v in need})

        def body(blk, eqn_order=eqn_order, tgt=targets[t]):
            start = jnp.minimum(blk * b, n - b)
            lenv = {}

            def rows(val, ax):
                return jax.lax.dynamic_slice_in_dim(val, start, b, axis=ax)

            def block_val(x, ia):
                """Operand x of a local equation whose row axis is ia (None: x is taken whole)."""
                if isinstance(x, _Lit):
                    return x.val
                if x in lenv:
                    return lenv[x]
                if ia is None:
                    return gval(x)
                if x in axis:       # a seed or a materialised local value: its block's rows
                    return rows(gval(x), axis[x])
                if x in lazy:
                    le = eqns[lazy[x]]
                    shape = list(avals[x].shape)
                    if len(shape) > ia and shape[ia] == n:
                        shape[ia] = b
                    return _bind(le.prim, {**le.params, "shape": tuple(shape)}, [gval(le.ins[0])])[0]
                val = gval(x)
                if jnp.ndim(val) <= ia or val.shape[ia] != n:
                    return val
                return rows(val, ia)

            for k in eqn_order:
                e = eqns[k]
                in_axes, params = plans[k]
                lenv[e.outs[0]] = _apply_split(e.prim, params, [block_val(x, ia) for x, ia in zip(e.ins, in_axes)])
            return [_join(lenv[m]) for m in tgt]

        outs = jax.lax.map(body, jnp.arange(nb, dtype=jnp.int32))
        for m, o in zip(targets[t], outs):
            a = axis[m]
            o = jnp.moveaxis(o, 0, a)                      # (..., nb, b, ...)
            merged = o.reshape(o.shape[:a] + (nb * b,) + o.shape[a + 2:])
            head = jax.lax.slice_in_dim(merged, 0, (nb - 1) * b, axis=a)
            tail = jax.lax.slice_in_dim(merged, nb * b - last, nb * b, axis=a)
            whole_local[m] = jnp.concatenate([head, tail], axis=a)
    return [gval(x) for x in out_atoms]
