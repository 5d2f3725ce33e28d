"""The report's content: one entry per target of `make all` (run or not run, never omitted), with
its figures, headline checks, timing and verdict; the atlas's cheapest-setting table; the stability
matrix; provenance. Rendered by html.py and markdown.py."""
from dataclasses import dataclass, field
from pathlib import Path
from typing import Optional

from . import atlas, checks, paper, provenance, stability, timing
from .trace import Trace, safe_value

VERDICTS = ("reproduced", "differs", "figure only", "not evaluated", "as expected", "not run", "atlas")


@dataclass
class GroupReport:
    """Checks judged apart from a target's headline (docs/paper_values.yaml `groups`): a second reading
    of the paper's claim (Fig. 2's two starts) or, beyond_paper, our own check against data the paper
    does not use (Fig. 8's experiments); each with its own verdict."""
    gid: str
    title: str
    beyond_paper: bool
    checks: list
    verdict: str
    reason: str = ""


@dataclass
class TargetReport:
    name: str
    title: str
    paper_where: str
    readme: str
    make: str
    profile: str                 # the profile whose outputs are shown (fallback: e.g. cpu for Table 1)
    fallback: bool
    run: bool
    figures: list                # existing figure files
    missing_figures: list        # named in docs/paper_values.yaml but not on disk
    checks: list                 # checks.CheckResult
    timing: dict                 # name -> Trace (wall, compile, ms_min, ms_max, n)
    verdict: str
    reason: str = ""
    note: str = ""
    beyond_paper: bool = False
    groups: list = field(default_factory=list)   # GroupReport, in the file's order
    count_label: str = "runs"                    # what the timing's count `n` counts
    paper_locator: str = ""                      # where in the paper (docs/paper_values.yaml paper.locator)

    @property
    def paper_groups(self) -> list:
        return [g for g in self.groups if not g.beyond_paper]

    @property
    def beyond_groups(self) -> list:
        return [g for g in self.groups if g.beyond_paper]


@dataclass
class Report:
    profile: str
    results: Path
    values_path: Path
    targets: list
    atlas_rows: list = field(default_factory=list)
    atlas_file: Optional[Path] = None
    stability_rows: list = field(default_factory=list)
    stability_file: Optional[Path] = None
    provenance: dict = field(default_factory=dict)


def results_for(name: str, entry: dict, results: Path, profile: str) -> tuple:
    """(results folder, profile) whose outputs represent `name`: the profile's own, or its fallback's
    (docs/paper_values.yaml `fallback`) when the own ones are absent and the fallback's exist."""
    fb = (entry.get("fallback") or {}).get(profile)
    if fb and not _has_outputs(entry, results) and _has_outputs(entry, results.parent / fb):
        return results.parent / fb, fb
    return results, profile


def _has_outputs(entry: dict, results: Path) -> bool:
    files = list(entry.get("figures") or []) + [c["file"] for c in (entry.get("checks") or {}).values()]
    if entry.get("timing"):
        files.append(entry["timing"])
    return any((results / f).exists() for f in files)


def verdict(entry: dict, run: bool, results_: list, stab: list) -> str:
    if not run:
        return "not run"
    if entry.get("beyond_paper"):
        if stab and entry.get("make") == "stability":
            return "as expected" if all(r.as_expected for r in stab) else "differs"
        return "atlas" if entry.get("make") == "accuracy" else "not evaluated"
    if entry.get("qualitative"):
        return "figure only"
    return judged_verdict(results_)


def judged_verdict(results_: list) -> str:
    judged = [c.passed for c in results_ if c.passed is not None]
    if not judged:
        return "not evaluated"
    return "reproduced" if all(judged) else "differs"


def group_reports(entry: dict, run: bool, cks: list) -> list:
    out = []
    for gid, g in (entry.get("groups") or {}).items():
        mine = [c for c in cks if c.group == gid]
        v = judged_verdict(mine) if run else "not run"
        out.append(GroupReport(gid=gid, title=g.get("title", gid), beyond_paper=bool(g.get("beyond_paper")),
                               checks=mine, verdict=v, reason=(g.get("reason") or "").strip() if v == "differs" else ""))
    return out


def target_report(name: str, entry: dict, results: Path, profile: str, values: dict, values_path) -> TargetReport:
    res, prof = results_for(name, entry, results, profile)
    figs = [res / f for f in entry.get("figures") or []]
    cks = [checks.evaluate(name, cid, c, res, values, values_path) for cid, c in (entry.get("checks") or {}).items()]
    tim = timing.traces(entry, res)
    run = _has_outputs(entry, res)
    stab = stability.matrix(res / "stability" / "stability.csv") if name == "stability" and run else []
    groups = group_reports(entry, run, cks)
    beyond = {g.gid for g in groups if g.beyond_paper}
    v = verdict(entry, run, [c for c in cks if c.group not in beyond], stab)
    return TargetReport(name=name, title=entry["title"], paper_where=entry["paper"]["where"], readme=entry["readme"],
                        make=entry.get("make", name), profile=prof, fallback=prof != profile, run=run,
                        figures=[f for f in figs if f.exists()], missing_figures=[str(f) for f in figs if not f.exists()],
                        checks=[c for c in cks if c.group is None], groups=groups,
                        count_label=(entry.get("timing_count") or {}).get("label", "runs"),
                        paper_locator="" if entry.get("beyond_paper") else entry["paper"].get("locator", ""), timing={k: t for k, t in tim.items() if safe_value(t) is not None}, verdict=v,
                        reason=entry.get("reason", "").strip() if v == "differs" else "",
                        note=entry.get("note", "") or entry.get("qualitative_note", ""),
                        beyond_paper=bool(entry.get("beyond_paper")))


def build(results, profile: str, values_path=paper.PAPER_VALUES) -> Report:
    results = Path(results).resolve()
    values = paper.load(values_path)
    entries = paper.targets(values)
    rep = Report(profile=profile, results=results, values_path=Path(values_path).resolve(),
                 targets=[target_report(n, e, results, profile, values, values_path) for n, e in entries.items()],
                 provenance=provenance.load_or_collect(results, profile))
    runs_csv = results / "accuracy" / "runs.csv"
    if runs_csv.exists():
        rep.atlas_file, rep.atlas_rows = runs_csv, atlas.cheapest(runs_csv, profile)
    stab = results / "stability" / "stability.csv"
    if stab.exists():
        rep.stability_file, rep.stability_rows = stab, stability.matrix(stab)
    return rep


def traced(trace: Optional[Trace]) -> Optional[float]:
    return safe_value(trace)
