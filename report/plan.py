"""`make all`'s plan: every target in dependency order with its expected wall time on this machine
for the profile, and the total, printed before anything runs.

    python -m report.plan --profile paper [--results results/paper] [--sitl-profile cpu] [TARGET ...]

A target's time is measured (wall + compile time of its runs, from the metrics an earlier run left in
results/<profile>/; shown with the file) or estimated (docs/time_estimates.yaml, with its source).
Table 1 and Fig. 3 are taken from `--sitl-profile` (cpu on a machine without a GPU)."""
import argparse
from pathlib import Path

from . import fmt, paper, timing


def plan_rows(profile: str, results, names, sitl_profile: str = None) -> list:
    """[(target, profile, seconds or None, how)] in the order of `names`."""
    targets = paper.targets()
    table = timing.estimates()
    results = Path(results)
    rows = []
    for name in names:
        t = targets[name]
        prof = sitl_profile if (sitl_profile and name in ("table1", "fig3")) else profile
        res = results.parent / prof if prof != profile else results
        sec = timing.measured_seconds(t, res)
        if sec is not None:
            over = timing.overhead_seconds(prof, table)
            rows.append((name, prof, sec + over, f"measured: {res / t['timing']} (+ {fmt.duration(over)} start-up, plots)"))
            continue
        sec = timing.estimate_seconds(name, prof, table)
        src = ((table["targets"].get(name) or {}).get(prof) or {}).get("source", "")
        rows.append((name, prof, sec, f"estimate: {src}" if sec is not None else "no estimate for this profile"))
    return rows


def render(rows, profile: str) -> str:
    lines = [f"make all PROFILE={profile}: {len(rows)} targets in this order, expected wall time on this machine",
             f"  {'target':<10} {'profile':<8} {'expected':>10}  from"]
    for name, prof, sec, how in rows:
        lines.append(f"  {name:<10} {prof:<8} {fmt.duration(sec) if sec is not None else '?':>10}  {how}")
    known = [r[2] for r in rows if r[2] is not None]
    unknown = len(rows) - len(known)
    total = fmt.duration(sum(known))
    lines.append(f"  {'total':<10} {'':<8} {total:>10}" + (f"  (+ {unknown} without an estimate)" if unknown else "")
                 + "  (cached runs are skipped: a resumed make all takes only what is left)")
    return "\n".join(lines)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--profile", default="paper")
    ap.add_argument("--results", default=None)
    ap.add_argument("--sitl-profile", default=None)
    ap.add_argument("targets", nargs="*")
    a = ap.parse_args(argv)
    names = a.targets or list(paper.ALL_TARGETS)
    unknown = [n for n in names if n not in paper.ALL_TARGETS]
    if unknown:
        ap.error(f"unknown targets {unknown}; known: {' '.join(paper.ALL_TARGETS)}")
    rows = plan_rows(a.profile, a.results or f"results/{a.profile}", names, a.sitl_profile)
    print(render(rows, a.profile), flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
