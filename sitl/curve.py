"""Learning curves: every training's loss every train.log_steps and each checkpoint's validation
MSE_5 / MSE_20, kept beside its checkpoint (ckp/<model>/curve.jsonl, one JSON object per line).

LagrangeBench's Trainer reports both only to Weights & Biases (or prints them). `recording(path)`
stands in for the `wandb` module its trainer calls, so the same numbers are appended to the file
instead, with no network and no other change to the training: {"step", "loss"} at each log step and
{"step", "val_mse5", "val_mse20"} at each validation. The validation's MSE_20 is LagrangeBench's
"val/loss" (the mean per-step MSE over the n_rollout_steps = 20 steps, the best-checkpoint criterion);
MSE_5 is the mean over its first 5 steps of the same rollouts. A run resumed from step s first drops
the lines past s (written by the killed segment after its last checkpoint).
"""
import contextlib
import json
from pathlib import Path

import numpy as np

from lab.atomic import write_text


class _Run:
    def __init__(self, path: Path):
        self.path = path

    def log(self, metrics: dict, step: int):
        row = {"step": int(step)}
        if "train/loss" in metrics:
            row["loss"] = float(metrics["train/loss"])
        if "val/loss" in metrics:
            row["val_mse20"] = float(metrics["val/loss"])
        if "val/mse5" in metrics:
            row["val_mse5"] = float(metrics["val/mse5"])
        with self.path.open("a") as f:
            f.write(json.dumps(row) + "\n")

    def finish(self):
        pass


class _Stand_in:
    """What LagrangeBench's trainer uses of the `wandb` module: `init(...)` returning a run."""

    def __init__(self, path: Path):
        self.path = path

    def init(self, **_):
        return _Run(self.path)


def with_mse5(averaged):
    """LagrangeBench's `averaged_metrics` plus "val/mse5": the mean over rollouts of each rollout's
    mean MSE over its first 5 steps."""
    def fn(eval_metrics):
        out = averaged(eval_metrics)
        per = [float(np.mean(np.asarray(m["mse"])[:5])) for m in eval_metrics.values() if "mse" in m]
        if per:
            out["val/mse5"] = float(np.mean(per))
        return out
    return fn


def _rows(path: Path):
    """The file's rows, each with its line; a line a killed process left half-written is skipped."""
    for line in Path(path).read_text().splitlines():
        try:
            row = json.loads(line)
        except ValueError:
            continue
        if isinstance(row, dict) and "step" in row:
            yield line, row


def truncate(path: Path, step: int):
    """Drop the lines past `step` (a resumed run continues from its checkpoint at `step`), and any
    half-written line; the file is replaced atomically, so a kill here loses nothing."""
    if not path.exists():
        return
    write_text(path, "".join(line + "\n" for line, row in _rows(path) if row["step"] <= step))


def read(path: Path) -> dict:
    """{"loss": [(step, loss)], "val": [(step, mse5, mse20)]} of a curve file ({} lists when none)."""
    out = {"loss": [], "val": []}
    if not Path(path).exists():
        return out
    for _, row in _rows(path):
        if "loss" in row:
            out["loss"].append((row["step"], row["loss"]))
        if "val_mse20" in row:
            out["val"].append((row["step"], row.get("val_mse5"), row["val_mse20"]))
    return out


@contextlib.contextmanager
def recording(path: Path, step0: int):
    """Within: LagrangeBench's trainer appends its loss and validations to `path` (cfg_logging.wandb
    must be True); the lines past `step0` are dropped first."""
    from lagrangebench.train import trainer as T

    path = Path(path)
    truncate(path, step0)
    saved = T.wandb, T.averaged_metrics
    T.wandb, T.averaged_metrics = _Stand_in(path), with_mse5(saved[1])
    try:
        yield path
    finally:
        T.wandb, T.averaged_metrics = saved
