"""Fig. 3 (Toshev et al. 2024): velocity magnitude per particle of the solver-only, GNS and SitL
rollouts and the ground truth, at several coarse steps of one test rollout (the paper's stamps reach
500 coarse steps); beside it, the position MSE against the rollout step (mean over the test windows
and their range). The velocity is what LagrangeBench sees: the periodic displacement between
consecutive frames over the frame interval dt * write_every (stamp s = s coarse steps after the last
input frame; s = 0 is the input).

Reads the long rollouts of the folder's fig3 runs (study.py: sitl/fig3_rollouts.py, in
results/<profile>/fig3/rollouts/<model>/); writes into --out (default results/<profile>/fig3)
fig3.{png,pdf} (stamps), fig3_mse.png and mse_steps.{csv,md} (MSE at steps 1, 5, 20, 50, 100, 200,
500 as far as the rollouts reach).

    python experiments/sitl/plot_fig3.py --profile smoke     (make fig3 runs the rollouts first)
"""
import json
import math
import pickle
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from sitl import settings as S  # noqa: E402
from lab.cli import profile_main  # noqa: E402
from lab import tables  # noqa: E402
from lab.atomic import write_text  # noqa: E402
from lab.figures import figure_dir, save_figure  # noqa: E402
from lab.io import OutputError  # noqa: E402
from lab.deliver import note_input  # noqa: E402

ROWS = (("truth", "ground truth"), ("solver", "solver only"), ("gns", "GNS"), ("sitl", "SitL"))


def speeds(traj: np.ndarray, box, frame_dt: float) -> np.ndarray:
    """|u| per frame (from the frame before): traj (T, N, dim) -> (T - 1, N)."""
    with np.errstate(invalid="ignore"):  # a diverged rollout's frames are inf: their speed is NaN, not plotted
        d = traj[1:] - traj[:-1]
        d = d - box * np.round(d / box)
        return np.linalg.norm(d, axis=-1) / frame_dt


def load(results, exp: S.Experiment) -> dict:
    """{"truth": (T, N, dim), model: (T, N, dim)} of test rollout fig3.rollout, and {model: record}."""
    from sitl.fig3_rollouts import out_dir

    i = exp.fig3.rollout
    out, records = {}, {}
    for m in exp.models:
        rec = out_dir(results) / m / "record.json"
        p = out_dir(results) / m / f"rollout_{i}.pkl"
        for f in (rec, p):
            if not f.exists():
                raise FileNotFoundError(f"{f}: missing; run sitl/fig3_rollouts.py (make fig3)")
        note_input(rec, p)
        try:
            records[m] = json.loads(rec.read_text())
            with p.open("rb") as f:
                r = pickle.load(f)
        except Exception as e:  # noqa: BLE001 - any failure to read is damage, named with its file
            raise OutputError(f"{p.parent}: damaged ({type(e).__name__}); delete it and `make fig3` rolls out {m} "
                              "again") from None
        out[m] = np.asarray(r["predicted_rollout"])
        out["truth"] = np.asarray(r["ground_truth_rollout"])
    return out, records


TABLE_STEPS = (1, 5, 20, 50, 100, 200, 500)


def mse_table(records: dict) -> list:
    """Rows {model, step, mean, min, max, n_windows, diverged} of the MSE at TABLE_STEPS (within the
    rollouts): mean, min and max over the windows still finite at that step, `diverged` the number
    that are not (their MSE is inf or NaN; a mean over them would be inf). All diverged: NaN."""
    rows = []
    for m, rec in records.items():
        a = np.asarray(rec["mse_steps"], np.float64)            # (windows, steps)
        for k in TABLE_STEPS:
            if k <= a.shape[1]:
                col = a[:, k - 1]
                ok = col[np.isfinite(col)]
                mean, lo, hi = (float(ok.mean()), float(ok.min()), float(ok.max())) if ok.size else (math.nan,) * 3
                rows.append({"model": m, "step": k, "mean": mean, "min": lo, "max": hi,
                             "n_windows": int(a.shape[0]), "diverged": int(a.shape[0] - ok.size)})
    return rows


def plot_mse(records: dict, dest: Path, title: str):
    fig, ax = plt.subplots(figsize=(5.5, 3.8), constrained_layout=True)
    for (m, lab), color in zip(ROWS[1:], ("C0", "C2", "C1")):
        if m not in records:
            continue
        a = np.asarray(records[m]["mse_steps"], np.float64)
        steps = np.arange(1, a.shape[1] + 1)
        ok = np.isfinite(a).all(axis=0)
        # the solver alone dashed and on top: where SitL equals it, SitL's line would hide it
        solver = m == "solver"
        ax.plot(steps[ok], a[:, ok].mean(axis=0), color=color, ls="--" if solver else "-", zorder=3 if solver else 2,
                label=f"{lab} (mean of {a.shape[0]} windows)")
        ax.fill_between(steps[ok], a[:, ok].min(axis=0), a[:, ok].max(axis=0), color=color, alpha=0.2)
        if not ok.all():
            ax.axvline(steps[~ok][0], color=color, ls=":", lw=1, label=f"{lab}: non-finite from step {steps[~ok][0]}")
    ax.set(xscale="log", yscale="log", xlabel="rollout step (coarse steps)", ylabel="position MSE", title=title)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7, loc="upper left")
    fig.savefig(dest, dpi=130)
    plt.close(fig)


def write_table(rows: list, dest: Path):
    tables.write_table(dest.with_suffix(".csv"), rows)
    lines = ["| model | step | MSE (mean of the finite windows) | min | max | windows | diverged |",
             "|---|---|---|---|---|---|---|"]
    lines += [f"| {r['model']} | {r['step']} | {r['mean']:.3g} | {r['min']:.3g} | {r['max']:.3g} | {r['n_windows']} | "
              f"{r['diverged']} |" for r in rows]
    write_text(dest.with_suffix(".md"), "\n".join(lines) + "\n")


def plot(results, exp: S.Experiment, profile: str, out=None) -> Path:
    meta = json.loads((S.data_dir(results) / "metadata.json").read_text())
    box = np.array([b[1] - b[0] for b in meta["bounds"]])
    frame_dt = meta["dt"] * meta["write_every"]
    trajs, records = load(results, exp)
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
    dest = figure_dir(results, "fig3", out)
    save_figure(fig, dest, "fig3", dpi=150)
    plot_mse(records, dest / "fig3_mse.png", f"RPF 2D, {profile}: MSE against rollout step")
    write_table(mse_table(records), dest / "mse_steps.csv")
    print(f"fig3: {dest / 'fig3.png'}")
    return dest


def options(ap):
    ap.add_argument("--out", default=None, help="figure folder (default <results>/fig3)")


def main(args):
    plot(args.results, S.load(args.profile), args.profile, args.out)


if __name__ == "__main__":
    profile_main(main, __doc__, options)
