"""What one training of GNS and of SitL costs, measured side by side in one process: the study's
equal-cost budget (sitl/study.py) compares the two models under the same machine load.

A finished training's own wall time depends on what else the machine ran meanwhile (the cpu
profile's SitL took 2.5 s / step beside other jobs and 1.6 s / step beside one), so two trainings'
records are no fair measure of what one model costs against the other. Here the two parts of a
training are timed for each model, the models alternating so that a change of load hits both:

  step     one training step as LagrangeBench 0.2.0's Trainer.train makes it (the case's noisy
           preprocessing, then its `_update`: loss, gradient, AdamW), `steps` of them after one
           warm-up step (compilation), seconds per step
  window   one validation window as Trainer.train's validation makes it (`eval_rollout`:
           n_rollout_steps of the model), `windows` of them after a one-window warm-up, seconds
           per window

Each is timed `repeats` times and its median kept. A training of N steps with validation every
eval_steps on eval_n_trajs windows then costs N * step + (N // eval_steps) * eval_n_trajs * window.
Untrained weights are used: the cost of a step does not depend on their values.

    .venv-lb/bin/python sitl/train_cost.py --profile cpu
"""
import json
import statistics
import time
from functools import partial

from sitl import common as C  # first: it sets up LagrangeBench

import jax
import jax.numpy as jnp
from lagrangebench import Trainer
from lagrangebench.evaluate import eval_rollout
from lagrangebench.train.trainer import _mse, _update
from lagrangebench.utils import broadcast_from_batch, broadcast_to_batch

from sitl import generate
from sitl import settings as S
from sitl import train as T
from lab.cli import profile_main

STEPS, WINDOWS, REPEATS = 10, 2, 3  # per timing: enough to average a step's jitter, minutes in all on cpu


class Probe:
    """One model's timed parts on the profile's dataset (LagrangeBench's own loaders and case)."""

    def __init__(self, exp: S.Experiment, path, kind: str):
        data_train, data_valid, _ = C.datasets(exp, path)
        self.case = C.case(exp, data_train, kind)
        model = C.model(exp, kind, data_train, self.case)
        cfg_train, cfg_eval, cfg_logging = T.trainer_configs(exp, f"cost_{kind}", kind)
        self.trainer = Trainer(model, self.case, data_train, data_valid, cfg_train=cfg_train, cfg_eval=cfg_eval,
                               cfg_logging=cfg_logging, input_seq_length=exp.model.input_seq_length,
                               seed=exp.train.seed)
        self.kind, self.noise, self.n_rollout = kind, exp.train.noise(kind), exp.eval.n_rollout_steps
        self.model_apply = jax.jit(model.apply)
        loss_fn = partial(_mse, model_fn=self.model_apply, loss_weight=self.trainer.loss_weight)
        self.update = partial(_update, loss_fn=loss_fn, opt_update=self.trainer.opt_update)
        self.preprocess = jax.vmap(self.case.preprocess, in_axes=(0, 0, None, 0, None))
        batch = self._batch(next(iter(self.trainer.loader_train)))
        key, features, _, nbrs = self.case.allocate(self.trainer.base_key, (batch[0][0], batch[1][0]))
        key, sub = jax.random.split(key)
        self.params, self.state = model.init(sub, (features, batch[1][0]))
        self.opt_state = self.trainer.opt_init(self.params)
        self.keys = jax.random.split(key, self.trainer.loader_train.batch_size)
        self.nbrs = broadcast_to_batch(nbrs, self.trainer.loader_train.batch_size)

    @staticmethod
    def _batch(raw):
        return jax.tree_util.tree_map(jnp.asarray, raw)

    def steps(self, n: int) -> float:
        """Seconds for n training steps on the next n training samples."""
        loader = iter(self.trainer.loader_train)
        t0 = time.perf_counter()
        for _ in range(n):
            batch = self._batch(next(loader))
            self.keys, features, target, self.nbrs = self.preprocess(self.keys, batch, self.noise, self.nbrs, 0)
            if bool(self.nbrs.did_buffer_overflow.sum() > 0):
                raise RuntimeError(f"train_cost {self.kind}: the graph list overflowed; the probe does not "
                                   "re-allocate it (Trainer.train does): raise the neighbour multiplier")
            loss, self.params, self.state, self.opt_state = self.update(
                params=self.params, state=self.state, features_batch=features, target_batch=target,
                particle_type_batch=batch[1], opt_state=self.opt_state)
        jax.block_until_ready(loss)
        return time.perf_counter() - t0

    def windows(self, n: int) -> float:
        """Seconds for the validation rollouts of n windows."""
        t0 = time.perf_counter()
        eval_rollout(case=self.case, metrics_computer=self.trainer.metrics_computer, model_apply=self.model_apply,
                     params=self.params, state=self.state, neighbors=broadcast_from_batch(self.nbrs, 0),
                     loader_eval=self.trainer.loader_valid, n_rollout_steps=self.n_rollout, n_trajs=n,
                     rollout_dir=None, out_type="none")
        return time.perf_counter() - t0


def measure(exp: S.Experiment, results, kinds=("sitl", "gns"), steps: int = STEPS, windows: int = WINDOWS,
            repeats: int = REPEATS) -> dict:
    """{kind: {"s_per_step", "s_per_window", "step_samples", "window_samples"}} plus the settings,
    the models alternating within each repeat."""
    steps, windows = max(1, min(steps, exp.train.step_max)), max(1, min(windows, exp.train.eval_n_trajs))
    path = generate.ready(exp, results)
    probes = {k: Probe(exp, path, k) for k in kinds}
    for p in probes.values():  # compilation
        p.steps(1)
        p.windows(1)
    times = {k: {"step": [], "window": []} for k in kinds}
    for r in range(repeats):
        for k, p in probes.items():
            times[k]["step"].append(p.steps(steps) / steps)
            times[k]["window"].append(p.windows(windows) / windows)
        print(f"train_cost: repeat {r + 1}/{repeats}: " + ", ".join(
            f"{k} {t['step'][-1]:.3g} s/step, {t['window'][-1]:.3g} s/window" for k, t in times.items()), flush=True)
    out = {k: {"s_per_step": statistics.median(t["step"]), "s_per_window": statistics.median(t["window"]),
               "step_samples": t["step"], "window_samples": t["window"]} for k, t in times.items()}
    out["settings"] = {"steps": steps, "windows": windows, "repeats": repeats}
    return out


def training_s(cost: dict, step_max: int, eval_steps: int, eval_n_trajs: int) -> float:
    """Predicted seconds of a training of step_max steps validating every eval_steps on eval_n_trajs
    windows (LagrangeBench validates at every positive multiple of eval_steps up to step_max)."""
    return step_max * cost["s_per_step"] + (step_max // eval_steps) * eval_n_trajs * cost["s_per_window"]


def options(ap):
    ap.add_argument("--repeats", type=int, default=REPEATS)


def main(args):
    exp = S.load(args.profile)
    out = measure(exp, args.results, repeats=args.repeats)
    t = exp.train
    for k in ("sitl", "gns"):
        out[k]["training_s"] = training_s(out[k], t.step_max, t.eval_steps, t.eval_n_trajs)
    print(json.dumps(out, indent=2))


if __name__ == "__main__":
    profile_main(main, __doc__, options)
