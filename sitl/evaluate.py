"""Test-set evaluation of one model with LagrangeBench's `infer` and metrics (Table 1): 20-step
rollouts from every (or `eval.n_trajs`) 22-frame window of test.h5; MSE_5 (`mse5`), MSE_20 (the
mean position MSE over the 20 steps, LagrangeBench's `loss`), MSE of the kinetic energy (`e_kin`)
and the Sinkhorn divergence (`sinkhorn`), averaged over rollouts; each with its per-window values
and a 95 % bootstrap interval over the windows (`ci_<metric>`, sitl/stats.py). The windows are
taken round-robin over the seeds (sitl/common.py), all of them by default (eval.n_trajs = -1). GNS
and SitL use their best checkpoint (by validation MSE_20); "solver" is SitL with the correction off
and no weights.

Also measures the inference cost: seconds per coarse step of the jitted model (median of repeats
after compilation), for the accuracy-cost comparison.

Writes results/<profile>/sitl/metrics/<model>.json and the rollouts (pkl) under
results/<profile>/sitl/rollouts/<model>/.

    .venv-lb/bin/python sitl/evaluate.py --profile smoke --model solver
"""
import json
import shutil
import time
from pathlib import Path

from sitl import common as C  # first: it sets up LagrangeBench

import jax
import jax.numpy as jnp
import numpy as np
from lagrangebench import infer
from lagrangebench.evaluate import averaged_metrics
from lagrangebench.utils import load_haiku

from sitl import generate
from sitl import integrity
from sitl import settings as S
from sitl import stats
from lab.cli import profile_main
from lab.atomic import write_text
from lab.io import OutputError
from lab.deliver import note_input
from lab.configtools import to_mapping
from lab.keys import digest, files_digest

HERE = Path(__file__).resolve().parent

KEYS = {"mse5": "val/mse5", "mse20": "val/loss", "e_kin": "val/e_kin", "sinkhorn": "val/sinkhorn"}
CODE = [HERE / f for f in ("evaluate.py", "model.py", "common.py", "stats.py")]


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


def per_window(metrics: dict) -> dict:
    """{metric: [value per test window]} in window order: each LagrangeBench's per-rollout mean (what
    its `averaged_metrics` averages), e.g. MSE_20 of a window = the mean of its 20 step MSEs; MSE_1 is
    the first step's alone (what one corrected step does, before errors compound)."""
    order = sorted(metrics, key=lambda k: int(k.rsplit("_", 1)[-1]))
    get = {"mse1": lambda m: np.asarray(m["mse"])[:1], "mse5": lambda m: m["mse5"], "mse20": lambda m: m["mse"],
           "e_kin": lambda m: m["e_kin"]["mse"], "sinkhorn": lambda m: m["sinkhorn"]}
    return {k: [float(np.mean(np.asarray(f(metrics[r])))) for r in order] for k, f in get.items()
            if all(k != "sinkhorn" or "sinkhorn" in metrics[r] for r in order)}


def summary(windows: dict, n_boot: int, seeds: list) -> dict:
    """Means, their bootstrap intervals (over windows) and the per-window values."""
    out = {"n_rollouts": len(next(iter(windows.values()))), "window_seeds": seeds, "per_window": windows}
    for k, v in windows.items():
        out[k] = float(np.mean(v))
        out[f"std_{k}"] = float(np.std(v))
        out[f"ci_{k}"] = list(stats.bootstrap_ci(v, n_boot))
    out["finite"] = bool(all(np.isfinite(out[k]) for k in windows))
    return out


def inputs_key(exp: S.Experiment, results, kind: str) -> str:
    """What a metrics file depends on: the dataset, the model / eval / dtype settings, its training
    record (the checkpoint it evaluates), the code. An evaluation of the same inputs is not repeated."""
    path = S.data_dir(results)
    train_json = S.ckpt_dir(results, kind) / "train.json"
    return digest({"data": [data_identity(path), (path / "metadata.json").read_text()],
                   "model": to_mapping(exp.model), "eval": to_mapping(exp.eval), "dtype": exp.train.dtype,
                   "noise": exp.train.noise(kind), "kind": kind, "code": files_digest(CODE),
                   "train": train_json.read_text() if kind != "solver" else None})


def data_identity(path: Path) -> str:
    """What identifies the dataset's content: its generation fingerprint and configuration and the
    digest of each file (generate.json), not its timings, so that a dataset generated again to the
    same files (a damaged split repaired) keeps the evaluations; the whole record when it has no
    file digests."""
    gen = json.loads((path / "generate.json").read_text())
    if not gen.get("files"):
        return (path / "generate.json").read_text()
    return digest({k: gen.get(k) for k in ("fingerprint", "config", "files")})


def current(exp: S.Experiment, results, kind: str):
    """The stored metrics of `kind` if they were made from the current inputs, else None."""
    dest = S.metrics_path(results, kind)
    if kind != "solver" and not (S.ckpt_dir(results, kind) / "train.json").exists():
        return None
    if not dest.exists():
        return None
    try:
        out = json.loads(dest.read_text())
    except (OSError, ValueError) as e:
        integrity.set_aside_damaged(dest, f"not readable as JSON: {' '.join(str(e).split())[:80]}",
                                    then=f"evaluating {kind} again")
        return None
    return out if out.get("inputs") == inputs_key(exp, results, kind) else None


def rollouts_intact(results, kind: str, done: dict) -> bool:
    """The stored rollouts (Fig. 3's input) exist and equal what `evaluate` wrote; a damaged one is
    named (and the whole evaluation redone, which rewrites them)."""
    rdir = S.rollout_dir(results, kind)
    if not rdir.exists():
        return False
    bad = integrity.damaged(rdir, done.get("rollout_files"))
    if bad is not None:
        print(f"evaluate {kind}: {bad[0]} {bad[1]}; evaluating again", flush=True)
        return False
    return True


def weights(results, kind: str, model, case, sample):
    """(params, state, checkpoint folder or None) of `kind`: its best checkpoint (GNS, SitL), or the
    solver's (no weights) initialised at `sample`."""
    if kind == "solver":
        features, _ = case.allocate_eval(sample)
        params, state = model.init(jax.random.PRNGKey(0), (features, sample[1]))
        return params, state, None
    ckp = S.ckpt_dir(results, kind) / "best"
    if not (ckp / "params_tree.pkl").exists():
        raise FileNotFoundError(f"{ckp}: no trained {kind}; run sitl/train.py --model {kind} first")
    bad = integrity.unreadable_checkpoint(ckp)
    if bad is not None:
        raise OutputError(f"{bad[0]}: {bad[1]}; `make table1` (sitl/train.py --model {kind}) sets the "
                          "checkpoint aside and trains again")
    params, state, _, _ = load_haiku(str(ckp))
    return params, state, ckp


def evaluate(exp: S.Experiment, results, kind: str, rollouts: bool = True, force: bool = False,
             sinkhorn: bool = True, timing: bool = True) -> dict:
    """Evaluate `kind` on the test windows (module docstring). rollouts: keep them (pkl, for Fig. 3);
    sinkhorn / timing: also the Sinkhorn divergence (slow to compile) and the time per coarse step
    (the study leaves both out; Table 1 and make sitl-cost have them)."""
    path = generate.ready(exp, results)
    if not force:
        done = current(exp, results, kind)
        if done is not None and (not rollouts or rollouts_intact(results, kind, done)) \
                and (not sinkhorn or "sinkhorn" in done) and (not timing or done.get("s_per_coarse_step")):
            note_input(*(S.rollout_dir(results, kind) / n for n in done.get("rollout_files", {})))
            print(f"evaluate {kind}: up to date ({S.metrics_path(results, kind)})", flush=True)
            return done
    data_train, _, data_test = C.datasets(exp, path)
    case = C.case(exp, data_train, kind)
    model = C.model(exp, kind, data_train, case)
    pos, ptype = data_test[0]
    sample = (jnp.asarray(pos[:, :exp.model.input_seq_length]), jnp.asarray(ptype))
    params, state, ckp = weights(results, kind, model, case, sample)
    rdir = S.rollout_dir(results, kind)
    if rdir.exists():
        shutil.rmtree(rdir)
    ev = exp.eval
    n_trajs = C.n_windows(exp, data_test)
    t0 = time.perf_counter()
    metrics = infer(model, case, data_test, params=params, state=state,
                    cfg_eval_infer={"n_trajs": n_trajs, "metrics_stride": ev.metrics_stride, "batch_size": ev.batch_size,
                                    "metrics": ["mse", "e_kin"] + (["sinkhorn"] if sinkhorn else []),
                                    "out_type": "pkl" if rollouts else "none",
                                    "n_extrap_steps": 0},
                    rollout_dir=str(rdir) if rollouts else None, n_rollout_steps=ev.n_rollout_steps, seed=exp.train.seed)
    wall = time.perf_counter() - t0
    avg = averaged_metrics(metrics)
    windows = per_window(metrics)
    for k, v in KEYS.items():  # our per-window values average to LagrangeBench's own numbers
        if k in windows and np.isfinite(avg[v]) and not np.isclose(np.mean(windows[k]), avg[v], rtol=1e-5, atol=0):
            raise RuntimeError(f"evaluate {kind}: per-window {k} averages to {np.mean(windows[k])}, "
                               f"LagrangeBench's {v} is {avg[v]}")
    seeds = [data_test.seed_of(i) for i in range(n_trajs)]
    out = {"model": kind, "checkpoint": str(ckp) if ckp else None, "n_rollout_steps": ev.n_rollout_steps,
           "noise_std": exp.train.noise(kind), "substeps": exp.model.substeps, "infer_wall_s": wall,
           "s_per_coarse_step": time_per_step(model, params, state, case, sample) if timing else None,
           "n_params": int(sum(np.size(x) for x in jax.tree_util.tree_leaves(params))),
           **summary(windows, ev.bootstrap, seeds)}
    train_json = S.ckpt_dir(results, kind) / "train.json"
    if train_json.exists() and kind != "solver":
        tr = json.loads(train_json.read_text())
        out.update(train_steps=tr.get("step_max"), train_wall_s=tr.get("wall_s"), best_step=tr.get("best_step"),
                   train_s_per_step=tr.get("s_per_step"))
    if rollouts:
        out["rollout_files"] = integrity.digests(rdir, sorted(p.name for p in rdir.glob("*.pkl")))
        note_input(*(rdir / n for n in out["rollout_files"]))
    out["inputs"] = inputs_key(exp, results, kind)
    dest = S.metrics_path(results, kind)
    write_text(dest, json.dumps(out, indent=2) + "\n")
    ci = out["ci_mse20"]
    print(f"evaluate {kind}: MSE_5 {out['mse5']:.3g}, MSE_20 {out['mse20']:.3g} [{ci[0]:.3g}, {ci[1]:.3g}], "
          f"MSE_Ekin {out['e_kin']:.3g}" + (f", Sinkhorn {out['sinkhorn']:.3g}" if sinkhorn else "") +
          f" over {out['n_rollouts']} test windows (seeds {sorted(set(seeds))})" +
          (f"; {1e3 * out['s_per_coarse_step']:.1f} ms per coarse step" if timing else ""), flush=True)
    return out


def options(ap):
    ap.add_argument("--model", required=True, choices=S.MODELS)
    ap.add_argument("--force", action="store_true", help="evaluate again even if the inputs are unchanged")


def main(args):
    evaluate(S.load(args.profile), args.results, args.model, force=args.force)


if __name__ == "__main__":
    profile_main(main, __doc__, options)
