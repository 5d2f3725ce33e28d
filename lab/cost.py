"""The cost of an experiment's runs without running them: ms per step of each run of a profile from a
short run of the driver the harness uses (sph.simulate.run: jitted chunks with the step guard,
compilation excluded), and the time a full run to its t_end would take.

A run whose study has a cached start (lab.protocol.Start, e.g. a relaxed lattice) is timed on its
scene's own lattice when the study's scene(run) accepts none (the cost per step depends on the
neighbour count, which a relaxed start changes by a few per cent at most), else on its start.
Number-neutral: it writes nothing.

    python -m lab.cost experiments/tgv3d --profile paper [--only sph_n20 tvf_n32] [--steps 40]
"""
import inspect

from sph import build_solver, simulate
from .cli import profile_main
from .configtools import require
from .experiment import Experiment


def measure(exp: Experiment, run, steps: int) -> dict:
    """ms per step of `run` over `steps` steps after compilation, and its full run's steps and hours."""
    params = list(inspect.signature(exp.study.scene).parameters.values())
    on_lattice = len(params) == 1 or params[1].default is not inspect.Parameter.empty
    solver = build_solver(*exp.study.scene(run)) if on_lattice else exp.solver(run)
    state, nbrs = solver.init_fn()
    spec = exp.spec(run)
    res = simulate.run(solver, state, nbrs, t_end=steps * solver.dt, write_every=steps, n_steps=steps,
                       progress=False, u_limit=spec.u_limit)
    n_full = solver.n_steps(spec.t_end)
    return {"run": run.name, "n_particles": solver.scene.n, "slots": int(nbrs.idx.shape[1]), "steps": steps,
            "ms_per_step": res.ms_per_step, "compile_s": res.compile_s, "steps_to_t_end": n_full,
            "full_run_h": n_full * res.ms_per_step / 3.6e6, "dtype": solver.numerics.dtype}


def main(argv=None):
    def options(ap):
        ap.add_argument("folder", help="the experiment folder (config.yaml, study.py)")
        ap.add_argument("--only", nargs="*", default=None, help="run names (default: all)")
        ap.add_argument("--steps", type=int, default=40, help="steps timed per run (after compilation)")

    def work(args):
        exp = Experiment(args.folder, args.profile, args.results)
        names = [r.name for r in exp.runs]
        bad = [n for n in (args.only or []) if n not in names]
        require(not bad, "--only", f"{bad[:1]} is not one of the profile's runs {names}")
        require(args.steps >= 1, "--steps", f"must be >= 1, got {args.steps}")
        print(f"{'run':>14} {'particles':>9} {'slots':>5} {'ms/step':>8} {'compile s':>9} {'steps to t_end':>14} "
              f"{'full run h':>10}")
        for run in exp.runs:
            if args.only is None or run.name in args.only:
                r = measure(exp, run, args.steps)
                print(f"{r['run']:>14} {r['n_particles']:>9} {r['slots']:>5} {r['ms_per_step']:>8.1f} "
                      f"{r['compile_s']:>9.1f} {r['steps_to_t_end']:>14} {r['full_run_h']:>10.2f}", flush=True)

    return profile_main(work, __doc__, options, argv)


if __name__ == "__main__":
    main()
