"""Fig. 3's rollouts over the paper's horizon: every model of the profile (solver alone, GNS, SitL,
each as Table 1 evaluates it: the best checkpoint) rolled out `fig3.steps` coarse steps (paper: 500,
i.e. 10 000 SPH steps at W = 20) from every test window that long (input_seq_length + fig3.steps
frames; one per seed at cpu), with LagrangeBench's `infer`, and the position MSE at every step.

Writes results/<profile>/fig3/rollouts/<model>/rollout_<i>.pkl and record.json: {"mse_steps": per
window, the MSE at steps 1..fig3.steps (LagrangeBench's per-step `mse`), "inputs": the key of what it
read (settings, dataset, the checkpoint's digests)}; a record with the same key is not made again.

    .venv-lb/bin/python sitl/fig3_rollouts.py --profile smoke
"""
import json
import shutil
import time
from pathlib import Path

from sitl import common as C  # first: it sets up LagrangeBench

import jax.numpy as jnp
import numpy as np
from lagrangebench import infer

from sitl import generate
from sitl import settings as S
from sitl.evaluate import weights
from lab.atomic import write_text
from lab.cli import profile_main
from lab.keys import digest, files_digest
from lab.configtools import to_mapping
from lab.deliver import note_input


def out_dir(results) -> Path:
    return Path(results) / "fig3" / "rollouts"


def inputs_key(exp: S.Experiment, results, kind: str) -> str:
    """What a model's long rollouts depend on: the settings, the dataset's metadata and the trained
    checkpoint's recorded digests (train.json)."""
    train = S.ckpt_dir(results, kind) / "train.json"
    files = json.loads(train.read_text()).get("files") if kind != "solver" and train.exists() else None
    return digest({"fig3": to_mapping(exp.fig3), "model": to_mapping(exp.model), "dtype": exp.train.dtype,
                   "noise": exp.train.noise(kind), "metadata": (S.data_dir(results) / "metadata.json").read_text(),
                   "checkpoint": files, "code": files_digest([Path(__file__), Path(S.__file__).with_name("model.py")])})


def current(exp: S.Experiment, results, kind: str):
    """The record of `kind`'s long rollouts when it matches the inputs and its files exist, else None."""
    rec = out_dir(results) / kind / "record.json"
    if not rec.exists():
        return None
    try:
        done = json.loads(rec.read_text())
    except ValueError:
        return None
    files = [out_dir(results) / kind / n for n in done.get("rollout_files", [])]
    if done.get("inputs") != inputs_key(exp, results, kind) or not all(p.exists() for p in files):
        return None
    return done


def make(exp: S.Experiment, results, kind: str) -> dict:
    done = current(exp, results, kind)
    if done is not None:
        print(f"fig3 rollouts {kind}: up to date", flush=True)
        note_input(out_dir(results) / kind / "record.json")
        return done
    path = generate.ready(exp, results)
    data_train, _, _ = C.datasets(exp, path)
    data_test = C.Interleaved("test", extra_seq_length=exp.fig3.steps, dataset_path=str(path), name="rpf2d",
                              input_seq_length=exp.model.input_seq_length)  # windows of the long rollouts
    case = C.case(exp, data_train, kind)
    model = C.model(exp, kind, data_train, case)
    pos, ptype = data_test[0]
    sample = (jnp.asarray(pos[:, :exp.model.input_seq_length]), jnp.asarray(ptype))
    params, state, _ = weights(results, kind, model, case, sample)
    rdir = out_dir(results) / kind
    if rdir.exists():
        shutil.rmtree(rdir)
    rdir.mkdir(parents=True)
    n = data_test.num_samples
    t0 = time.perf_counter()
    metrics = infer(model, case, data_test, params=params, state=state,
                    cfg_eval_infer={"n_trajs": n, "metrics_stride": 1, "batch_size": 1, "metrics": ["mse"],
                                    "out_type": "pkl", "n_extrap_steps": 0},
                    rollout_dir=str(rdir), n_rollout_steps=exp.fig3.steps, seed=exp.train.seed)
    wall = time.perf_counter() - t0
    mse = [np.asarray(metrics[f"rollout_{i}"]["mse"], np.float64).tolist() for i in range(n)]
    out = {"model": kind, "steps": exp.fig3.steps, "n_windows": n,
           "window_seeds": [data_test.seed_of(i) for i in range(n)], "mse_steps": mse, "wall_s": wall,
           "rollout_files": sorted(p.name for p in rdir.glob("*.pkl")), "inputs": inputs_key(exp, results, kind)}
    write_text(rdir / "record.json", json.dumps(out, indent=1) + "\n")
    note_input(rdir / "record.json")
    last = [m[-1] for m in mse]
    print(f"fig3 rollouts {kind}: {n} windows x {exp.fig3.steps} steps in {wall:.0f} s; MSE at the last step "
          f"{', '.join(f'{x:.3g}' for x in last)}", flush=True)
    return out


def main(args):
    exp = S.load(args.profile)
    for kind in exp.models:
        make(exp, args.results, kind)


if __name__ == "__main__":
    profile_main(main, __doc__)
