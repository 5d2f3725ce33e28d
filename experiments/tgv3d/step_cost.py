"""Cost of the 3D Taylor-Green runs without running them: ms per step of every method at the given
resolutions, from a short run of the driver the experiment uses (sph.simulate.run: jitted chunks
with the step guard, compilation excluded), and the time a full run to t_end would take.

The particles start on the lattice (no relaxation): the cost per step depends on the neighbour
count, which the relaxed start changes by a few per cent at most.

    python experiments/tgv3d/step_cost.py --profile paper --n 20 32 [--steps 40]
"""

from sph import simulate
from lab import cli

try:
    from . import run as R, settings as S
except ImportError:  # run as a script: its folder comes first on the import path
    import run as R
    import settings as S


def measure(exp: "S.Experiment", method: "S.Method", n: int, steps: int) -> dict:
    solver = R.build(exp, method, n, None)
    state, nbrs = solver.init_fn()
    res = simulate.run(solver, state, nbrs, t_end=steps * solver.dt, write_every=steps, n_steps=steps,
                       progress=False, u_limit=exp.numerics.c_ref_factor * exp.material.u_ref)
    n_full = solver.n_steps(exp.t_end)
    return {"method": method.name, "n_side": n, "n_particles": solver.scene.n, "slots": int(nbrs.idx.shape[1]),
            "steps": steps, "ms_per_step": res.ms_per_step, "compile_s": res.compile_s, "steps_to_t_end": n_full,
            "full_run_h": n_full * res.ms_per_step / 3.6e6}


def options(ap):
    ap.add_argument("--n", nargs="*", type=int, default=None, help="resolutions of the profile (default: all)")
    ap.add_argument("--only", nargs="*", default=None, help="method names (default: all)")
    ap.add_argument("--steps", type=int, default=40, help="steps timed per run (after compilation)")


def main(args):
    exp = S.load(args.profile)
    ns = cli.select("--n", args.n, list(exp.n_side)) or list(exp.n_side)
    methods = cli.select("--only", args.only, [m.name for m in exp.methods])
    print(f"{'method':>8} {'n':>4} {'particles':>9} {'slots':>5} {'ms/step':>8} {'compile s':>9} "
          f"{'steps to t_end':>14} {'full run h':>10}  ({exp.numerics.dtype}, {exp.numerics.neighbor_search})")
    for n in ns:
        for m in exp.methods:
            if methods is None or m.name in methods:
                r = measure(exp, m, n, args.steps)
                print(f"{r['method']:>8} {n:>4} {r['n_particles']:>9} {r['slots']:>5} {r['ms_per_step']:>8.1f} "
                      f"{r['compile_s']:>9.1f} {r['steps_to_t_end']:>14} {r['full_run_h']:>10.2f}", flush=True)


if __name__ == "__main__":
    from lab.cli import profile_main

    profile_main(main, __doc__, options)
