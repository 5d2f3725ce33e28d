"""Fig. 3 (Toshev et al. 2024): velocity magnitude per particle of the solver-only, GNS and SitL
rollouts and the ground truth, at several coarse steps of one test rollout. The velocity is what
LagrangeBench sees: the periodic displacement between consecutive frames over the frame interval
dt * write_every (stamp s = s coarse steps after the last input frame; s = 0 is the input).

Reads the rollouts of sitl/evaluate.py (results/<profile>/sitl/rollouts/<model>/rollout_<i>.pkl);
writes results/<profile>/fig3/fig3.png and .pdf.

    python sitl/plot_fig3.py --profile smoke
"""
import json
import pickle
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from sitl import settings as S  # noqa: E402
from lab.cli import profile_main  # noqa: E402
from lab.io import OutputError  # noqa: E402
from lab.deliver import note_input  # noqa: E402

ROWS = (("truth", "ground truth"), ("solver", "solver only"), ("gns", "GNS"), ("sitl", "SitL"))


def speeds(traj: np.ndarray, box, frame_dt: float) -> np.ndarray:
    """|u| per frame (from the frame before): traj (T, N, dim) -> (T - 1, N)."""
    d = traj[1:] - traj[:-1]
    d = d - box * np.round(d / box)
    return np.linalg.norm(d, axis=-1) / frame_dt


def load(results, exp: S.Experiment) -> dict:
    i = exp.fig3.rollout
    out = {}
    for m in exp.models:
        p = S.rollout_dir(results, m) / f"rollout_{i}.pkl"
        if not p.exists():
            raise FileNotFoundError(f"{p}: missing; run sitl/evaluate.py --model {m}")
        note_input(p)
        try:
            with p.open("rb") as f:
                r = pickle.load(f)
        except Exception as e:  # noqa: BLE001 - any failure to read is damage, named with its file
            raise OutputError(f"{p}: damaged ({type(e).__name__}); `make fig3` evaluates {m} again") from None
        out[m] = np.asarray(r["predicted_rollout"])
        out["truth"] = np.asarray(r["ground_truth_rollout"])
    return out


def plot(results, exp: S.Experiment, profile: str) -> Path:
    meta = json.loads((S.data_dir(results) / "metadata.json").read_text())
    box = np.array([b[1] - b[0] for b in meta["bounds"]])
    frame_dt = meta["dt"] * meta["write_every"]
    trajs = load(results, exp)
    isl = exp.model.input_seq_length
    rows = [(k, lab) for k, lab in ROWS if k in trajs]
    stamps = exp.fig3.stamps
    spd = {k: speeds(trajs[k], box, frame_dt) for k, _ in rows}
    vmax = max(float(np.nanmax(spd["truth"])), 1e-12)
    fig, axes = plt.subplots(len(rows), len(stamps), figsize=(1.6 * len(stamps) + 1.2, 2.9 * len(rows)),
                             squeeze=False, constrained_layout=True)
    for i, (k, lab) in enumerate(rows):
        for j, s in enumerate(stamps):
            ax = axes[i, j]
            f = isl - 1 + s                      # frame index: s coarse steps after the last input
            r = trajs[k][f]
            ok = np.all(np.isfinite(r), axis=1)
            sc = ax.scatter(r[ok, 0], r[ok, 1], c=spd[k][f - 1][ok], s=4, cmap="viridis", vmin=0, vmax=vmax)
            ax.set_xlim(0, box[0])
            ax.set_ylim(0, box[1])
            ax.set_aspect("equal")
            ax.set_xticks([])
            ax.set_yticks([])
            if not ok.all():
                ax.text(0.5, 0.5, "diverged", transform=ax.transAxes, ha="center", color="r")
            if i == 0:
                ax.set_title(f"step {s}\n({s * meta['write_every']} SPH steps)", fontsize=8)
            if j == 0:
                ax.set_ylabel(lab)
    fig.colorbar(sc, ax=axes, shrink=0.6, label="|u|")
    fig.suptitle(f"RPF 2D, test rollout {exp.fig3.rollout} ({profile}, {meta['num_particles_max']} particles)",
                 fontsize=9)
    dest = Path(results) / "fig3"
    dest.mkdir(parents=True, exist_ok=True)
    for ext in ("png", "pdf"):
        fig.savefig(dest / f"fig3.{ext}", dpi=150)
    plt.close(fig)
    print(f"fig3: {dest / 'fig3.png'}")
    return dest


def main(args):
    plot(args.results, S.load(args.profile), args.profile)


if __name__ == "__main__":
    profile_main(main, __doc__)
