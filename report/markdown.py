"""The report as markdown (results/<profile>/report/report.md): the same content as index.html,
every number followed by a footnote naming the file, row and column it comes from."""
import os

from . import fmt, timing
from .atlas import OTHER_LOAD_NOTE, setting_label
from .model import Report, TargetReport
from .paper import ROOT
from .stability import NUMBERS


SMOKE_NOTE = ("The smoke profile runs small, short versions of each target: its verdicts compare them with the "
              "paper settings' tolerances and are expected to differ.")
NO_REASON = "no documented reason for this profile's runs"


def cell(text) -> str:
    """Text for a markdown table cell (a | would end the cell)."""
    return str(text).replace("|", "\\|")


class Doc:
    def __init__(self, rep: Report, out_dir, links: dict):
        self.rep, self.out, self.links = rep, out_dir, links
        self.notes = {}

    def num(self, trace, unit: str = "", value=None) -> str:
        v = trace.value() if value is None else value
        text = fmt.duration(v) if trace.display == "duration" else fmt.number(v) + (f" {unit}" if unit else "")
        key = trace.describe(ROOT)
        n = self.notes.setdefault(key, len(self.notes) + 1)
        return f"{text}[^{n}]"

    def link(self, repo_path: str) -> str:
        return f"[{repo_path}]({os.path.relpath(ROOT / repo_path, self.out)})"


def tolerance(d: Doc, c) -> str:
    if c.tol_kind is None:
        return "-"
    return {"max": lambda: f"<= {d.num(c.tol_trace, c.unit)}", "min": lambda: f">= {d.num(c.tol_trace, c.unit)}",
            "abs": lambda: f"paper +- {d.num(c.tol_trace, c.unit)}",
            "factor": lambda: f"within a factor {d.num(c.tol_trace)} of the paper",
            "below_paper": lambda: "<= paper"}[c.tol_kind]()


def target_section(d: Doc, t: TargetReport) -> list:
    out = [f"## {t.paper_where}: {t.title}", "", f"Verdict: **{t.verdict}**. Experiment: {d.link(t.readme)}; "
           f"`make {t.make} PROFILE={t.profile}`."]
    if t.fallback:
        out.append(f"Shown from the **{t.profile}** profile (the {d.rep.profile} profile of this target needs a GPU).")
    if not t.run:
        return out + ["", f"not run: no outputs under `results/{t.profile}/` yet.", ""]
    if t.note:
        out += ["", t.note]
    out.append("")
    for f in t.figures:
        out += [f"![{t.name}: {f.name}]({d.links[str(f)]})", ""]
    if t.checks:
        out += ["| quantity | here | paper | reference | tolerance | verdict |", "|---|---|---|---|---|---|"]
        for c in t.checks:
            here = d.num(c.value_trace, c.unit, c.value) if c.value is not None else "n/a (not in this profile's outputs)"
            pap = d.num(c.paper_trace, c.unit) + (f" ({c.paper_where})" if c.paper_where else "") if c.paper_trace else "-"
            v = {True: "within", False: "outside", None: "-"}[c.passed]
            out.append(f"| {cell(c.label)} | {here} | {pap} | {cell(c.reference) or '-'} | {tolerance(d, c)} | {v} |")
        out.append("")
    if t.verdict == "differs":
        out += [f"**Why it differs:** {t.reason or NO_REASON} (details: {d.link(t.readme)})", ""]
    if t.timing:
        wall, ms = timing.cells(d.num, t.timing)
        n = d.num(t.timing["n"]) if "n" in t.timing else "-"
        out += [f"Wall time of the {n} runs (solve): {wall}; ms per step: {ms}.", ""]
    return out


def render(rep: Report, out_dir, links: dict) -> str:
    d = Doc(rep, out_dir, links)
    out = [f"# JAX-SPH reproduction: {rep.profile} profile", "",
           f"Every target of `make all PROFILE={rep.profile}` beside the paper (Toshev et al. 2024, arXiv:2403.04750), "
           "run or not run. Paper values and tolerances: " + d.link("docs/paper_values.yaml") + ".", "",
           *([SMOKE_NOTE, ""] if rep.profile == "smoke" else []),
           "## Provenance", "", "| | |", "|---|---|"]
    out += [f"| {k} | {v} |" for k, v in rep.provenance.items()]
    out += ["", "## Summary", "", "| target | paper | verdict | wall time of the runs | ms per step |", "|---|---|---|---|---|"]
    for t in rep.targets:
        wall, ms = timing.cells(d.num, t.timing) if t.run else ("-", "-")
        prof = f" ({t.profile} profile)" if t.fallback else ""
        out.append(f"| {t.name}{prof} | {t.paper_where} | {t.verdict} | {wall} | {ms} |")
    out.append("")
    for t in rep.targets:
        out += target_section(d, t)
    out += ["## What accuracy costs: the cheapest setting per error level (2D TGV)", ""]
    if rep.atlas_rows:
        out += ["| error you accept | cheapest setting that reaches it | its error | wall time of the run | "
                "other work meanwhile [cores] |", "|---|---|---|---|---|"]
        for r in rep.atlas_rows:
            if r.run is None:
                out.append(f"| {100 * r.level:g} % | no run | - | - | - |")
                continue
            s = f"{setting_label(r.run)}, dx {d.num(r.traces['dx'])} ({d.num(r.traces['n_particles'])} particles)"
            if not r.reached:
                s = f"no setting of the sweep (best: {s})"
            load = d.num(r.traces["other_load"]) if "other_load" in r.traces else "not measured"
            out.append(f"| {100 * r.level:g} % | {s} | {d.num(r.traces['error'], '%')} | "
                       f"{d.num(r.traces['wall_s']) if r.reached else '-'} | {load} |")
        out += ["", OTHER_LOAD_NOTE]
    else:
        out.append("not run (`make accuracy`).")
    out += ["", "## Stability matrix", ""]
    if rep.stability_rows:
        out += ["| case | method | expected | outcome | as expected | " + " | ".join(h for _, h in NUMBERS) + " |",
                "|---" * (5 + len(NUMBERS)) + "|"]
        for r in rep.stability_rows:
            cells = " | ".join(d.num(r.traces[c]) if c in r.traces else "-" for c, _ in NUMBERS)
            out.append(f"| {r.case} | {r.method} | {r.expected} | {'pass' if r.passed else 'fail'} | "
                       f"{'yes' if r.as_expected else 'no'} | {cells} |")
    else:
        out.append("not run (`make stability`).")
    out += ["", "## Sources", ""] + [f"[^{n}]: {k}" for k, n in d.notes.items()]
    return "\n".join(out) + "\n"
