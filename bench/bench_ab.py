"""Benchmark: the step of this working tree against the step of another commit, interleaved.

Each side runs in its own worker process (`import sph` from its own tree: the other commit is checked
out once as a git worktree under ~/.cache/sph_bench_ab/<rev>), builds the same scene, compiles a jitted
`lax.scan` chunk of `--steps` steps with the step guard (`make_chunk`, as every run advances) and
then times rounds on request; the driver alternates ref, this, ref, this, ... over pipes
(bench/peer_protocol.py), so that this shared machine's load hits both alike. Reported per case:
min and median wall ms per step of each side and their ratio (this / ref: below 1 is faster), and
the same for the CPU time of the worker process (all threads; less sensitive to other jobs
than wall time on a shared machine); memory: XLA's buffer sizes of the compiled chunk (temporaries + arguments + outputs, exact and
independent of the load) and the peak resident set while stepping above the bare JAX process.

    python bench/bench_ab.py --ref a84d12d                       # every case of the matrix below
    python bench/bench_ab.py --ref a84d12d --cases tgv2d_0.02_sph tgv3d_32_riemann --repeats 7

Cases: `tgv2d_<dx>_<method>` (dx 0.02, 0.01), `tgv3d_<n>_<method>` (n 32, 50 particles per side),
method sph / tvf / riemann; `ldc2d_0.02_<method>` (the walled cavity, no-slip walls with a moving lid)
and `tank_0.02_riemann` (a water column in a closed tank under gravity: one-sided Riemann walls).
All float64, cell_sort neighbour search, lattice positions with 0.05 dx noise.
"""
import argparse
import os
import subprocess
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
METHODS = ("sph", "tvf", "riemann")
CASES = ([f"tgv2d_{dx}_{m}" for dx in ("0.02", "0.01") for m in METHODS]
         + [f"tgv3d_{n}_{m}" for n in (32, 50) for m in METHODS]
         + [f"ldc2d_0.02_{m}" for m in METHODS] + ["tank_0.02_riemann"])


def scene_of(case):
    """The scene of a case name (built from `sph.cases`, present in both trees)."""
    import dataclasses

    import sph
    from sph.cases import ldc, tank, tgv, tgv3d
    from sph.lattice import jitter

    kind, size, method = case.split("_")
    fx = {"sph": {}, "tvf": {"tvf": True}, "riemann": {"riemann": True, "density_evolution": True}}[method]
    mat = sph.Material(eta=0.01)
    if kind == "tgv2d":
        sc = tgv.scene(float(size), mat, sph.Effects(**fx))
    elif kind == "tgv3d":
        sc = tgv3d.scene(tgv3d.dx_for(int(size)), mat, sph.Effects(**fx))
    elif kind == "ldc2d":
        return ldc.scene(float(size), sph.Material(eta=0.01), sph.Effects(walls="no_slip", **fx))
    else:
        return tank.scene(float(size), sph.Material(eta=0.01, u_ref=2.0),
                          sph.Effects(walls="no_slip", gravity=(0.0, -1.0), **fx),
                          width=0.5, height=0.5, tank_length=1.0, tank_height=0.8)
    r = jitter(sc.r, 0.05 * sc.dx, seed=0, box=sc.domain.box)
    return dataclasses.replace(sc, r=r)


def worker(case, steps):
    """Build the case in this process's `sph`, serve timed rounds (bench/peer_protocol.py)."""
    from peer_protocol import open_channel, rss_gb, serve

    out = open_channel()
    import jax

    import sph
    from sph.rollout import make_chunk

    sph.precision.enable_x64()
    jax.numpy.zeros(1).block_until_ready()
    base = rss_gb()
    solver = sph.build_solver(scene_of(case), sph.Numerics(dtype="float64"))
    state, nbrs = solver.init_fn()
    chunk = jax.jit(make_chunk(solver.step_fn, steps, guard=solver.guard)).lower(state, nbrs, 0, steps).compile()
    mem = chunk.memory_analysis()
    xla_gb = (mem.temp_size_in_bytes + mem.argument_size_in_bytes + mem.output_size_in_bytes) / 2**30

    def run(n):
        for _ in range(n // steps):
            out_ = chunk(state, nbrs, 0, steps)
            jax.block_until_ready(out_)
            assert int(out_[2]) == steps and not bool(out_[3]), f"{case}: the chunk overflowed or stopped"

    serve(out, run, steps, {"n": int(solver.scene.n), "k": int(nbrs.idx.shape[1]), "xla_gb": xla_gb,
                            "rss_base_gb": base, "sph": str(Path(sph.__file__).parent)})


def ref_tree(rev):
    """A worktree of `rev` outside the repository, under $XDG_CACHE_HOME (default ~/.cache)/sph_bench_ab
    (made once; outside, so that searches of the tree never see the old code)."""
    sha = subprocess.run(["git", "rev-parse", rev], cwd=ROOT, check=True, capture_output=True, text=True).stdout.strip()
    cache = Path(os.environ.get("XDG_CACHE_HOME", Path.home() / ".cache"))
    path = cache / "sph_bench_ab" / sha[:12]
    if not (path / "sph").is_dir():
        subprocess.run(["git", "worktree", "add", "--detach", "-f", str(path), sha], cwd=ROOT, check=True,
                       capture_output=True)
    return path, sha[:12]


def compare(case, ref_path, steps, repeats):
    from peer_protocol import Worker, interleave

    env = dict(os.environ)
    from sph.xla_cpu import set_cpu_defaults

    set_cpu_defaults()          # the same XLA flags for both sides (the old tree set them on import)
    env["XLA_FLAGS"] = os.environ.get("XLA_FLAGS", "")
    argv = [sys.executable, str(Path(__file__).resolve()), "--worker", case, "--steps", str(steps)]
    ref = Worker(argv, "ref", env={**env, "PYTHONPATH": str(ref_path)})
    this = Worker(argv, "this", env={**env, "PYTHONPATH": str(ROOT)})
    try:
        assert ref.info["sph"] != this.info["sph"], "both workers imported the same sph"
        a, b = interleave(ref, this, steps, repeats)
        ma, mb = ref.quit(), this.quit()
    finally:
        ref.kill(), this.kill()
    ta = 1e3 * np.array([r["wall_s"] / r["steps"] for r in a])
    tb = 1e3 * np.array([r["wall_s"] / r["steps"] for r in b])
    ca = 1e3 * np.array([r["cpu_s"] / r["steps"] for r in a])
    cb = 1e3 * np.array([r["cpu_s"] / r["steps"] for r in b])
    return dict(case=case, n=this.info["n"], k=this.info["k"], ref_min_ms=ta.min(), ref_median_ms=np.median(ta),
                this_min_ms=tb.min(), this_median_ms=np.median(tb), ratio_min=tb.min() / ta.min(),
                ratio_median=np.median(tb) / np.median(ta), ref_cpu_median_ms=np.median(ca),
                this_cpu_median_ms=np.median(cb), cpu_ratio_median=np.median(cb) / np.median(ca), ref_xla_gb=ref.info["xla_gb"],
                this_xla_gb=this.info["xla_gb"], ref_rss_gb=ma["rss_peak_gb"] - ref.info["rss_base_gb"],
                this_rss_gb=mb["rss_peak_gb"] - this.info["rss_base_gb"])


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--ref", help="the commit to compare against (git rev)")
    ap.add_argument("--cases", nargs="+", default=CASES, choices=CASES, metavar="CASE")
    ap.add_argument("--steps", type=int, default=0, help="steps per round (default: 20 in 2D, 3 in 3D)")
    ap.add_argument("--repeats", type=int, default=5, help="rounds per side")
    ap.add_argument("--out", default="results/bench/ab.csv")
    ap.add_argument("--worker", default=None, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.worker:
        return worker(args.worker, args.steps)
    if not args.ref:
        ap.error("--ref: the commit to compare against is required")
    import pandas as pd

    ref_path, sha = ref_tree(args.ref)
    rows = []
    print(f"this tree vs {sha} ({args.ref}), rounds interleaved; ms per step (wall), ratio = this / ref; memory "
          f"GB: XLA buffers of the chunk / peak RSS while stepping above bare JAX", flush=True)
    for case in args.cases:
        steps = args.steps or (3 if case.startswith("tgv3d") else 20)
        r = compare(case, ref_path, steps, args.repeats)
        rows.append(r)
        print(f"  {case:20s} N {r['n']:7d} K {r['k']:4d} | ref {r['ref_min_ms']:9.2f} {r['ref_median_ms']:9.2f} | "
              f"this {r['this_min_ms']:9.2f} {r['this_median_ms']:9.2f} | ratio {r['ratio_min']:.3f} "
              f"{r['ratio_median']:.3f} | CPU ratio {r['cpu_ratio_median']:.3f} | XLA {r['ref_xla_gb']:.3f} / {r['this_xla_gb']:.3f} | RSS "
              f"{r['ref_rss_gb']:.3f} / {r['this_rss_gb']:.3f}", flush=True)
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    pd.DataFrame(rows).assign(ref=sha).to_csv(args.out, index=False)
    print(f"-> {args.out}")


if __name__ == "__main__":
    main()
