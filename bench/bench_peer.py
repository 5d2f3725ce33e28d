"""Benchmark: JAX-SPH 0.1.0's solver step against this project's, side by side (`make bench-peer`).

Runs in `.venv-lb` (JAX-SPH 0.1.0 installed there; `lbcompat` restores the jax aliases it imports;
same jax as the core environment). Both codes advance the same scene (same particle positions, wall
particles included, velocities, time step, quintic kernel h = dx, c_ref = 10 U):

* JAX-SPH: its `WCSPH` + `si_euler` + neighbour list exactly as its `simulate.py` builds them
  (Sparse jax-md list, backend "jaxmd_vmap", capacity_multiplier 1.25, no skin: rebuilt every step),
  one jitted `advance` call per step, as its simulation loop does. Its settings follow the scene's
  effects and our numerics, as its case files would set them: `solver.name` "RIE" for Riemann SPH
  (EoS `RIEMANNEoS`, linear with c = 10 U, as its case_setup picks for RIE) else "SPH" (Tait,
  gamma 1); `solver.tvf` 1 with TVF; `solver.density_evolution`; `solver.is_bc_trick` with walls;
  `eta_limiter` and `eos.p_bg_factor` = ours.
* this project: `sph.build_solver` + a jitted `lax.scan` chunk of the same steps (the way every run
  here advances), neighbour search `--backend` (default cell_sort, Verlet skin 0.5 dx).

Cases (all by default):

* TGV 2D, dx 0.02 (50^2 particles, lattice + 0.05 dx noise, periodic), Re 100: standard SPH, TVF
  and Riemann SPH, each in float64 and float32. Riemann SPH is JAX-SPH's `solver.name=RIE
  solver.density_evolution=True` (as its validation/tgv2d.sh runs it): density evolution with the
  Riemann velocity, dissipation limiter eta = 3 (its default), no density renormalization, no TVF;
  ours `sph.Effects(riemann=True, density_evolution=True)` with `Numerics.eta_limiter` 3, no
  re-initialization. float32 as JAX-SPH runs it (its main.py leaves x64 off, so its module-level
  EPS = jnp.finfo(float).eps is a float32): this process has x64 on for the float64 cases, so the
  peer's EPS is set to the case's dtype, and its step is checked to keep every field in that dtype
  (a float64 EPS promoted the float32 step to float64; that case failed before).
* lid-driven cavity 2D, dx 0.02, Re 100, float64: JAX-SPH's own LDC case (cases/ldc.py +
  ldc.yaml of v0.1.0) runs standard SPH (solver.name SPH, tvf 0), the generalized wall BC
  (`is_bc_trick`, no-slip), EoS background pressure p_bg = 0.01 p_ref and a fixed dt = 4e-4;
  so do both codes here (ours: `sph.cases.ldc.scene` with `Effects(walls="no_slip")`,
  `Numerics(p_bg_factor=0.01, dt=4e-4)`). Geometry: 3 cell-centred wall layers around [0, 1]^2
  (shifted by 3 dx), the top 3 rows moving at U = 1 *including* the corner blocks (JAX-SPH's
  full-width lid; our ldc2d experiment instead fixes those corners, `lid_corners: fixed`): 2500
  fluid + 636 wall particles, 168 of them moving. The positions and tags are checked against
  JAX-SPH's own construction (`pos_box_2d` + `pos_init_cartesian_2d`, lid mask of cases/ldc.py)
  before timing. Wall particles keep their prescribed velocity in JAX-SPH through the case's
  `_boundary_conditions_fn`, reproduced here (cases/ is not part of the installed package).
  Differences that remain: JAX-SPH's case setup always makes the box periodic (side 1 + 6 dx,
  pbc true), so its neighbour list also pairs the outer wall layers across the periodic boundary
  (1662 extra wall-wall pairs on top of 35970 at dx 0.02, +4.6%; edges it evaluates, without
  effect on the fluid: wall states come from fluid neighbours only and wall accelerations are
  reset); ours is a closed, non-periodic box. Both codes take our scene's particle order (fluid
  first, then walls) instead of JAX-SPH's (walls first). The lattice starts at rest (JAX-SPH's
  `r0_type: cartesian` default; its validation run starts from a relaxed state).
* TGV 3D, 20^3 and 32^3 (periodic (2 pi)^3, Re 100), standard SPH, float64.

Timings alternate A, B, A, B, ... (`--repeats` rounds of `--steps` steps each, after one warm-up
round that also compiles); min and median time per step of each and the ratio JAX-SPH / ours.
This machine is shared and noisy: only ratios from the same run mean anything.
Writes results/bench/peer.csv and prints a table.

    .venv-lb/bin/python bench/bench_peer.py                 # every case above
    .venv-lb/bin/python bench/bench_peer.py --quick         # 2D SPH f64 and 3D 12^3 only
    .venv-lb/bin/python bench/bench_peer.py --cases ldc2d_dx0.02_sph_f64 --steps 3 --repeats 1
"""
import argparse
import csv
import os
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from lbcompat import apply_jax_aliases  # noqa: E402

apply_jax_aliases()

import jax  # noqa: E402
import jax.numpy as jnp  # noqa: E402

import sph  # noqa: E402
from bench_scaling import tgv2d_scene, tgv3d_scene  # noqa: E402
from sph.cases import ldc  # noqa: E402
from sph.rollout import make_chunk  # noqa: E402


# ---------------------------------------------------------------------------------------------------
# the peer: JAX-SPH 0.1.0, assembled as its simulate.py does
# ---------------------------------------------------------------------------------------------------

def peer_bc_fn(scene, dtype):
    """The wall condition of JAX-SPH's cases/ldc.py `_boundary_conditions_fn` (v0.1.0): solid walls
    at rest, moving walls at the lid velocity, no acceleration on either; the identity without walls
    (as its tgv.py)."""
    from jax_sph.utils import Tag

    if scene.effects.walls is None:
        return lambda state: state
    moving = scene.tag == sph.MOVING_WALL
    u_lid = jnp.asarray(scene.u[moving][0] if moving.any() else np.zeros(scene.dim), dtype)

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


def peer_advance(scene, numerics, dt, dtype):
    """JAX-SPH's jitted `advance(dt, state, neighbors)`, its initial state and neighbour list, with
    the settings its case files would give this scene (module docstring)."""
    import jax_sph.case_setup
    import jax_sph.solver
    import jax_sph.utils
    from jax_sph import partition
    from jax_sph.eos import RIEMANNEoS, TaitEoS
    from jax_sph.integrator import si_euler
    from jax_sph.jax_md import space
    from jax_sph.jax_md.partition import Sparse
    from jax_sph.solver import WCSPH

    # JAX-SPH runs float32 with x64 off (its main.py enables x64 only for float64), so its
    # module-level EPS = jnp.finfo(float).eps is a float32 there; here x64 is on for our float64
    # cases, and a float64 EPS would promote its float32 step to float64: set it as its own run has it.
    for module in (jax_sph.solver, jax_sph.utils, jax_sph.case_setup):
        module.EPS = jnp.finfo(dtype).eps
    int_dtype = jnp.int64 if dtype == jnp.float64 else jnp.int32  # its default int, x64 on / off

    dim, dx, mat, fx = scene.dim, scene.dx, scene.material, scene.effects
    if fx.riemann and fx.walls is not None:
        raise NotImplementedError("JAX-SPH Riemann walls need its wall normals (recomputed every step "
                                  "for moving walls); not set up here")
    box = np.asarray(scene.domain.box, float)
    c_ref = numerics.c_ref_factor * mat.u_ref
    p_ref = mat.rho_ref * c_ref**2 / numerics.gamma  # as its case_setup
    p_bg = numerics.p_bg_factor * p_ref
    if fx.riemann:  # its case_setup: RIEMANNEoS for solver RIE (p = 100 u_ref^2 (rho - rho_ref) + p_bg)
        assert numerics.c_ref_factor == 10.0 and numerics.gamma == 1.0, "RIEMANNEoS has c_ref = 10 u_ref"
        eos = RIEMANNEoS(mat.rho_ref, p_bg, mat.u_ref)
    else:
        eos = TaitEoS(p_ref, mat.rho_ref, p_bg, numerics.gamma)
    # its case_setup always builds a periodic space (walls, if any, are particles inside the box)
    displacement_fn, shift_fn = space.periodic(side=jnp.asarray(box, dtype))
    n = scene.n
    r = jnp.asarray(scene.r, dtype)
    u = jnp.asarray(scene.u, dtype)
    rho = jnp.full(n, mat.rho_ref, dtype)
    state = {"r": r, "tag": jnp.asarray(scene.tag, dtype=int_dtype), "u": u, "v": u,
             "dudt": jnp.zeros_like(u), "dvdt": jnp.zeros_like(u), "drhodt": jnp.zeros_like(rho),
             "rho": rho, "p": eos.p_fn(rho), "mass": jnp.full(n, mat.rho_ref * dx**dim, dtype),
             "eta": jnp.full(n, mat.eta, dtype), "dTdt": jnp.zeros_like(rho), "T": jnp.ones_like(rho),
             "kappa": jnp.zeros_like(rho), "Cp": jnp.zeros_like(rho), "nw": jnp.zeros_like(r)}
    bc_fn = peer_bc_fn(scene, dtype)
    state = bc_fn(state)  # as its case_setup.initialize
    solver = WCSPH(displacement_fn, eos, lambda r: jnp.zeros_like(r), dx, dim, dt, c_ref, numerics.eta_limiter,
                   "RIE" if fx.riemann else "SPH", "QSK", fx.walls is not None, fx.density_evolution, 0.0,
                   fx.walls == "free_slip", False, False)
    forward = solver.forward_wrapper()
    neighbor_fn = partition.neighbor_list(displacement_fn, jnp.asarray(box, dtype), r_cutoff=solver._kernel_fn.cutoff,
                                          backend="jaxmd_vmap", capacity_multiplier=1.25, mask_self=False,
                                          format=Sparse, num_particles_max=n, num_partitions=1,
                                          pbc=np.array([True] * dim))
    neighbors = neighbor_fn.allocate(state["r"], num_particles=n)
    advance = jax.jit(si_euler(1.0 if fx.tvf else 0.0, forward, shift_fn, bc_fn, None))
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


def ldc2d_scene(dx, layers=3):
    """Our cavity (sph.cases.ldc, full-width moving lid as JAX-SPH), checked against JAX-SPH's own."""
    scene = ldc.scene(dx, sph.Material(rho_ref=1.0, eta=0.01, u_ref=1.0), sph.Effects(walls="no_slip"),
                      layers=layers, lid_velocity=1.0)
    r, tag, box = peer_ldc_geometry(dx, layers)
    key = lambda r_: np.lexsort(np.round(r_ / dx, 3).T)  # noqa: E731  (lattice order)
    a, b = key(scene.r), key(r)
    if not (len(r) == scene.n and np.allclose(scene.r[a], r[b], rtol=0.0, atol=1e-4 * dx)
            and np.array_equal(scene.tag[a], tag[b]) and np.allclose(scene.domain.box, box)):
        raise AssertionError(f"ldc2d dx {dx}: our scene differs from JAX-SPH's cases/ldc.py geometry")
    return scene


# ---------------------------------------------------------------------------------------------------
# this project
# ---------------------------------------------------------------------------------------------------

def ours_advance(scene, numerics):
    solver = sph.build_solver(scene, numerics)
    state, nbrs = solver.init_fn()
    chunks = {}
    carry = [state, nbrs, 0]

    def run(steps):
        if steps not in chunks:
            chunks[steps] = jax.jit(make_chunk(solver.step_fn, steps))
        state, nbrs, step = carry
        state, nbrs, _ = sph.rollout.advance(chunks[steps], solver.neighbors, state, nbrs, step, steps)
        jax.block_until_ready(state.r)
        carry[:] = [state, nbrs, step + steps]

    return run, solver.dt, int(nbrs.max_occupancy)


# name: (scene, dtype, sph.Numerics overrides (JAX-SPH follows them), steps per round)
RIEMANN = sph.Effects(riemann=True, density_evolution=True)
LDC = {"p_bg_factor": 0.01, "dt": 4e-4}  # JAX-SPH cases/ldc.yaml: eos.p_bg_factor 0.01, solver.dt 0.0004
CASES = {
    "tgv2d_dx0.02_sph_f64": (lambda: tgv2d_scene(50), "float64", {}, 100),
    "tgv2d_dx0.02_tvf_f64": (lambda: tgv2d_scene(50, sph.Effects(tvf=True)), "float64", {}, 100),
    "tgv2d_dx0.02_riemann_f64": (lambda: tgv2d_scene(50, RIEMANN), "float64", {}, 100),
    "tgv2d_dx0.02_sph_f32": (lambda: tgv2d_scene(50), "float32", {}, 100),
    "tgv2d_dx0.02_tvf_f32": (lambda: tgv2d_scene(50, sph.Effects(tvf=True)), "float32", {}, 100),
    "tgv2d_dx0.02_riemann_f32": (lambda: tgv2d_scene(50, RIEMANN), "float32", {}, 100),
    "ldc2d_dx0.02_sph_f64": (lambda: ldc2d_scene(0.02), "float64", LDC, 100),
    "tgv3d_20_sph_f64": (lambda: tgv3d_scene(20), "float64", {}, 22),   # ours rebuilds about every 11 steps:
    "tgv3d_32_sph_f64": (lambda: tgv3d_scene(32), "float64", {}, 11),   # whole rebuild periods per round
}
QUICK = {"tgv2d_dx0.02_sph_f64": CASES["tgv2d_dx0.02_sph_f64"],
         "tgv3d_12_sph_f64": (lambda: tgv3d_scene(12), "float64", {}, 6)}


def bench_case(name, make, dtype, overrides, steps, repeats, backend):
    scene = make()
    numerics = sph.Numerics(dtype=dtype, neighbor_search=backend, **overrides)
    ours, dt, k_ours = ours_advance(scene, numerics)
    theirs, n_theirs, k_theirs = peer_advance(scene, numerics, dt, jnp.float64 if dtype == "float64" else jnp.float32)
    if n_theirs != scene.n:
        raise AssertionError(f"{name}: JAX-SPH has {n_theirs} particles, ours {scene.n}")
    ours(steps)  # compile and warm up
    theirs(steps)
    times = {"jax_sph": [], "ours": []}
    for _ in range(repeats):
        for who, fn in (("jax_sph", theirs), ("ours", ours)):
            t0 = time.perf_counter()
            fn(steps)
            times[who].append((time.perf_counter() - t0) / steps)
    t_j, t_o = np.array(times["jax_sph"]), np.array(times["ours"])
    return dict(case=name, n=scene.n, n_jax_sph=n_theirs, dtype=dtype, backend=backend, dt=dt, steps=steps,
                repeats=repeats, K_ours=k_ours, edges_jax_sph=k_theirs,
                jax_sph_min_ms=1e3 * t_j.min(), jax_sph_median_ms=1e3 * np.median(t_j),
                ours_min_ms=1e3 * t_o.min(), ours_median_ms=1e3 * np.median(t_o),
                ratio_min=t_j.min() / t_o.min(), ratio_median=np.median(t_j) / np.median(t_o))


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--steps", type=int, default=None, help="steps per round (default: per case)")
    ap.add_argument("--cases", default=None, help="comma-separated subset of " + ",".join({**CASES, **QUICK}))
    ap.add_argument("--backend", default="cell_sort", choices=["cell_sort", "jax_md"])
    ap.add_argument("--out", default="results/bench")
    args = ap.parse_args()
    sph.precision.enable_x64()
    cases = QUICK if args.quick else CASES
    if args.cases:
        known = {**CASES, **QUICK}
        unknown = [k for k in args.cases.split(",") if k not in known]
        if unknown:
            ap.error(f"--cases: unknown {unknown}; known: {list(known)}")
        cases = {k: known[k] for k in args.cases.split(",")}
    os.makedirs(args.out, exist_ok=True)
    print(f"jax {jax.__version__} on {jax.devices()[0].platform}; interleaved JAX-SPH, ours; ratio = JAX-SPH / ours")
    print(f"{'case':26s} {'N':>7s} {'JAX-SPH min':>11s} {'median':>9s} {'ours min':>9s} {'median':>9s} "
          f"{'ratio min':>9s} {'median':>7s}  (ms per step)")
    rows = []
    for name, (make, dtype, overrides, steps) in cases.items():
        r = bench_case(name, make, dtype, overrides, args.steps or steps, args.repeats, args.backend)
        rows.append(r)
        print(f"{r['case']:26s} {r['n']:7d} {r['jax_sph_min_ms']:11.2f} {r['jax_sph_median_ms']:9.2f} "
              f"{r['ours_min_ms']:9.2f} {r['ours_median_ms']:9.2f} {r['ratio_min']:9.2f} {r['ratio_median']:7.2f}",
              flush=True)
        with open(os.path.join(args.out, "peer.csv"), "w", newline="") as f:
            w = csv.DictWriter(f, fieldnames=list(rows[0]))
            w.writeheader()
            w.writerows(rows)
    print(f"wrote {args.out}/peer.csv")


if __name__ == "__main__":
    main()
