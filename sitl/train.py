"""Train GNS or SitL on the generated RPF 2D dataset with LagrangeBench's Trainer (paper App. B:
10 message-passing layers, latent 64, 2 MLP layers, one input velocity, no pushforward, the best
checkpoint by the 20-step validation MSE). Pushforward (train.pushforward_*, beyond the paper) is
passed to LagrangeBench's Trainer as its own schedule.

Checkpoints go to results/<profile>/sitl/ckp/<model>/ (LagrangeBench's layout: the latest
checkpoint there, the best in best/), with the learning curve (curve.jsonl, sitl/curve.py). A killed run continues from its latest checkpoint (written
every train.eval_steps); train.json records the fingerprint (config + code + dataset) and marks a
finished run, so a finished training of the same inputs is not repeated. "solver" has no weights
and is never trained.

    .venv-lb/bin/python sitl/train.py --profile smoke --model sitl
"""
import json
import time

from sitl import common as C  # first: it sets up LagrangeBench

import jax
from lagrangebench import Trainer

from sitl import curve
from sitl import generate
from sitl import integrity
from sitl import model as M
from sitl import settings as S
from lab import runs
from lab.atomic import write_text
from lab.cli import profile_main
from lab.deliver import note_input
from lab.lock import folder_lock


CURVE = "curve.jsonl"
"""The learning curve beside a checkpoint (sitl/curve.py)."""


def trainer_configs(exp: S.Experiment, run_name: str, kind: str):
    t = exp.train
    cfg_train = {
        "batch_size": 1, "step_max": t.step_max, "num_workers": t.num_workers, "noise_std": t.noise(kind),
        "optimizer": {"lr_start": t.lr_start, "lr_final": t.lr_final, "lr_decay_rate": t.lr_decay_rate,
                      "lr_decay_steps": t.lr_decay_steps},
        "pushforward": {"steps": list(t.pushforward_steps), "unrolls": list(t.pushforward_unrolls),
                        "probs": list(t.pushforward_probs)},
        "loss_weight": {"acc": 1.0, "vel": 0.0, "pos": 0.0},
    }
    cfg_eval = {
        "n_rollout_steps": exp.eval.n_rollout_steps, "test": False, "rollout_dir": None,
        # LagrangeBench 0.2.0 sizes the *training* loader with eval.train.batch_size
        "train": {"n_trajs": t.eval_n_trajs, "metrics_stride": 10, "batch_size": 1, "metrics": ["mse"],
                  "out_type": "none"},
        "infer": {"batch_size": 1},
    }
    # "wandb" on: sitl/curve.py stands in for it and keeps the learning curve in a file
    cfg_logging = {"log_steps": t.log_steps, "eval_steps": t.eval_steps, "wandb": True, "run_name": run_name}
    return cfg_train, cfg_eval, cfg_logging


def train(exp: S.Experiment, results, kind: str) -> dict:
    """Train (or resume, or skip) model `kind`; one training of a model at a time: a second process
    asking for it waits for the lock (beside its checkpoint folder, which may be set aside), then
    finds it complete."""
    if kind == "solver":
        return {"model": kind, "trained": False}
    parent = S.ckpt_dir(results, kind).parent
    with folder_lock(parent, name=f".{kind}.train.lock"):
        return _train(exp, results, kind)


def _train(exp: S.Experiment, results, kind: str) -> dict:
    path = generate.ready(exp, results)
    ckp = S.ckpt_dir(results, kind)
    side = ckp / "train.json"
    fp = S.train_fingerprint(exp, kind, (path / "metadata.json").read_text())
    record = read_record(side)
    if record is None:  # the record itself is damaged: what it describes cannot be trusted
        integrity.set_aside_damaged(side, "not readable as JSON", then=f"training {kind} again", whole=ckp)
        record = fresh_record(fp, kind)
    elif record.get("fingerprint") != fp:
        if ckp.exists():
            runs.set_aside(ckp, f"train {kind}: trained on other inputs", then="training afresh")
        record = fresh_record(fp, kind)
    else:
        bad = damaged_checkpoint(ckp, record)
        if bad is not None:
            integrity.set_aside_damaged(*bad, then=f"training {kind} again", whole=ckp)
            record = fresh_record(fp, kind)
        elif record.get("complete"):
            note_input(*(ckp / n for n in record.get("files", {})))
            print(f"train {kind}: up to date ({ckp})", flush=True)
            return record
    ckp.mkdir(parents=True, exist_ok=True)
    write_text(side, json.dumps(record, indent=2) + "\n")

    data_train, data_valid, _ = C.datasets(exp, path)
    case = C.case(exp, data_train, kind)
    model = C.model(exp, kind, data_train, case)
    cfg_train, cfg_eval, cfg_logging = trainer_configs(exp, f"{kind}_{data_train.name}", kind)
    trainer = Trainer(model, case, data_train, data_valid, cfg_train=cfg_train, cfg_eval=cfg_eval,
                      cfg_logging=cfg_logging, input_seq_length=exp.model.input_seq_length, seed=exp.train.seed)
    resume = (ckp / "params_tree.pkl").exists()
    step0 = json.loads((ckp / "metadata_ckp.json").read_text())["step"] if resume else 0
    seeds = sorted({data_valid.seed_of(i) for i in range(exp.train.eval_n_trajs)})
    print(f"train {kind}: {'resuming at step ' + str(step0) if resume else 'from scratch'}, "
          f"step_max {exp.train.step_max}, noise {exp.train.noise(kind):g}, lr {exp.train.lr_start:g}, "
          f"{len(data_train)} training samples, best checkpoint on {exp.train.eval_n_trajs} validation windows "
          f"of seeds {seeds}", flush=True)
    t0 = time.perf_counter()
    with curve.recording(ckp / CURVE, step0):
        params, state, _ = trainer.train(step_max=exp.train.step_max, store_ckp=str(ckp),
                                         load_ckp=str(ckp) if resume else None)
    jax.block_until_ready(params)
    wall = time.perf_counter() - t0
    n_over = M.overflowed(state)
    if n_over:
        raise RuntimeError(f"train {kind}: SitL's in-model neighbour lists overflowed in {n_over} forward passes "
                           "(their outputs were NaN); raise model.capacity_multiplier")
    best = json.loads((ckp / "best" / "metadata_ckp.json").read_text())
    record["segments"].append({"from_step": step0, "to_step": exp.train.step_max, "wall_s": wall})
    record.update(wall_s=record["wall_s"] + wall, complete=True, step_max=exp.train.step_max,
                  best_step=best["step"], best_val_mse20=best["loss"], noise_std=exp.train.noise(kind),
                  lr_start=exp.train.lr_start, seed=exp.train.seed, valid_windows=exp.train.eval_n_trajs,
                  pushforward={"steps": list(exp.train.pushforward_steps),
                               "unrolls": list(exp.train.pushforward_unrolls),
                               "probs": list(exp.train.pushforward_probs)},
                  valid_seeds=seeds, train_samples=len(data_train),
                  s_per_step=wall / max(1, exp.train.step_max - step0),
                  curve=CURVE, files=integrity.digests(ckp, checkpoint_files()))
    note_input(*(ckp / n for n in record.get("files", {})))
    write_text(side, json.dumps(record, indent=2) + "\n")
    print(f"train {kind}: done in {wall:.0f} s ({record['s_per_step']:.3f} s/step); best val MSE_20 "
          f"{best['loss']:.3g} at step {best['step']}", flush=True)
    return record


def read_record(side):
    """train.json; {} when there is none, None when it cannot be read (damaged)."""
    if not side.exists():
        return {}
    try:
        record = json.loads(side.read_text())
    except (OSError, ValueError):
        return None
    return record if isinstance(record, dict) else None


def fresh_record(fp: str, kind: str) -> dict:
    return {"fingerprint": fp, "model": kind, "wall_s": 0.0, "segments": []}


def checkpoint_files() -> list:
    """The files of a finished training whose digests train.json keeps: the latest and the best checkpoint."""
    return [*integrity.CHECKPOINT_FILES, *(f"best/{n}" for n in integrity.CHECKPOINT_FILES)]


def damaged_checkpoint(ckp, record: dict):
    """(file, why) when the checkpoint this training would use is damaged: a finished one that differs
    from the digests train.json recorded or cannot be read, or the latest one a killed run resumes
    from that cannot be read; else None."""
    if record.get("complete"):
        return integrity.damaged(ckp, record.get("files")) or integrity.unreadable_checkpoint(ckp / "best")
    if (ckp / "params_tree.pkl").exists():
        return integrity.unreadable_checkpoint(ckp)
    return None


def options(ap):
    ap.add_argument("--model", required=True, choices=S.MODELS)


def main(args):
    train(S.load(args.profile), args.results, args.model)


if __name__ == "__main__":
    profile_main(main, __doc__, options)
