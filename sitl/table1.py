"""Table 1 (Toshev et al. 2024): RPF 2D, 20-step test rollouts, solver only vs GNS vs SitL, our
measured values (mean over the test windows of every seed, with a 95 % bootstrap interval over the
windows) beside the paper's, and paired comparisons of the models on the same windows. Reads
results/<profile>/sitl/metrics/<model>.json (written by sitl/evaluate.py) and writes
results/<profile>/table1/table1.csv, comparisons.csv and table1.md.

    python sitl/table1.py --profile smoke
"""
import json
from pathlib import Path

from sitl import settings as S
from sitl import stats
from sitl.fmt import ratio_digits
from lab.cli import profile_main
from lab.atomic import write_text
from lab.tables import write_table
from lab.io import OutputError

PAPER = {  # Table 1 of the paper: metric -> (solver only, GNS, SitL)
    "mse5": (1.7e-7, 6.7e-9, 3.3e-9),
    "mse20": (7.9e-6, 1.9e-7, 1.3e-7),
    "e_kin": (0.13, 2.8e-4, 7.4e-5),
    "sinkhorn": (3.4e-7, 3.7e-8, 9.3e-9),
}
LABELS = {"mse5": "MSE_5", "mse20": "MSE_20", "e_kin": "MSE_Ekin", "sinkhorn": "Sinkhorn"}
LB_RPF_PARTICLES = 3200
"""Particles of LagrangeBench's RPF 2D dataset (its metadata; the paper's text gives no count)."""
COLUMNS = {"solver": "Solver only", "gns": "GNS", "sitl": "SitL"}


def load_metrics(results, models) -> dict:
    out = {}
    for m in models:
        p = S.metrics_path(results, m)
        if not p.exists():
            raise FileNotFoundError(f"{p}: missing; run sitl/evaluate.py --model {m}")
        try:
            out[m] = json.loads(p.read_text())
        except ValueError as e:
            raise OutputError(f"{p}: damaged ({e}); `make table1` sets it aside and evaluates {m} again") from None
    return out


TRAINING = ("train_steps", "train_wall_s", "noise_std")  # rows that describe a training


def rows(measured: dict) -> list:
    models = [m for m in S.MODELS if m in measured]
    table = []
    for key, label in LABELS.items():
        row = {"metric": label}
        for m in models:
            row[f"{m}_ours"] = measured[m][key]
            lo, hi = measured[m].get(f"ci_{key}", (None, None))
            row[f"{m}_lo"], row[f"{m}_hi"] = lo, hi
            row[f"{m}_paper"] = PAPER[key][S.MODELS.index(m)]
        table.append(row)
    for key, label in (("s_per_coarse_step", "inference s / coarse step"), ("train_steps", "training steps"),
                       ("train_wall_s", "training wall s"), ("noise_std", "training noise_std"),
                       ("n_rollouts", "test windows")):
        # the solver alone has no weights: its training cells stay empty (its record carries the
        # profile's noise_std only because every evaluation records its settings)
        table.append({"metric": label, **{f"{m}_ours": None if m == "solver" and key in TRAINING else measured[m].get(key)
                                          for m in models}})
    return table


PAIRS = (("sitl", "solver"), ("gns", "solver"), ("sitl", "gns"))


def comparisons(measured: dict, n_boot: int) -> list:
    """Paired comparisons on the same test windows: mean(a) / mean(b) per metric with its paired
    bootstrap interval (sitl/stats.py) and whether a is lower, higher or undecided."""
    out = []
    for a, b in PAIRS:
        if a not in measured or b not in measured:
            continue
        for key, label in LABELS.items():
            wa, wb = (measured[m].get("per_window", {}).get(key) for m in (a, b))
            if not wa or not wb or len(wa) != len(wb):
                continue
            r, lo, hi = stats.paired_ratio(wa, wb, n_boot)
            out.append({"a": a, "b": b, "metric": label, "ratio": r, "lo": lo, "hi": hi,
                        "verdict": stats.verdict(lo, hi, len(wa))})
    return out


def chain_verdict(steps) -> str:
    """Whether a chain a < b < c ... holds, from the paired verdicts of its steps (a vs b, b vs c, ...,
    each from stats.verdict): 'holds' when every step is significantly lower, 'does not hold' when
    one is significantly the other way or equal within the margin, else 'undecided'. The one rule
    behind the paper's ordering SitL < GNS < solver only, here and in Table 1 as its authors ran it
    (sitl/study.py)."""
    steps = list(steps)
    if steps and all(s == "lower" for s in steps):
        return "holds"
    return "does not hold" if any(s in ("higher", stats.EQUAL) for s in steps) else "undecided"


def ordering(measured: dict, comps: list) -> str:
    """Whether the paper's ordering (SitL below GNS below solver only) holds per metric, decided by
    the paired intervals (chain_verdict)."""
    if not all(m in measured for m in S.MODELS):
        return "not all three models evaluated"
    out = []
    for label in LABELS.values():
        v = {(c["a"], c["b"]): c["verdict"] for c in comps if c["metric"] == label}
        steps = [v.get(("sitl", "gns")), v.get(("gns", "solver"))]
        out.append(f"{label}: {chain_verdict(steps)} (SitL vs GNS {steps[0]}, GNS vs solver {steps[1]})")
    return "; ".join(out)


def fmt(x, digits: int = 3) -> str:
    if x is None:
        return ""
    if isinstance(x, int):
        return str(x)
    return f"{x:.{digits}g}"


def fmt_ci(row: dict, m: str) -> str:
    v, lo, hi = row.get(f"{m}_ours"), row.get(f"{m}_lo"), row.get(f"{m}_hi")
    if lo is None or hi is None:
        return fmt(v)
    return f"{fmt(v)} [{fmt(lo)}, {fmt(hi)}]"


def e_kin_note(n_particles) -> list:
    """MSE_Ekin is the squared error of E_kin = sum_i |v_i|^2 dx^dim (LagrangeBench's MetricsComputer,
    evaluate/metrics.py: the sum over particles times dx**dim, v the displacement per frame interval),
    an integral over the domain: on another particle count in the same box it is on the same scale,
    so ours stands on the scale of a run on LagrangeBench's dataset (LB_RPF_PARTICLES). Said where the
    counts differ."""
    if n_particles is None or n_particles == LB_RPF_PARTICLES:
        return []
    return ["", f"MSE_Ekin is comparable across particle counts: LagrangeBench's E_kin is the sum of |v|^2 over the "
                f"particles times dx^2, an integral over the box, so ours on {n_particles} particles is on the scale "
                f"of a run on LagrangeBench's RPF 2D dataset ({LB_RPF_PARTICLES} particles)."]


def write(results, models=S.MODELS, profile: str = "", n_boot: int = 2000, n_particles: int = None) -> Path:
    measured = load_metrics(results, models)
    table = rows(measured)
    comps = comparisons(measured, n_boot)
    dest = Path(results) / "table1"
    dest.mkdir(parents=True, exist_ok=True)
    fields = ["metric"] + [f"{m}_{w}" for m in models for w in ("ours", "lo", "hi", "paper")]
    write_table(dest / "table1.csv", table, columns=fields)
    write_table(dest / "comparisons.csv", comps, columns=["a", "b", "metric", "ratio", "lo", "hi", "verdict"])
    head = "| metric | " + " | ".join(f"{COLUMNS[m]} (ours) | {COLUMNS[m]} (paper)" for m in models) + " |"
    n = measured[models[0]].get("n_rollouts")
    lines = [f"# Table 1, RPF 2D, profile {profile or Path(results).name}", "",
             f"Ours: mean over {n} test windows [95 % bootstrap interval over the windows].", "",
             head, "|" + "---|" * (1 + 2 * len(models))]
    for row in table:
        lines.append(f"| {row['metric']} | " + " | ".join(f"{fmt_ci(row, m)} | {fmt(row.get(f'{m}_paper'))}"
                                                         for m in models) + " |")
    lines += e_kin_note(n_particles)
    if comps:
        lines += ["", "Paired comparisons on the same windows: ratio of means [95 % paired bootstrap interval].", "",
                  "| a / b | metric | ratio | verdict |", "|---|---|---|---|"]
        for c in comps:
            d = ratio_digits(c["ratio"], c["lo"], c["hi"])
            lines.append(f"| {COLUMNS[c['a']]} / {COLUMNS[c['b']]} | {c['metric']} | {fmt(c['ratio'], d)} "
                         f"[{fmt(c['lo'], d)}, {fmt(c['hi'], d)}] | {COLUMNS[c['a']]} {c['verdict']} |")
    lines += ["", f"Paper's ordering (SitL < GNS < solver only): {ordering(measured, comps)}.", ""]
    write_text(dest / "table1.md", "\n".join(lines))
    print("\n".join(lines))
    return dest


def main(args):
    exp = S.load(args.profile)
    write(args.results, exp.models, args.profile, exp.eval.bootstrap, exp.data.n_particles)


if __name__ == "__main__":
    profile_main(main, __doc__)
