"""How far round-off moves a protocol run's metrics: one run of an experiment folder at a profile,
its fluid positions moved by `amp` (normal, seed 1) before the first step, then the run's metrics.
`amp` 0 still rebuilds the start op by op (a round-off distance from the make run's jitted start).
Writes into its own results folder, never results/.

    .venv/bin/python scripts/roundoff_spread.py experiments/ldc2d paper sph_dx0.02 1e-12 /tmp/ldcpert

(Fig. 6, sph, 2026-12-07: u_rms 0.01136 / 0.01169 / 0.01178 / 0.01238 / 0.01246 and v_rms
0.00954 / 0.01006 / 0.01007 / 0.01178 / 0.01241 for the make run, amp 0, 1e-12, 1e-11 and 1e-10:
up to about 30 % after 44000 steps.)
"""
import json
import sys

import jax.numpy as jnp
import numpy as np

import sph
from sph import xla_cpu
from lab.experiment import Experiment


def main(folder: str, profile: str, name: str, amp: float, results: str) -> dict:
    exp = Experiment(folder, profile, f"{results}/amp{amp:g}")
    run = exp.run(name)

    def start(run, solver):
        state, _ = solver.init_fn()
        fluid = np.asarray(solver.scene.tag) == sph.FLUID
        dr = np.random.default_rng(1).standard_normal(np.shape(state.r)) * amp * fluid[:, None]
        r = jnp.asarray(np.asarray(state.r) + dr, state.r.dtype)
        nbrs = solver.neighbors.allocate(r)
        return solver.state_at(r, state.u, nbrs), nbrs

    exp.study.initial_state = start
    exp.run_one(run, progress=False)
    return exp.metrics(run)


if __name__ == "__main__":
    xla_cpu.set_cpu_defaults()
    folder, profile, name, amp, results = sys.argv[1:6]
    m = main(folder, profile, name, float(amp), results)
    print(json.dumps({k: v for k, v in m.items() if isinstance(v, (int, float))}))
