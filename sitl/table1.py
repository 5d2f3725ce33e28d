"""Table 1 (Toshev et al. 2024): RPF 2D, 20-step test rollouts, solver only vs GNS vs SitL, our
measured values beside the paper's. Reads results/<profile>/sitl/metrics/<model>.json (written by
sitl/evaluate.py) and writes results/<profile>/table1/table1.csv and table1.md.

    python sitl/table1.py --profile smoke
"""
import csv
import json
from pathlib import Path

from sitl import settings as S
from sph.harness.cli import profile_main

PAPER = {  # Table 1 of the paper: metric -> (solver only, GNS, SitL)
    "mse5": (1.7e-7, 6.7e-9, 3.3e-9),
    "mse20": (7.9e-6, 1.9e-7, 1.3e-7),
    "e_kin": (0.13, 2.8e-4, 7.4e-5),
    "sinkhorn": (3.4e-7, 3.7e-8, 9.3e-9),
}
LABELS = {"mse5": "MSE_5", "mse20": "MSE_20", "e_kin": "MSE_Ekin", "sinkhorn": "Sinkhorn"}
COLUMNS = {"solver": "Solver only", "gns": "GNS", "sitl": "SitL"}


def load_metrics(results, models) -> dict:
    out = {}
    for m in models:
        p = S.metrics_path(results, m)
        if not p.exists():
            raise FileNotFoundError(f"{p}: missing; run sitl/evaluate.py --model {m}")
        out[m] = json.loads(p.read_text())
    return out


def rows(measured: dict) -> list:
    models = [m for m in S.MODELS if m in measured]
    table = []
    for key, label in LABELS.items():
        row = {"metric": label}
        for m in models:
            row[f"{m}_ours"] = measured[m][key]
            row[f"{m}_paper"] = PAPER[key][S.MODELS.index(m)]
        table.append(row)
    for key, label in (("s_per_coarse_step", "inference s / coarse step"), ("train_steps", "training steps"),
                       ("train_wall_s", "training wall s"), ("n_rollouts", "test rollouts")):
        table.append({"metric": label, **{f"{m}_ours": measured[m].get(key) for m in models}})
    return table


def ordering(measured: dict) -> str:
    """Whether the paper's ordering (solver only worst, SitL best) holds, per metric."""
    if not all(m in measured for m in S.MODELS):
        return "not all three models evaluated"
    out = []
    for key, label in LABELS.items():
        v = {m: measured[m][key] for m in S.MODELS}
        holds = v["sitl"] <= v["gns"] <= v["solver"]
        out.append(f"{label}: {'holds' if holds else 'does not hold'} "
                   f"(best {min(v, key=lambda m: v[m] if v[m] == v[m] else float('inf'))})")
    return "; ".join(out)


def fmt(x) -> str:
    if x is None:
        return ""
    if isinstance(x, int):
        return str(x)
    return f"{x:.3g}"


def write(results, models=S.MODELS, profile: str = "") -> Path:
    measured = load_metrics(results, models)
    table = rows(measured)
    dest = Path(results) / "table1"
    dest.mkdir(parents=True, exist_ok=True)
    fields = ["metric"] + [f"{m}_{w}" for m in models for w in ("ours", "paper")]
    with (dest / "table1.csv").open("w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=fields)
        w.writeheader()
        for row in table:
            w.writerow({k: row.get(k, "") for k in fields})
    head = "| metric | " + " | ".join(f"{COLUMNS[m]} (ours) | {COLUMNS[m]} (paper)" for m in models) + " |"
    lines = [f"# Table 1, RPF 2D, profile {profile or Path(results).name}", "",
             head, "|" + "---|" * (1 + 2 * len(models))]
    for row in table:
        lines.append(f"| {row['metric']} | " + " | ".join(f"{fmt(row.get(f'{m}_ours'))} | {fmt(row.get(f'{m}_paper'))}"
                                                         for m in models) + " |")
    lines += ["", f"Paper's ordering (solver only worst, SitL best): {ordering(measured)}.", ""]
    (dest / "table1.md").write_text("\n".join(lines))
    print("\n".join(lines))
    return dest


def main(args):
    write(args.results, S.load(args.profile).models, args.profile)


if __name__ == "__main__":
    profile_main(main, __doc__)
