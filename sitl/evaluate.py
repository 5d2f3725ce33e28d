"""Test-set evaluation of one model with LagrangeBench's `infer` and metrics (Table 1): 20-step
rollouts from every (or `eval.n_trajs`) 22-frame window of test.h5; MSE_5 (`mse5`), MSE_20 (the
mean position MSE over the 20 steps, LagrangeBench's `loss`), MSE of the kinetic energy (`e_kin`)
and the Sinkhorn divergence (`sinkhorn`), averaged over rollouts. GNS and SitL use their best
checkpoint (by validation MSE_20); "solver" is SitL with the correction off and no weights.

Also measures the inference cost: seconds per coarse step of the jitted model (median of repeats
after compilation), for the accuracy-cost comparison.

Writes results/<profile>/sitl/metrics/<model>.json and the rollouts (pkl) under
results/<profile>/sitl/rollouts/<model>/.

    .venv-lb/bin/python sitl/evaluate.py --profile smoke --model solver
"""
import json
import shutil
import time

from sitl import common as C  # first: it sets up LagrangeBench

import jax
import jax.numpy as jnp
import numpy as np
from lagrangebench import infer
from lagrangebench.evaluate import averaged_metrics
from lagrangebench.utils import load_haiku

from sitl import generate
from sitl import settings as S
from sph.harness.cli import profile_main

KEYS = {"mse5": "val/mse5", "mse20": "val/loss", "e_kin": "val/e_kin", "sinkhorn": "val/sinkhorn"}


def time_per_step(model, params, state, case, sample, repeats: int = 10) -> float:
    """Median wall time of one jitted forward (features from case.preprocess_eval) after compiling."""
    features, _ = case.allocate_eval(sample)
    apply = jax.jit(model.apply)
    args = (params, state, (features, sample[1]))
    jax.block_until_ready(apply(*args))
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        jax.block_until_ready(apply(*args))
        times.append(time.perf_counter() - t0)
    return float(np.median(times))


def evaluate(exp: S.Experiment, results, kind: str) -> dict:
    path = generate.ready(exp, results)
    data_train, _, data_test = C.datasets(exp, path)
    case = C.case(exp, data_train)
    model = C.model(exp, kind, data_train, case)
    pos, ptype = data_test[0]
    sample = (jnp.asarray(pos[:, :exp.model.input_seq_length]), jnp.asarray(ptype))
    if kind == "solver":
        features, _ = case.allocate_eval(sample)
        params, state = model.init(jax.random.PRNGKey(0), (features, sample[1]))
        ckp = None
    else:
        ckp = S.ckpt_dir(results, kind) / "best"
        if not (ckp / "params_tree.pkl").exists():
            raise FileNotFoundError(f"{ckp}: no trained {kind}; run sitl/train.py --model {kind} first")
        params, state, _, _ = load_haiku(str(ckp))
    rdir = S.rollout_dir(results, kind)
    if rdir.exists():
        shutil.rmtree(rdir)
    ev = exp.eval
    n_trajs = data_test.num_samples if ev.n_trajs == -1 else min(ev.n_trajs, data_test.num_samples)
    t0 = time.perf_counter()
    metrics = infer(model, case, data_test, params=params, state=state,
                    cfg_eval_infer={"n_trajs": n_trajs, "metrics_stride": ev.metrics_stride, "batch_size": ev.batch_size,
                                    "metrics": ["mse", "e_kin", "sinkhorn"], "out_type": "pkl", "n_extrap_steps": 0},
                    rollout_dir=str(rdir), n_rollout_steps=ev.n_rollout_steps, seed=exp.train.seed)
    wall = time.perf_counter() - t0
    avg = averaged_metrics(metrics)
    out = {"model": kind, "checkpoint": str(ckp) if ckp else None, "n_rollouts": len(metrics),
           "n_rollout_steps": ev.n_rollout_steps, "infer_wall_s": wall,
           "s_per_coarse_step": time_per_step(model, params, state, case, sample),
           "n_params": int(sum(np.size(x) for x in jax.tree_util.tree_leaves(params))),
           "finite": bool(all(np.isfinite(avg[v]) for v in KEYS.values())),
           **{k: avg[v] for k, v in KEYS.items()}, **{f"std_{k}": avg[v.replace("val/", "val/std")]
                                                      for k, v in KEYS.items()}}
    train_json = S.ckpt_dir(results, kind) / "train.json"
    if train_json.exists():
        tr = json.loads(train_json.read_text())
        out.update(train_steps=tr.get("step_max"), train_wall_s=tr.get("wall_s"), best_step=tr.get("best_step"))
    dest = S.metrics_path(results, kind)
    dest.parent.mkdir(parents=True, exist_ok=True)
    dest.write_text(json.dumps(out, indent=2) + "\n")
    print(f"evaluate {kind}: MSE_5 {out['mse5']:.3g}, MSE_20 {out['mse20']:.3g}, MSE_Ekin {out['e_kin']:.3g}, "
          f"Sinkhorn {out['sinkhorn']:.3g} over {out['n_rollouts']} test rollouts; "
          f"{1e3 * out['s_per_coarse_step']:.1f} ms per coarse step", flush=True)
    return out


def options(ap):
    ap.add_argument("--model", required=True, choices=S.MODELS)


def main(args):
    evaluate(S.load(args.profile), args.results, args.model)


if __name__ == "__main__":
    profile_main(main, __doc__, options)
