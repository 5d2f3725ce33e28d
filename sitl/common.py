"""LagrangeBench plumbing shared by train.py and evaluate.py: the datasets, the case (features,
noise, integrator, normalisation) and the model of one kind, all from the generated RPF dataset.
Runs in .venv-lb (LagrangeBench 0.2.0, imported through lbcompat)."""
import os
import warnings
from pathlib import Path

os.environ.setdefault("WANDB_MODE", "disabled")
warnings.filterwarnings("ignore", category=DeprecationWarning)  # jaxopt: unmaintained
warnings.filterwarnings("ignore", category=FutureWarning)

import lbcompat  # noqa: E402

lbcompat.import_lagrangebench()

import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402
from lagrangebench import H5Dataset, case_builder  # noqa: E402

from sitl import model as M  # noqa: E402
from sitl import settings as S  # noqa: E402


def _guard_diverged_rollouts():
    """LagrangeBench's rollout loop (validation during training, and `infer`) re-allocates the graph
    list whenever it overflows and retries the step; once a model's positions are NaN (a diverged
    solver or network) every allocation overflows again and the loop never ends. Its per-batch
    rollout is replaced by the same loop (LagrangeBench 0.2.0's `_eval_batched_rollout`, MIT) that
    stops at the first non-finite predicted frame and sets it and every later frame to +inf: the
    rollout ends, its MSE is +inf (reported as diverged), and a diverged validation never replaces a
    finite best checkpoint (LagrangeBench keeps a checkpoint whose loss is lower; a NaN loss would
    stick). Its first validation is kept as the best whatever its loss.
    A re-allocation that does not cure the overflow is an error, never an endless loop."""
    from lagrangebench.evaluate import rollout as R
    from lagrangebench.utils import broadcast_from_batch, broadcast_to_batch

    if getattr(R, "_sitl_guarded", False):
        return

    def batched(forward_eval_vmap, preprocess_eval_vmap, case, params, state, traj_batch_i, neighbors,
                metrics_computer_vmap, n_rollout_steps, t_window, n_extrap_steps=0):
        pos_input_batch, particle_type_batch = traj_batch_i
        current_batch_size, n_nodes_max, _, dim = pos_input_batch.shape
        if n_rollout_steps == -1:
            n_rollout_steps = pos_input_batch.shape[2] - t_window
        current = pos_input_batch[:, :, 0:t_window]
        traj_len = n_rollout_steps + n_extrap_steps
        targets = pos_input_batch[:, :, t_window:t_window + traj_len]
        predictions = jnp.zeros((current_batch_size, traj_len, n_nodes_max, dim))
        neighbors_batch = broadcast_to_batch(neighbors, current_batch_size)
        step, retried, diverged = 0, False, None
        while step < traj_len:
            sample_batch = (current, particle_type_batch)
            features_batch, new_neighbors = preprocess_eval_vmap(sample_batch, neighbors_batch)
            if new_neighbors.did_buffer_overflow.sum() > 0:
                if retried:  # e.g. particles piled up by a diverging network: treated as diverged
                    print(f"(eval) rollout step {step}: the graph list overflows right after its re-allocation: "
                          "diverged", flush=True)
                    predictions, diverged = predictions.at[:, step:].set(jnp.inf), step
                    break
                ind = jnp.argmax(new_neighbors.did_buffer_overflow)
                _, nbrs_temp = case.allocate_eval(broadcast_from_batch(sample_batch, index=ind))
                neighbors_batch = broadcast_to_batch(nbrs_temp, current_batch_size)
                retried = True
                continue
            neighbors_batch, retried = new_neighbors, False
            nxt, state_batch = forward_eval_vmap(params, state, (features_batch, particle_type_batch), current,
                                                 targets[:, :, step])
            state = broadcast_from_batch(state_batch, 0)
            if not bool(jnp.all(jnp.isfinite(nxt[:, :, -1]))):   # diverged: +inf to the end
                predictions, diverged = predictions.at[:, step:].set(jnp.inf), step
                break
            current = nxt
            predictions = predictions.at[:, step].set(current[:, :, -1])
            step += 1
        targets = targets.transpose(0, 2, 1, 3)
        metrics_batch = metrics_computer_vmap(predictions[:, :n_rollout_steps], targets)
        if diverged is not None:  # periodic distances of inf are NaN: the position errors are +inf
            metrics_batch = {k: (v.at[:, diverged:].set(jnp.inf) if k.startswith(("mse", "mae")) else v)
                             for k, v in metrics_batch.items()}
        return predictions, metrics_batch, broadcast_from_batch(neighbors_batch, 0)

    R._eval_batched_rollout = batched
    R._sitl_guarded = True


_guard_diverged_rollouts()


class Interleaved(H5Dataset):
    """An evaluation split (valid / test: trajectories cut into windows) whose windows are ordered
    round-robin over the trajectories (seeds): window i is window i // S of trajectory i % S. So the
    first n windows (LagrangeBench's `n_trajs`, e.g. the validation windows that choose the best
    checkpoint) come from every seed, not all from seed 0 as in LagrangeBench's own order."""

    def __getitem__(self, idx: int):
        return self.getter(self.source(idx))

    def source(self, idx: int) -> int:
        """LagrangeBench's own index (trajectory-major) of our window `idx`."""
        n_traj = len(self.traj_keys)
        if not 0 <= idx < self.num_samples:
            raise IndexError(f"{self.file_path}: window {idx} of {self.num_samples}")
        return (idx % n_traj) * self._split_valid_traj_into_n + idx // n_traj

    def seed_of(self, idx: int) -> int:
        """The trajectory (seed) window `idx` is cut from."""
        return idx % len(self.traj_keys)


def datasets(exp: S.Experiment, path: Path):
    """(train, valid, test) datasets: training windows of input_seq_length + 1 frames, plus the
    longest pushforward unroll (as LagrangeBench's runner: train.max_unroll, 0 without pushforward);
    valid / test cut into windows of input_seq_length + n_rollout_steps frames, ordered round-robin
    over the seeds (`Interleaved`)."""
    isl, n = exp.model.input_seq_length, exp.eval.n_rollout_steps
    kw = dict(dataset_path=str(path), name="rpf2d", input_seq_length=isl)
    return (H5Dataset("train", extra_seq_length=exp.train.max_unroll, **kw), Interleaved("valid", extra_seq_length=n, **kw),
            Interleaved("test", extra_seq_length=n, **kw))


def n_windows(exp: S.Experiment, data_test) -> int:
    """Test windows evaluated: all (eval.n_trajs = -1) or the first eval.n_trajs (round-robin over seeds)."""
    return data_test.num_samples if exp.eval.n_trajs == -1 else min(exp.eval.n_trajs, data_test.num_samples)


def case(exp: S.Experiment, data_train, kind: str):
    """LagrangeBench's case of model `kind`: its training noise enters the normalisation statistics
    (LagrangeBench adds noise_std^2 to the variances), so a model is evaluated with its own."""
    meta = data_train.metadata
    box = np.array([b[1] - b[0] for b in meta["bounds"]])
    dtype = jnp.float64 if exp.train.dtype == "float64" else jnp.float32
    return case_builder(box=box, metadata=meta, input_seq_length=exp.model.input_seq_length,
                        noise_std=exp.train.noise(kind), external_force_fn=data_train.external_force_fn,
                        cfg_neighbors={"backend": "jaxmd_vmap", "multiplier": 1.25}, dtype=dtype)


def model(exp: S.Experiment, kind: str, data_train, case_fns):
    """The haiku model of `kind`; SitL's in-model lists are allocated at the first training frame."""
    r_sample = data_train[0][0][:, 0]
    return M.build(kind, data_train.metadata, case_fns.normalization_stats, r_sample, exp.model, exp.train.dtype)
