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


def datasets(exp: S.Experiment, path: Path):
    """(train, valid, test) H5Datasets: training windows of input_seq_length + 1 frames (no
    pushforward), valid/test cut into windows of input_seq_length + n_rollout_steps frames."""
    isl, n = exp.model.input_seq_length, exp.eval.n_rollout_steps
    kw = dict(dataset_path=str(path), name="rpf2d", input_seq_length=isl)
    return (H5Dataset("train", extra_seq_length=0, **kw), H5Dataset("valid", extra_seq_length=n, **kw),
            H5Dataset("test", extra_seq_length=n, **kw))


def case(exp: S.Experiment, data_train):
    meta = data_train.metadata
    box = np.array([b[1] - b[0] for b in meta["bounds"]])
    dtype = jnp.float64 if exp.train.dtype == "float64" else jnp.float32
    return case_builder(box=box, metadata=meta, input_seq_length=exp.model.input_seq_length,
                        noise_std=exp.train.noise_std, external_force_fn=data_train.external_force_fn,
                        cfg_neighbors={"backend": "jaxmd_vmap", "multiplier": 1.25}, dtype=dtype)


def model(exp: S.Experiment, kind: str, data_train, case_fns):
    """The haiku model of `kind`; SitL's in-model lists are allocated at the first training frame."""
    r_sample = data_train[0][0][:, 0]
    return M.build(kind, data_train.metadata, case_fns.normalization_stats, r_sample, exp.model, exp.train.dtype)
