"""Benchmark: JAX-SPH 0.1.0's solver step against this project's, side by side (`make bench-peer`).

Two row sets, both from the same scene for both codes (same particle positions, wall particles
included, velocities, time step, quintic kernel h = dx, c_ref = 10 U):

* **own environments (the headline).** JAX-SPH runs in `.venv-peer`: jax 0.4.29 / jaxlib 0.4.29 and
  jax-sph 0.1.0, pinned as its users install it (environment-peer.txt, built on first use by
  scripts/setup_peer.sh), in its own process (`bench/jaxsph_peer.py` as a worker), x64 on only for
  float64 (as its main.py), no XLA flags of ours. This project runs in `.venv` in another process
  (this file with `--worker-ours`), x64 on only for float64 (as our float32 runs), under the entry
  points' XLA CPU defaults. Our worker builds the scene and writes it, with every setting below, to a
  .npz file; the JAX-SPH worker builds its solver from that file. The driver (this file, in `.venv`)
  alternates their rounds over pipes (bench/peer_protocol.py) and collects wall time, CPU time and
  peak memory of each process.
* **shared jax.** Both codes in one process in `.venv-lb` (`--shared-jax`): JAX-SPH 0.1.0 on the
  project's jax (`lbcompat` restores the jax aliases it imports), x64 on for all cases, both under the
  XLA CPU defaults. Memory is not separable there and not reported.

The two codes:

* JAX-SPH: its `WCSPH` + `si_euler` + neighbour list exactly as its `simulate.py` builds them
  (Sparse jax-md list, backend "jaxmd_vmap", capacity_multiplier 1.25, no skin: rebuilt every step),
  one jitted `advance` call per step, as its simulation loop does. Its settings follow the scene's
  effects and our numerics, as its case files would set them: `solver.name` "RIE" for Riemann SPH
  (EoS `RIEMANNEoS`, linear with c = 10 U, as its case_setup picks for RIE) else "SPH" (Tait,
  gamma 1); `solver.tvf` 1 with TVF; `solver.density_evolution`; `solver.is_bc_trick` with walls;
  `eta_limiter` and `eos.p_bg_factor` = ours. (bench/jaxsph_peer.py)
* this project: `sph.build_solver` + a jitted `lax.scan` chunk of the same steps (the way every run
  here advances), neighbour search `--backend` (default cell_sort, Verlet skin 0.5 dx).

Cases (all by default):

* TGV 2D, dx 0.02 (50^2 particles, lattice + 0.05 dx noise, periodic), Re 100: standard SPH, TVF
  and Riemann SPH, each in float64 and float32. Riemann SPH is JAX-SPH's `solver.name=RIE
  solver.density_evolution=True` (as its validation/tgv2d.sh runs it): density evolution with the
  Riemann velocity, dissipation limiter eta = 3 (its default), no density renormalization, no TVF;
  ours `sph.Effects(riemann=True, density_evolution=True)` with `Numerics.eta_limiter` 3, no
  re-initialization. float32 as JAX-SPH runs it (its main.py leaves x64 off, so its module-level
  EPS = jnp.finfo(float).eps is a float32): in its own environment x64 is off for float32 as there;
  in the shared-jax process x64 is on for the float64 cases, so the peer's EPS is set to the case's
  dtype, and its step is checked to keep every field in that dtype (a float64 EPS promoted the
  float32 step to float64; that case failed before).
* lid-driven cavity 2D, dx 0.02, Re 100, float64: JAX-SPH's own LDC case (cases/ldc.py +
  ldc.yaml of v0.1.0) runs standard SPH (solver.name SPH, tvf 0), the generalized wall BC
  (`is_bc_trick`, no-slip), EoS background pressure p_bg = 0.01 p_ref and a fixed dt = 4e-4;
  so do both codes here (ours: `sph.cases.ldc.scene` with `Effects(walls="no_slip")`,
  `Numerics(p_bg_factor=0.01, dt=4e-4)`). Geometry: 3 cell-centred wall layers around [0, 1]^2
  (shifted by 3 dx), the top 3 rows moving at U = 1 *including* the corner blocks (JAX-SPH's
  full-width lid; our ldc2d experiment instead fixes those corners, `lid_corners: fixed`): 2500
  fluid + 636 wall particles, 168 of them moving. The positions and tags are checked against
  JAX-SPH's own construction (`pos_box_2d` + `pos_init_cartesian_2d`, lid mask of cases/ldc.py)
  before timing (by the JAX-SPH side, where jax_sph is installed). Wall particles keep their
  prescribed velocity in JAX-SPH through the case's `_boundary_conditions_fn`, reproduced in
  bench/jaxsph_peer.py (cases/ is not part of the installed package).
  Differences that remain: JAX-SPH's case setup always makes the box periodic (side 1 + 6 dx,
  pbc true), so its neighbour list also pairs the outer wall layers across the periodic boundary
  (1662 extra wall-wall pairs on top of 35970 at dx 0.02, +4.6%; edges it evaluates, without
  effect on the fluid: wall states come from fluid neighbours only and wall accelerations are
  reset); ours is a closed, non-periodic box. Both codes take our scene's particle order (fluid
  first, then walls) instead of JAX-SPH's (walls first). The lattice starts at rest (JAX-SPH's
  `r0_type: cartesian` default; its validation run starts from a relaxed state).
* TGV 3D, 20^3 and 32^3 (periodic (2 pi)^3, Re 100), standard SPH, float64.

Timings alternate A, B, A, B, ... (JAX-SPH, ours; `--repeats` rounds of `--steps` steps each, after
one warm-up round that also compiles); min and median wall time per step of each and the ratio
JAX-SPH / ours; the same for CPU time (whole process, all threads: on a shared machine less
sensitive to other jobs than wall time); in the own-environment rows the peak resident set of
each process while stepping (bench/peer_protocol.py says how it is read). This machine is shared
and noisy: only ratios from the same run mean anything. Writes results/bench/peer.csv (column
`env`: own / shared) and prints both tables.

Run from the repository root (with `-m`, `bench` and `lbcompat` import from there, no path set-up):

    .venv/bin/python -m bench.bench_peer                          # every case, both row sets
    .venv/bin/python -m bench.bench_peer --quick                  # 2D SPH f64 and 3D 12^3 only
    .venv/bin/python -m bench.bench_peer --cases tgv2d_dx0.02_sph_f64,tgv3d_20_sph_f64 --no-shared
    .venv-lb/bin/python -m bench.bench_peer --shared-jax          # the shared-jax rows alone
"""
import os

_ENV0 = dict(os.environ)  # as the driver started: its workers set their own XLA flags

import argparse  # noqa: E402
import csv  # noqa: E402
import json  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from typing import Callable, NamedTuple  # noqa: E402

if __name__ == "__main__" and not __package__:
    sys.exit("run from the repository root as a module: python -m bench.bench_peer ...")

import jax  # noqa: E402
import numpy as np  # noqa: E402

import sph  # noqa: E402
from bench.bench_scaling import tgv2d_scene, tgv3d_scene  # noqa: E402
from bench.jaxsph_peer import save_setup  # noqa: E402
from bench.peer_protocol import (Worker, format_table, interleave, open_channel, rss_gb, serve,  # noqa: E402
                                 summarize)
from sph.cases import ldc  # noqa: E402
from sph.rollout import make_chunk  # noqa: E402

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
YNN_FLAG = "--xla_cpu_experimental_ynn_fusion_type"


def xla_cpu_defaults():
    """The entry points' XLA CPU defaults (sph.xla_cpu), before the first JAX computation."""
    from sph.xla_cpu import set_cpu_defaults

    set_cpu_defaults()


def peer_env():
    """The environment of the JAX-SPH worker: the driver's as it started, without our XLA flag (JAX-SPH
    runs as its users run it; an unknown flag would abort jaxlib 0.4.29)."""
    env = dict(_ENV0)
    flags = [f for f in env.get("XLA_FLAGS", "").split() if not f.startswith(YNN_FLAG)]
    if flags:
        env["XLA_FLAGS"] = " ".join(flags)
    else:
        env.pop("XLA_FLAGS", None)
    return env


# ---------------------------------------------------------------------------------------------------
# the scenes
# ---------------------------------------------------------------------------------------------------

LDC_LAYERS = 3


def ldc2d_scene(dx, layers=LDC_LAYERS):
    """Our cavity (sph.cases.ldc, full-width moving lid as JAX-SPH's; the JAX-SPH side checks it against
    its own cases/ldc.py geometry, bench/jaxsph_peer.check_ldc_geometry)."""
    return ldc.scene(dx, sph.Material(rho_ref=1.0, eta=0.01, u_ref=1.0), sph.Effects(walls="no_slip"),
                     layers=layers, lid_velocity=1.0)


def scene_setup(name, scene, numerics, dt, ldc_layers=0):
    """What the JAX-SPH side needs of a case (bench/jaxsph_peer.py: its fields), as plain values."""
    mat, fx = scene.material, scene.effects
    return dict(name=name, dtype=numerics.dtype, r=np.asarray(scene.r), u=np.asarray(scene.u),
                tag=np.asarray(scene.tag), box=np.asarray(scene.domain.box, float), dim=scene.dim, n=scene.n,
                dx=scene.dx, rho_ref=mat.rho_ref, eta=mat.eta, u_ref=mat.u_ref,
                c_ref_factor=numerics.c_ref_factor, gamma=numerics.gamma, p_bg_factor=numerics.p_bg_factor,
                eta_limiter=numerics.eta_limiter, dt=float(dt), riemann=bool(fx.riemann), tvf=bool(fx.tvf),
                density_evolution=bool(fx.density_evolution), walls=fx.walls or "", ldc_layers=ldc_layers)


class Case(NamedTuple):
    make: Callable          # () -> sph.Scene
    dtype: str
    overrides: dict         # sph.Numerics overrides (JAX-SPH follows them)
    steps: int              # steps per round
    ldc_layers: int = 0     # > 0: the cavity, checked against JAX-SPH's own geometry


RIEMANN = sph.Effects(riemann=True, density_evolution=True)
LDC = {"p_bg_factor": 0.01, "dt": 4e-4}  # JAX-SPH cases/ldc.yaml: eos.p_bg_factor 0.01, solver.dt 0.0004
CASES = {
    "tgv2d_dx0.02_sph_f64": Case(lambda: tgv2d_scene(50), "float64", {}, 100),
    "tgv2d_dx0.02_tvf_f64": Case(lambda: tgv2d_scene(50, sph.Effects(tvf=True)), "float64", {}, 100),
    "tgv2d_dx0.02_riemann_f64": Case(lambda: tgv2d_scene(50, RIEMANN), "float64", {}, 100),
    "tgv2d_dx0.02_sph_f32": Case(lambda: tgv2d_scene(50), "float32", {}, 100),
    "tgv2d_dx0.02_tvf_f32": Case(lambda: tgv2d_scene(50, sph.Effects(tvf=True)), "float32", {}, 100),
    "tgv2d_dx0.02_riemann_f32": Case(lambda: tgv2d_scene(50, RIEMANN), "float32", {}, 100),
    "ldc2d_dx0.02_sph_f64": Case(lambda: ldc2d_scene(0.02), "float64", LDC, 100, LDC_LAYERS),
    "tgv3d_20_sph_f64": Case(lambda: tgv3d_scene(20), "float64", {}, 22),   # ours rebuilds about every 11 steps:
    "tgv3d_32_sph_f64": Case(lambda: tgv3d_scene(32), "float64", {}, 11),   # whole rebuild periods per round
}
QUICK = {"tgv2d_dx0.02_sph_f64": CASES["tgv2d_dx0.02_sph_f64"],
         "tgv3d_12_sph_f64": Case(lambda: tgv3d_scene(12), "float64", {}, 6)}
KNOWN = {**CASES, **QUICK}


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


def build_ours(name, backend):
    case = KNOWN[name]
    scene = case.make()
    numerics = sph.Numerics(dtype=case.dtype, neighbor_search=backend, **case.overrides)
    run, dt, k = ours_advance(scene, numerics)
    return run, k, scene_setup(name, scene, numerics, dt, case.ldc_layers)


def ours_worker(args):
    """This project's timing worker (own-environment rows): builds the case, writes its setup for the
    JAX-SPH worker, then serves rounds (bench/peer_protocol.py)."""
    out = open_channel()
    xla_cpu_defaults()
    if KNOWN[args.worker_ours].dtype == "float64":
        sph.precision.enable_x64()
    platform = jax.devices()[0].platform
    base = rss_gb()
    run, k, setup = build_ours(args.worker_ours, args.backend)
    save_setup(args.setup_out, setup)
    serve(out, run, args.steps, {"code": "ours", "jax": jax.__version__, "platform": platform, "n": setup["n"],
                                 "K": k, "dt": setup["dt"], "rss_base_gb": base, "python": sys.executable,
                                 "code_dir": os.path.dirname(sph.__file__)})


# ---------------------------------------------------------------------------------------------------
# the two row sets
# ---------------------------------------------------------------------------------------------------

def own_env_case(name, steps, repeats, backend, ours_python, peer_python, tmp):
    """One headline row: each code in its own process and environment, rounds interleaved."""
    setup = os.path.join(tmp, f"{name}.npz")
    ours = peer = None
    try:
        ours = Worker([ours_python, "-m", "bench.bench_peer", "--worker-ours", name, "--backend", backend,
                       "--steps", str(steps), "--setup-out", setup], "ours", env=_ENV0, cwd=ROOT)
        peer = Worker([peer_python, "-m", "bench.jaxsph_peer", setup, "--steps", str(steps)], "JAX-SPH",
                      env=peer_env(), cwd=ROOT)
        peer_rounds, ours_rounds = interleave(peer, ours, steps, repeats)
        peer_mem, ours_mem = peer.quit(), ours.quit()
    finally:
        for w in (peer, ours):
            if w is not None:
                w.kill()
    row = dict(env="own", case=name, n=ours.info["n"], dtype=KNOWN[name].dtype, backend=backend,
               dt=ours.info["dt"], steps=steps, repeats=repeats, K_ours=ours.info["K"],
               edges_jax_sph=peer.info["edges"], jax_jax_sph=peer.info["jax"], jax_ours=ours.info["jax"],
               sph_dir=ours.info["code_dir"], jax_sph_dir=peer.info["code_dir"])
    row.update(summarize(peer_rounds, ours_rounds))
    for who, mem in (("jax_sph", peer_mem), ("ours", ours_mem)):
        for key in ("rss_base_gb", "rss_peak_gb", "rss_max_gb"):
            row[f"{who}_{key}"] = mem[key]
    row["rss_method"] = ours_mem["rss_method"]
    return row


def shared_case(name, steps, repeats, backend):
    """One shared-jax row: both codes in this process (.venv-lb), rounds interleaved."""
    from bench import jaxsph_peer

    ours, k, setup = build_ours(name, backend)
    theirs, edges = jaxsph_peer.build(setup)
    ours(steps)  # compile and warm up
    theirs(steps)
    rounds = {"jax_sph": [], "ours": []}
    for _ in range(repeats):
        for who, fn in (("jax_sph", theirs), ("ours", ours)):
            t0, c0 = time.perf_counter(), time.process_time()
            fn(steps)
            rounds[who].append({"steps": steps, "wall_s": time.perf_counter() - t0,
                                "cpu_s": time.process_time() - c0})
    row = dict(env="shared", case=name, n=setup["n"], dtype=setup["dtype"], backend=backend, dt=setup["dt"],
               steps=steps, repeats=repeats, K_ours=k, edges_jax_sph=edges, jax_jax_sph=jax.__version__,
               jax_ours=jax.__version__)
    row.update(summarize(rounds["jax_sph"], rounds["ours"]))
    return row


def shared_jax_rows(args, cases):
    """The --shared-jax mode (in .venv-lb)."""
    import lbcompat

    lbcompat.apply_jax_aliases()
    xla_cpu_defaults()
    sph.precision.enable_x64()
    print(f"shared jax {jax.__version__} on {jax.devices()[0].platform}", file=sys.stderr, flush=True)
    rows = []
    for name in cases:
        rows.append(shared_case(name, args.steps or KNOWN[name].steps, args.repeats, args.backend))
        print(format_table(rows[-1:], f"shared jax: {name}"), file=sys.stderr, flush=True)
    return rows


def write_csv(path, rows):
    fields = []
    for r in rows:
        fields += [k for k in r if k not in fields]
    with open(path, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=fields, restval="")
        w.writeheader()
        w.writerows(rows)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--steps", type=int, default=None, help="steps per round (default: per case)")
    ap.add_argument("--cases", default=None, help="comma-separated subset of " + ",".join(KNOWN))
    ap.add_argument("--backend", default="cell_sort", choices=["cell_sort", "jax_md"])
    ap.add_argument("--out", default="results/bench")
    ap.add_argument("--no-shared", action="store_true", help="skip the shared-jax rows (.venv-lb)")
    ap.add_argument("--no-own", action="store_true", help="skip the own-environment rows (.venv-peer)")
    ap.add_argument("--peer-python", default=os.path.join(ROOT, ".venv-peer", "bin", "python"))
    ap.add_argument("--lb-python", default=os.path.join(ROOT, ".venv-lb", "bin", "python"))
    ap.add_argument("--shared-jax", action="store_true", help="run the shared-jax rows in this process "
                    "(in .venv-lb); with --json, write them there")
    ap.add_argument("--json", default=None, help=argparse.SUPPRESS)
    ap.add_argument("--worker-ours", default=None, help=argparse.SUPPRESS)
    ap.add_argument("--setup-out", default=None, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.worker_ours:
        return ours_worker(args)
    cases = list(QUICK if args.quick else CASES)
    if args.cases:
        cases = args.cases.split(",")
        unknown = [k for k in cases if k not in KNOWN]
        if unknown:
            ap.error(f"--cases: unknown {unknown}; known: {list(KNOWN)}")
    if args.shared_jax:
        rows = shared_jax_rows(args, cases)
        if args.json:
            with open(args.json, "w") as f:
                json.dump(rows, f)
        else:
            print(format_table(rows, "shared jax (both codes in one process)"))
        return
    for skip, python, how in ((args.no_own, args.peer_python, "bash scripts/setup_peer.sh"),
                              (args.no_shared, args.lb_python, "make setup-lb")):
        if not skip and not os.access(python, os.X_OK):
            sys.exit(f"{python} not found: build it with `{how}` (or skip its rows: --no-own / --no-shared)")
    os.makedirs(args.out, exist_ok=True)
    rows = []
    if not args.no_own:
        own = []
        with tempfile.TemporaryDirectory(prefix="bench_peer_") as tmp:
            for name in cases:
                own.append(own_env_case(name, args.steps or KNOWN[name].steps, args.repeats, args.backend,
                                        sys.executable, args.peer_python, tmp))
                print(format_table(own[-1:], f"own environments: {name}"), file=sys.stderr, flush=True)
                write_csv(os.path.join(args.out, "peer.csv"), rows + own)
        rows += own
    if not args.no_shared:
        with tempfile.TemporaryDirectory(prefix="bench_peer_") as tmp:
            out = os.path.join(tmp, "shared.json")
            cmd = [args.lb_python, "-m", "bench.bench_peer", "--shared-jax", "--cases", ",".join(cases),
                   "--repeats", str(args.repeats), "--backend", args.backend, "--json", out]
            if args.steps:
                cmd += ["--steps", str(args.steps)]
            import subprocess

            subprocess.run(cmd, check=True, cwd=ROOT, env=_ENV0)
            with open(out) as f:
                rows += json.load(f)
        write_csv(os.path.join(args.out, "peer.csv"), rows)
    own = [r for r in rows if r["env"] == "own"]
    if own:
        print(f"this project: {own[0]['sph_dir']}; JAX-SPH: {own[0]['jax_sph_dir']}")
    shared = [r for r in rows if r["env"] == "shared"]
    if own:
        print(format_table(own, f"JAX-SPH 0.1.0 in its own environment (jax {own[0]['jax_jax_sph']}, .venv-peer) "
                                f"against ours (jax {own[0]['jax_ours']}, .venv), one process each"))
    if shared:
        print(format_table(shared, f"shared jax {shared[0]['jax_ours']} (.venv-lb): both codes in one process"))
    print(f"wrote {args.out}/peer.csv")


if __name__ == "__main__":
    main()
