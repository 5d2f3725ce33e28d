"""Learning curves of the study's trainings (sitl/curve.py records): the training loss every
train.log_steps, and each checkpoint's validation MSE_20 (solid) and MSE_5 (dashed), one colour per
run; the solver alone's test MSE_20 at the same L as a horizontal line (its validation number is not
recorded; the test windows are other windows of the same trajectories' seeds). Is a curve still
moving at its last step? `still_moving` says, from the last two validations.

Writes <results>/sitl_study/curves.png, curves.csv and curves.md (one row per run: steps, last loss, first and
last validation MSE_20, the best, and the relative change over the last two validations).

Made by sitl/study.py (make sitl-study).
"""
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from sitl import curve  # noqa: E402
from sitl import settings as S  # noqa: E402
from lab.atomic import write_text  # noqa: E402
from lab.tables import write_table  # noqa: E402

MOVING = 0.05
"""A curve whose validation MSE_20 changed by more than this fraction between its last two
validations is still moving."""


def still_moving(val: list) -> bool:
    """Whether the last two validations (step, mse5, mse20) differ by more than MOVING."""
    if len(val) < 2:
        return True
    a, b = val[-2][2], val[-1][2]
    return abs(b - a) > MOVING * max(abs(a), 1e-300)


def summary(name: str, c: dict) -> dict:
    val = c["val"]
    last_two = (val[-1][2] - val[-2][2]) / val[-2][2] if len(val) >= 2 and val[-2][2] else None
    return {"run": name, "steps": c["loss"][-1][0] if c["loss"] else 0, "last_loss": c["loss"][-1][1] if c["loss"] else None,
            "first_val_mse20": val[0][2] if val else None, "last_val_mse20": val[-1][2] if val else None,
            "best_val_mse20": min(v[2] for v in val) if val else None, "last_change": last_two,
            "still_moving": still_moving(val)}


def plot(curves: dict, solver_lines: dict, dest: Path, title: str) -> list:
    """curves {run: curve.read(...)}, solver_lines {label: MSE_20}; returns the summary rows."""
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(11, 4.2), constrained_layout=True)
    rows = []
    for i, (name, c) in enumerate(sorted(curves.items())):
        color = f"C{i % 10}"
        if c["loss"]:
            ax1.plot(*zip(*c["loss"]), color=color, lw=1, label=name)
        if c["val"]:
            steps, m5, m20 = zip(*c["val"])
            ax2.plot(steps, m20, "-o", ms=3, color=color, label=f"{name}: MSE_20")
            ax2.plot(steps, m5, "--", color=color, lw=1)
        rows.append(summary(name, c))
    for j, (label, value) in enumerate(solver_lines.items()):
        ax2.axhline(value, color="k", ls=(":", "-.")[j % 2], lw=1, label=label)
    ax1.set(yscale="log", xlabel="training step", ylabel="training loss (normalised acceleration MSE)",
            title="training loss")
    ax2.set(yscale="log", xlabel="training step", ylabel="validation MSE (dashed: MSE_5)",
            title="validation of each checkpoint")
    for ax in (ax1, ax2):
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=6, loc="center left", bbox_to_anchor=(1.0, 0.5))
    fig.suptitle(title, fontsize=9)
    fig.savefig(dest, dpi=120)
    plt.close(fig)
    write_table(dest.with_suffix(".csv"), rows, columns=list(rows[0]) if rows else ["run"])
    write_text(dest.with_suffix(".md"), markdown(rows, solver_lines))
    return rows


def markdown(rows: list, solver_lines: dict) -> str:
    """curves.md: one row per training (its steps, last training loss, first / best / last validation
    MSE_20, the change over its last two validations and whether it is still moving)."""
    def g(x):
        return "" if x is None else f"{x:.3g}"

    lines = ["# Learning curves of the study's trainings", "",
             f"Validation MSE_20 on the same validation windows at each checkpoint; still moving: the last two "
             f"validations differ by more than {MOVING:.0%}. The solver alone's test MSE_20 (other windows of the "
             "same seeds): " + (", ".join(f"{k} {g(v)}" for k, v in solver_lines.items()) or "not evaluated") + ".", "",
             "| run | steps | last loss | first val MSE_20 | best | last | last change | still moving |",
             "|---|---|---|---|---|---|---|---|"]
    for r in rows:
        change = "" if r["last_change"] is None else f"{r['last_change']:+.1%}"
        lines.append(f"| {r['run']} | {r['steps']} | {g(r['last_loss'])} | {g(r['first_val_mse20'])} | "
                     f"{g(r['best_val_mse20'])} | {g(r['last_val_mse20'])} | {change} | "
                     f"{'yes' if r['still_moving'] else 'no'} |")
    return "\n".join(lines) + "\n"


def from_study(results, rows: dict, solver_rows: dict, title: str):
    """The curves of the study's trained runs (rows: {name: row with "folder", "run"}), the solver rows'
    test MSE_20 as lines; writes <results>/sitl_study/curves.png / .csv / .md."""
    curves = {}
    for name, r in rows.items():
        run = r["run"]
        if run.kind not in ("gns", "sitl") or "folder" not in r:
            continue
        path = S.ckpt_dir(r["folder"], run.kind) / "curve.jsonl"
        if path.exists():
            curves[name] = curve.read(path)
    lines = {f"{n} (test MSE_20)": sr["metrics"]["mse20"] for n, sr in solver_rows.items()
             if sr.get("metrics") and sr["metrics"].get("finite", True)}
    if not curves:
        return []
    return plot(curves, lines, Path(results) / "sitl_study" / "curves.png", title)
