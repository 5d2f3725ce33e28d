"""Benchmark: time per step and peak memory of the TGV in 2D and 3D, standard SPH, TVF and Riemann SPH
(the table of the README's "Speed" section).

Every case runs in its own process (so that its peak resident memory is its own): the default
numerics (float64, quintic kernel, the default neighbour search, skin 0.5 dx), the scene of
bench_scaling.py (lattice + 0.05 dx noise), a jitted chunk of `steps` steps with the step guard
(`sph.rollout.make_chunk`, as the runs advance; the steps include the neighbour-list rebuilds at
their natural rate, about one in 11 steps at the start of the vortex), compiled before timing; min
and median over `--rounds` chunks. 3D cases use numerics.neighbor_search cell_sort explicitly (the
3D experiments' setting, also when the default was jax-md).

`--compare PATH` runs every case also with the `sph` of another checkout (PATH/sph, e.g. a
`git worktree` of an older commit), alternating the two (current, other, current, other) so that the
load of a shared machine falls on both; the table then gives both and their ratio (min over runs).

    python bench/bench_speed.py                               # all cases, SPH / TVF / Riemann
    python bench/bench_speed.py --cases 2d_dx0.02 3d_32 --methods sph
    python bench/bench_speed.py --compare /tmp/head           # before / after
"""
import argparse
import json
import os
import subprocess
import sys

CASES = {  # name -> (dim, particles per side, steps per chunk)
    "2d_dx0.02": (2, 50, 200),
    "2d_dx0.0125": (2, 80, 150),
    "2d_dx0.01": (2, 100, 100),
    "3d_20": (3, 20, 22),
    "3d_32": (3, 32, 11),
    "3d_50": (3, 50, 12),
}
METHODS = ("sph", "tvf", "riemann")


def _import_sph_from(path):
    """Import the package `sph` from PATH/sph, ahead of the installed (editable) one."""
    import importlib.util

    spec = importlib.util.spec_from_file_location("sph", os.path.join(path, "sph", "__init__.py"),
                                                  submodule_search_locations=[os.path.join(path, "sph")])
    module = importlib.util.module_from_spec(spec)
    sys.modules["sph"] = module
    spec.loader.exec_module(module)


def child(dim, side, steps, method, rounds):
    import resource
    import time

    if os.environ.get("BENCH_SPH_PATH"):
        _import_sph_from(os.environ["BENCH_SPH_PATH"])

    import jax
    import numpy as np

    import sph
    from sph.rollout import make_chunk

    from bench_scaling import tgv2d_scene, tgv3d_scene  # this script's folder comes first on the import path

    effects = {"sph": sph.Effects(), "tvf": sph.Effects(tvf=True),
               "riemann": sph.Effects(riemann=True, density_evolution=True)}[method]
    scene = (tgv3d_scene if dim == 3 else tgv2d_scene)(side, effects)
    numerics = sph.Numerics(neighbor_search="cell_sort") if dim == 3 else sph.Numerics()
    solver = sph.build_solver(scene, numerics)
    state, nbrs = solver.init_fn()
    t0 = time.perf_counter()
    chunk = jax.jit(make_chunk(solver.step_fn, steps, guard=solver.guard)).lower(state, nbrs, 0, steps).compile()
    compile_s = time.perf_counter() - t0
    out = chunk(state, nbrs, 0, steps)
    jax.block_until_ready(out)
    assert int(out[2]) == steps and not bool(out[3]), "the chunk overflowed or was stopped"
    times = []
    for _ in range(rounds):
        t0 = time.perf_counter()
        jax.block_until_ready(chunk(state, nbrs, 0, steps))
        times.append((time.perf_counter() - t0) / steps)
    print(json.dumps(dict(n=scene.n, K=int(nbrs.idx.shape[1]), search=numerics.neighbor_search,
                          ms_min=1e3 * min(times), ms_median=1e3 * float(np.median(times)), compile_s=compile_s,
                          peak_gb=resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 2**20,
                          sph_file=sph.__file__)))


def run_case(name, method, rounds, path=None):
    dim, side, steps = CASES[name]
    env = dict(os.environ)
    if path:
        env["BENCH_SPH_PATH"] = os.path.abspath(path)
    cmd = [sys.executable, os.path.abspath(__file__), "--child", str(dim), str(side), str(steps), method, str(rounds)]
    res = subprocess.run(cmd, env=env, capture_output=True, text=True)
    if res.returncode:
        raise RuntimeError(f"{name} {method}{' (' + path + ')' if path else ''} failed:\n{res.stderr[-3000:]}")
    return json.loads(res.stdout.strip().splitlines()[-1])


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", nargs="+", default=list(CASES), choices=list(CASES))
    ap.add_argument("--methods", nargs="+", default=list(METHODS), choices=list(METHODS))
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--compare", default=None, help="a checkout whose sph/ is timed against this one")
    ap.add_argument("--child", nargs=5, default=None, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child:
        dim, side, steps, method, rounds = args.child
        child(int(dim), int(side), int(steps), method, int(rounds))
        return
    from sph.xla_cpu import set_cpu_defaults

    set_cpu_defaults()  # in XLA_FLAGS, which the children (either checkout's sph) inherit
    head = f"{'case':10s} {'method':8s} {'N':>7s} {'K':>4s} {'ms/step min':>11s} {'median':>8s} {'peak GB':>7s}"
    print(head + (f" {'other min':>9s} {'median':>8s} {'peak GB':>7s} {'speed-up':>8s}" if args.compare else ""))
    for name in args.cases:
        for method in args.methods:
            runs = {"this": [], "other": []}
            for _ in range(2 if args.compare else 1):
                runs["this"].append(run_case(name, method, args.rounds))
                if args.compare:
                    runs["other"].append(run_case(name, method, args.rounds, args.compare))
            a = min(runs["this"], key=lambda r: r["ms_min"])
            line = (f"{name:10s} {method:8s} {a['n']:7d} {a['K']:4d} {a['ms_min']:11.2f} {a['ms_median']:8.2f} "
                    f"{max(r['peak_gb'] for r in runs['this']):7.2f}")
            if args.compare:
                b = min(runs["other"], key=lambda r: r["ms_min"])
                line += (f" {b['ms_min']:9.2f} {b['ms_median']:8.2f} {max(r['peak_gb'] for r in runs['other']):7.2f} "
                         f"{b['ms_min'] / a['ms_min']:8.2f}")
            print(line, flush=True)


if __name__ == "__main__":
    main()
