"""How strongly SitL's in-model SPH solver reacts to LagrangeBench's training noise.

LagrangeBench trains with random-walk noise on the input positions (GNS's recipe, Sanchez-Gonzalez
et al. 2020; SitL's std is `train.sitl_noise_std`, the paper's 1e-5). A GNN sees it as slightly perturbed features; SitL's SPH
substeps see it as compressed and stretched particle pairs, and a weakly compressible solver turns
that into pressure accelerations of order c^2 (delta rho / rho) / dx. This script puts a number on
it: on a stored training frame, the RMS change of our coarse solver's acceleration (sitl/model.py's
`coarse_solver`, the SitL substep's physics) when the positions get Gaussian noise of each std,
in LagrangeBench's normalised units (a * Delta t^2 / acc_std, Delta t = the frame interval), beside
the RMS of the clean acceleration in the same units; and both in the units of the model trained at
that noise (LagrangeBench normalises with sqrt(acc_std^2 + noise_std^2)), with the noise in units of
the dataset's sigma_a. When the change dominates, the corrector is
trained mostly to cancel the solver's reaction to noise that the test rollouts never contain.

Writes results/<profile>/sitl/metrics/noise_response.json (committed by `make snapshot`).

    .venv-lb/bin/python sitl/noise_response.py --profile cpu [--stds 3e-4 1e-4 3e-5 1e-5]
"""
import json
from pathlib import Path

import h5py
import jax.numpy as jnp
import numpy as np

from sitl import generate
from sitl import model as M
from sitl import settings as S
from lab.cli import profile_main
from lab.atomic import write_text


def response(path: Path, substeps: int, stds, frame: int = 100, seed: int = 0, dtype: str = "float32") -> list:
    meta = json.loads((path / "metadata.json").read_text())
    with h5py.File(path / "train.h5") as f:
        pos = f["00000/position"][frame:frame + 2].astype(np.float64)
    solver = M.coarse_solver(meta, substeps, dtype)
    disp = solver.scene.domain.make_displacement(1.0)
    frame_dt = meta["dt"] * meta["write_every"]
    scale = frame_dt**2 / np.asarray(meta["acc_std"])
    r_prev, r0 = jnp.asarray(pos[0], solver.dtype), jnp.asarray(pos[1], solver.dtype)
    u = disp(r0, r_prev) / frame_dt
    nbrs = solver.neighbors.allocate(r0)
    a0 = np.asarray(solver.state_at(r0, u, solver.neighbors.update(r0, nbrs)).dudt)
    rms_clean = float(np.sqrt(np.mean((a0 * scale) ** 2)))
    rng = np.random.default_rng(seed)
    rows = []
    acc_std = np.asarray(meta["acc_std"])
    for s in stds:
        rn = solver.scene.domain.shift(r0, jnp.asarray(rng.normal(0.0, s, r0.shape), solver.dtype))
        a = np.asarray(solver.state_at(rn, u, solver.neighbors.update(rn, nbrs)).dudt)
        # the units the model trained at this noise works in: LagrangeBench inflates the statistics,
        # std = sqrt(acc_std^2 + noise_std^2) (data/utils.py get_dataset_stats)
        scale_model = frame_dt**2 / np.sqrt(acc_std**2 + s**2)
        rows.append({"noise_std": float(s), "noise_over_dx": float(s / meta["dx"]),
                     "noise_over_sigma_a": float(s / np.sqrt(np.mean(acc_std**2))),
                     "rms_change": float(np.sqrt(np.mean(((a - a0) * scale) ** 2))), "rms_clean": rms_clean,
                     "rms_change_model_units": float(np.sqrt(np.mean(((a - a0) * scale_model) ** 2))),
                     "rms_clean_model_units": float(np.sqrt(np.mean((a0 * scale_model) ** 2)))})
    return rows


def options(ap):
    ap.add_argument("--stds", type=float, nargs="+", default=None,
                    help="default: 3e-4 (LagrangeBench's default), 1e-4, 3e-5 and the paper's 1e-5")


def main(args):
    exp = S.load(args.profile)
    path = generate.ready(exp, args.results)
    frame, seed = 100, 0
    rows = response(path, exp.model.substeps, args.stds or [3e-4, 1e-4, 3e-5, exp.train.sitl_noise_std], frame, seed)
    dest = S.metrics_path(args.results, "solver").with_name("noise_response.json")
    write_text(dest, json.dumps({"substeps": exp.model.substeps, "frame": frame, "seed": seed, "rows": rows},
                               indent=2) + "\n")
    for r in rows:
        print(f"noise {r['noise_std']:.1e} ({r['noise_over_dx']:.1e} dx, {r['noise_over_sigma_a']:.2g} sigma_a): SPH "
              f"acceleration changes by {r['rms_change']:.3g} RMS (data-normalised units; "
              f"{r['rms_change_model_units']:.3g} in the model's); the clean acceleration's RMS is {r['rms_clean']:.3g} "
              f"({r['rms_clean_model_units']:.3g})")
    print(f"written {dest}", flush=True)
    return rows


if __name__ == "__main__":
    profile_main(main, __doc__, options)
