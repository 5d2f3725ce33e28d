"""The peer of `make bench-peer`: JAX-SPH 0.1.0's step, assembled as its `simulate.py` does, for a
scene given as plain arrays and settings (a "setup", written by bench/bench_peer.py from our scene).

Imports neither `sph` nor JAX-SPH at module level, so it serves both row sets of bench/bench_peer.py:

* own environment (the headline): run as a worker in .venv-peer (jax 0.4.29, as JAX-SPH's users
  install it; scripts/setup_peer.sh), one process per case, driven over its pipes
  (bench/peer_protocol.py). Like JAX-SPH's main.py, x64 is on only for float64 cases.

      .venv-peer/bin/python -m bench.jaxsph_peer SETUP.npz --steps 100     # from the repo root

* shared jax: imported by bench/bench_peer.py --shared-jax in .venv-lb (the project's jax, with
  lbcompat's aliases), where both codes run in one process with x64 on.

The settings each field of the setup stands for, and why they make the two codes equivalent, are in
bench/bench_peer.py's docstring.
"""
import argparse
import os
import sys

import numpy as np

# setup fields: arrays, then scalars (bench_peer.scene_setup writes them)
ARRAYS = ("r", "u", "tag", "box")
FLOATS = ("dx", "rho_ref", "eta", "u_ref", "c_ref_factor", "gamma", "p_bg_factor", "eta_limiter", "dt")
INTS = ("dim", "n", "ldc_layers")
BOOLS = ("riemann", "tvf", "density_evolution")
STRINGS = ("name", "dtype", "walls")  # walls: "" (none), "no_slip", "free_slip"


def save_setup(path, setup):
    np.savez(path, **{k: np.asarray(setup[k]) for k in ARRAYS + FLOATS + INTS + BOOLS + STRINGS})


def load_setup(path):
    with np.load(path) as z:
        s = {k: np.array(z[k]) for k in ARRAYS}
        s.update({k: float(z[k]) for k in FLOATS})
        s.update({k: int(z[k]) for k in INTS})
        s.update({k: bool(z[k]) for k in BOOLS})
        s.update({k: str(z[k]) for k in STRINGS})
    return s


def peer_bc_fn(setup, dtype):
    """The wall condition of JAX-SPH's cases/ldc.py `_boundary_conditions_fn` (v0.1.0): solid walls
    at rest, moving walls at the lid velocity, no acceleration on either; the identity without walls
    (as its tgv.py)."""
    import jax.numpy as jnp
    from jax_sph.utils import Tag

    if not setup["walls"]:
        return lambda state: state
    moving = setup["tag"] == Tag.MOVING_WALL
    u_lid = jnp.asarray(setup["u"][moving][0] if moving.any() else np.zeros(setup["dim"]), dtype)

    def bc_fn(state):
        mask1 = state["tag"][:, None] == Tag.SOLID_WALL
        mask2 = state["tag"][:, None] == Tag.MOVING_WALL
        state["u"] = jnp.where(mask1, 0.0, state["u"])
        state["v"] = jnp.where(mask1, 0.0, state["v"])
        state["u"] = jnp.where(mask2, u_lid, state["u"])
        state["v"] = jnp.where(mask2, u_lid, state["v"])
        state["dudt"] = jnp.where(mask1, 0.0, state["dudt"])
        state["dvdt"] = jnp.where(mask1, 0.0, state["dvdt"])
        state["dudt"] = jnp.where(mask2, 0.0, state["dudt"])
        state["dvdt"] = jnp.where(mask2, 0.0, state["dvdt"])
        return state

    return bc_fn


def peer_advance(setup):
    """JAX-SPH's jitted `advance(dt, state, neighbors)`, its initial state and neighbour list, with the
    settings its case files would give this scene (bench/bench_peer.py's docstring); compiled and run
    once (dt = 0, as simulate.py does for the initial accelerations). Returns run(steps), the number
    of particles and the neighbour list's edge capacity."""
    import jax
    import jax.numpy as jnp
    import jax_sph.case_setup
    import jax_sph.solver
    import jax_sph.utils
    from jax_sph import partition
    from jax_sph.eos import RIEMANNEoS, TaitEoS
    from jax_sph.integrator import si_euler
    from jax_sph.jax_md import space
    from jax_sph.jax_md.partition import Sparse
    from jax_sph.solver import WCSPH

    dtype = jnp.float64 if setup["dtype"] == "float64" else jnp.float32
    if dtype == jnp.float64 and not jax.config.jax_enable_x64:
        raise RuntimeError("a float64 case needs jax_enable_x64")
    # JAX-SPH runs float32 with x64 off (its main.py enables x64 only for float64), so its module-level
    # EPS = jnp.finfo(float).eps is a float32 there; in a process with x64 on (the shared-jax run) a
    # float64 EPS would promote its float32 step to float64: set it as its own run has it.
    for module in (jax_sph.solver, jax_sph.utils, jax_sph.case_setup):
        module.EPS = jnp.finfo(dtype).eps
    int_dtype = jnp.int64 if dtype == jnp.float64 else jnp.int32  # its default int, x64 on / off

    dim, dx, dt, walls = setup["dim"], setup["dx"], setup["dt"], setup["walls"]
    if setup["riemann"] and walls:
        raise NotImplementedError("JAX-SPH Riemann walls need its wall normals (recomputed every step "
                                  "for moving walls); not set up here")
    box = np.asarray(setup["box"], float)
    rho_ref, u_ref = setup["rho_ref"], setup["u_ref"]
    c_ref = setup["c_ref_factor"] * u_ref
    p_ref = rho_ref * c_ref**2 / setup["gamma"]  # as its case_setup
    p_bg = setup["p_bg_factor"] * p_ref
    if setup["riemann"]:  # its case_setup: RIEMANNEoS for solver RIE (p = 100 u_ref^2 (rho - rho_ref) + p_bg)
        assert setup["c_ref_factor"] == 10.0 and setup["gamma"] == 1.0, "RIEMANNEoS has c_ref = 10 u_ref"
        eos = RIEMANNEoS(rho_ref, p_bg, u_ref)
    else:
        eos = TaitEoS(p_ref, rho_ref, p_bg, setup["gamma"])
    # its case_setup always builds a periodic space (walls, if any, are particles inside the box)
    displacement_fn, shift_fn = space.periodic(side=jnp.asarray(box, dtype))
    n = len(setup["r"])
    r = jnp.asarray(setup["r"], dtype)
    u = jnp.asarray(setup["u"], dtype)
    rho = jnp.full(n, rho_ref, dtype)
    state = {"r": r, "tag": jnp.asarray(setup["tag"], dtype=int_dtype), "u": u, "v": u,
             "dudt": jnp.zeros_like(u), "dvdt": jnp.zeros_like(u), "drhodt": jnp.zeros_like(rho),
             "rho": rho, "p": eos.p_fn(rho), "mass": jnp.full(n, rho_ref * dx**dim, dtype),
             "eta": jnp.full(n, setup["eta"], dtype), "dTdt": jnp.zeros_like(rho), "T": jnp.ones_like(rho),
             "kappa": jnp.zeros_like(rho), "Cp": jnp.zeros_like(rho), "nw": jnp.zeros_like(r)}
    bc_fn = peer_bc_fn(setup, dtype)
    state = bc_fn(state)  # as its case_setup.initialize
    solver = WCSPH(displacement_fn, eos, lambda r: jnp.zeros_like(r), dx, dim, dt, c_ref, setup["eta_limiter"],
                   "RIE" if setup["riemann"] else "SPH", "QSK", bool(walls), setup["density_evolution"], 0.0,
                   walls == "free_slip", False, False)
    forward = solver.forward_wrapper()
    neighbor_fn = partition.neighbor_list(displacement_fn, jnp.asarray(box, dtype), r_cutoff=solver._kernel_fn.cutoff,
                                          backend="jaxmd_vmap", capacity_multiplier=1.25, mask_self=False,
                                          format=Sparse, num_particles_max=n, num_partitions=1,
                                          pbc=np.array([True] * dim))
    neighbors = neighbor_fn.allocate(state["r"], num_particles=n)
    advance = jax.jit(si_euler(1.0 if setup["tvf"] else 0.0, forward, shift_fn, bc_fn, None))
    state, neighbors = advance(0.0, state, neighbors)  # compile; initial accelerations (as simulate.py)
    jax.block_until_ready(state["v"])
    promoted = {k: str(a.dtype) for k, a in state.items() if jnp.issubdtype(a.dtype, jnp.floating) and a.dtype != dtype}
    if promoted:
        raise AssertionError(f"JAX-SPH step is not {jnp.dtype(dtype)}: {promoted}")

    def run(steps):
        nonlocal state, neighbors
        for _ in range(steps):
            new_state, new_nbrs = advance(dt, state, neighbors)
            if new_nbrs.did_buffer_overflow:
                neighbors = neighbor_fn.allocate(state["r"], num_particles=n)
                continue
            state, neighbors = new_state, new_nbrs
        jax.block_until_ready(state["r"])

    return run, int(state["r"].shape[0]), int(neighbors.idx.shape[1])


def peer_ldc_geometry(dx, n_walls=3):
    """Positions and tags of JAX-SPH's own 2D LDC (v0.1.0 cases/ldc.py `_init_pos2D`, not installed
    with the package): walls `pos_box_2d`, fluid shifted by n_walls dx, lid = rows above 1 + n_walls dx."""
    from jax_sph.utils import Tag, pos_box_2d, pos_init_cartesian_2d

    r_f = n_walls * dx + np.asarray(pos_init_cartesian_2d(np.ones(2), dx))
    r_w = np.asarray(pos_box_2d(np.ones(2), dx, n_walls))
    r = np.concatenate([r_w, r_f])
    tag = np.concatenate([np.full(len(r_w), Tag.SOLID_WALL), np.full(len(r_f), Tag.FLUID)])
    box = np.ones(2) + 2 * n_walls * dx
    tag = np.where(r[:, 1] > box[1] - n_walls * dx, Tag.MOVING_WALL, tag)
    return r, tag, box


def check_ldc_geometry(setup):
    """Our cavity (positions, tags incl. the full-width lid, box) against JAX-SPH's own construction."""
    dx = setup["dx"]
    r, tag, box = peer_ldc_geometry(dx, setup["ldc_layers"])
    key = lambda r_: np.lexsort(np.round(r_ / dx, 3).T)  # noqa: E731  (lattice order)
    a, b = key(setup["r"]), key(r)
    if not (len(r) == len(setup["r"]) and np.allclose(setup["r"][a], r[b], rtol=0.0, atol=1e-4 * dx)
            and np.array_equal(setup["tag"][a], tag[b]) and np.allclose(setup["box"], box)):
        raise AssertionError(f"{setup['name']}: our scene differs from JAX-SPH's cases/ldc.py geometry")


def build(setup):
    """peer_advance plus the checks: particle count, and for the cavity the geometry."""
    if setup["ldc_layers"]:
        check_ldc_geometry(setup)
    run, n, edges = peer_advance(setup)
    if n != setup["n"]:
        raise AssertionError(f"{setup['name']}: JAX-SPH has {n} particles, ours {setup['n']}")
    return run, edges


def main():
    from bench.peer_protocol import open_channel, rss_gb, serve

    out = open_channel()
    ap = argparse.ArgumentParser(description="JAX-SPH timing worker (bench/peer_protocol.py)")
    ap.add_argument("setup")
    ap.add_argument("--steps", type=int, required=True, help="steps of the warm-up round")
    args = ap.parse_args()
    setup = load_setup(args.setup)
    import jax
    import jax_sph

    jax.config.update("jax_enable_x64", setup["dtype"] == "float64")  # as JAX-SPH's main.py
    platform = jax.devices()[0].platform
    base = rss_gb()
    run, edges = build(setup)
    serve(out, run, args.steps, {"code": "jax_sph", "jax": jax.__version__, "platform": platform,
                                 "n": setup["n"], "edges": edges, "rss_base_gb": base,
                                 "python": sys.executable,
                                 "code_dir": os.path.dirname(jax_sph.__file__)})


if __name__ == "__main__":
    main()
