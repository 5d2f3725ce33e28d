"""Table 1's "solver only" with the authors' body-force bug, to explain the paper's number.

The authors' SitL solver evaluated LagrangeBench's per-particle RPF force_fn(r) (r of shape (dim,))
on the whole (N, 2) position array: `r[1]` is then particle 1's position vector, and the result is one
(2,) vector broadcast to every particle, so half of them got the wrong sign. Here that bug is taken
as g = (+g, 0) for every particle (the upper half, -g in the data, pushed the wrong way; which sign
the authors' code picked depended on one particle's position). This script evaluates
our "solver only" module (sitl/model.py, correction off) exactly as sitl/evaluate.py does, on the
same test windows with LagrangeBench's `infer`, once with the data's per-particle force and once with
that uniform force, so the two Table 1 columns can be put side by side. MSE_5, MSE_20 and MSE_Ekin
only: the question is the paper's 7.9e-6 / 0.13, and LagrangeBench's Sinkhorn metric at the
paper's 3200 particles spent over 20 min compiling one `cond` on this CPU without finishing.

Writes results/<profile>/sitl/metrics/solver_authors_force.json (never read by Table 1's rules).

    .venv-lb/bin/python sitl/authors_force.py --profile cpu
"""
import dataclasses
import json

from sitl import common as C  # first: it sets up LagrangeBench

import jax
import jax.numpy as jnp
import numpy as np
from lagrangebench import infer
from lagrangebench.evaluate import averaged_metrics

from sitl import generate
from sitl import settings as S
from sitl.evaluate import KEYS, per_window, summary
from lab.cli import profile_main
from lab.atomic import write_text


def uniform_force_model(exp: S.Experiment, data_train, case_fns):
    """The solver-only module whose body force is the authors' uniform (+g, 0) (model.solver_force)."""
    return C.model(uniform_force(exp), "solver", data_train, case_fns)


def uniform_force(exp: S.Experiment) -> S.Experiment:
    """The experiment with the authors' uniform force in the in-loop solver."""
    return dataclasses.replace(exp, model=dataclasses.replace(exp.model, solver_force="uniform"))


def evaluate(exp: S.Experiment, results, kind: str) -> dict:
    path = generate.ready(exp, results)
    data_train, _, data_test = C.datasets(exp, path)
    case = C.case(exp, data_train, "solver")
    model = uniform_force_model(exp, data_train, case) if kind == "uniform" else C.model(exp, "solver", data_train, case)
    pos, ptype = data_test[0]
    sample = (jnp.asarray(pos[:, :exp.model.input_seq_length]), jnp.asarray(ptype))
    features, _ = case.allocate_eval(sample)
    params, state = model.init(jax.random.PRNGKey(0), (features, sample[1]))
    ev = exp.eval
    n_trajs = C.n_windows(exp, data_test)
    metrics = infer(model, case, data_test, params=params, state=state,
                    cfg_eval_infer={"n_trajs": n_trajs, "metrics_stride": ev.metrics_stride, "batch_size": ev.batch_size,
                                    "metrics": ["mse", "e_kin"], "out_type": "none", "n_extrap_steps": 0},
                    n_rollout_steps=ev.n_rollout_steps, seed=exp.train.seed)
    avg = averaged_metrics(metrics)
    out = summary(per_window(metrics), ev.bootstrap, [data_test.seed_of(i) for i in range(n_trajs)])
    for k, v in KEYS.items():  # the per-window values average to LagrangeBench's own numbers
        if k not in out:
            continue
        assert not np.isfinite(avg[v]) or np.isclose(out[k], avg[v], rtol=1e-5), (k, out[k], avg[v])
    return out


def main(args):
    exp, results = S.load(args.profile), args.results
    out = {"per_particle": evaluate(exp, results, "per_particle"), "uniform": evaluate(exp, results, "uniform")}
    dest = S.metrics_path(results, "solver").with_name("solver_authors_force.json")
    write_text(dest, json.dumps(out, indent=2) + "\n")
    for k, v in out.items():
        print(f"solver only, {k} force: MSE_5 {v['mse5']:.3g}, MSE_20 {v['mse20']:.3g}, MSE_Ekin {v['e_kin']:.3g} "
              f"over {v['n_rollouts']} rollouts", flush=True)
    return out


if __name__ == "__main__":
    profile_main(main, __doc__)
