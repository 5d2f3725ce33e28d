"""The report as markdown (results/<profile>/report/report.md): the same content as index.html,
every number followed by a footnote naming the file, row and column it comes from."""
import os

from . import fmt, provenance, timing
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


def value_word(c) -> str:
    """What the compared value is called: the paper's own, or a reference's (authors' code, literature)."""
    return "paper" if c.is_paper or not c.source_kind else "reference"


def value_header(checks) -> str:
    """The compared-value column: "paper" only where every value in it is the paper's own."""
    return "reference" if any(c.source_kind and not c.is_paper for c in checks) else "paper"


def tolerance(d: Doc, c) -> str:
    if c.tol_kind is None:
        return "-"
    w = value_word(c)
    return {"max": lambda: f"<= {d.num(c.tol_trace, c.unit)}", "min": lambda: f">= {d.num(c.tol_trace, c.unit)}",
            "abs": lambda: f"{w} +- {d.num(c.tol_trace, c.unit)}",
            "factor": lambda: f"within a factor {d.num(c.tol_trace)} of the {w}",
            "below_paper": lambda: f"<= {w}"}[c.tol_kind]()


def checks_table(d: Doc, checks) -> list:
    if not checks:
        return []
    out = [f"| quantity | here | {value_header(checks)} | source | reference data | tolerance | verdict |",
           "|---|---|---|---|---|---|---|"]
    for c in checks:
        here = d.num(c.value_trace, c.unit, c.value) if c.value is not None else "n/a (not in this profile's outputs)"
        pap = d.num(c.paper_trace, c.unit) if c.paper_trace else "-"
        v = {True: "within", False: "outside", None: "-"}[c.passed]
        out.append(f"| {cell(c.label)} | {here} | {pap} | {cell(c.source_label) or '-'} | {cell(c.reference) or '-'} | "
                   f"{tolerance(d, c)} | {v} |")
    return out + [""]


def group_section(d: Doc, t: TargetReport, g) -> list:
    head = f"beyond the paper: {g.title}" if g.beyond_paper else g.title
    out = [f"### {t.paper_where}, {head}", "", f"Verdict: **{g.verdict}**.", ""]
    out += checks_table(d, g.checks)
    if g.verdict == "differs":
        out += [f"**Why it differs:** {g.reason or NO_REASON} (details: {d.link(t.readme)})", ""]
    return out


def verdict_cells(t: TargetReport) -> tuple:
    """(the paper's verdict, with each reading of it where there are several; beyond the paper)."""
    v = t.verdict
    if t.run and t.paper_groups:
        v += " (" + "; ".join(f"{g.title}: {g.verdict}" for g in t.paper_groups) + ")"
    beyond = "; ".join(f"{g.title}: {g.verdict}" for g in t.beyond_groups) if t.run else ""
    return v, beyond or "-"


def target_section(d: Doc, t: TargetReport) -> list:
    out = [f"## {t.paper_where}: {t.title}", "", f"Verdict: **{t.verdict}**. Experiment: {d.link(t.readme)}; "
           f"`make {t.make} PROFILE={t.profile}`."]
    if t.paper_locator:
        out.append(f"In the paper: {t.paper_locator}.")
    if t.fallback:
        out.append(f"Shown from the **{t.profile}** profile (the {d.rep.profile} profile of this target needs a GPU).")
    if not t.run:
        return out + ["", f"not run: no outputs under `results/{t.profile}/` yet.", ""]
    if t.note:
        out += ["", t.note]
    out.append("")
    for f in t.figures:
        out += [f"![{t.name}: {f.name}]({d.links[str(f)]})", ""]
    out += checks_table(d, t.checks)
    if t.verdict == "differs":
        out += [f"**Why it differs:** {t.reason or NO_REASON} (details: {d.link(t.readme)})", ""]
    for g in t.groups:
        out += group_section(d, t, g)
    if t.timing:
        wall, ms = timing.cells(d.num, t.timing)
        n = d.num(t.timing["n"]) if "n" in t.timing else "-"
        out += [f"Wall time of the {n} {t.count_label} (solve): {wall}; ms per step: {ms}.", ""]
    return out


def render(rep: Report, out_dir, links: dict) -> str:
    d = Doc(rep, out_dir, links)
    out = [f"# JAX-SPH reproduction: {rep.profile} profile", "",
           f"Every target of `make all PROFILE={rep.profile}` beside the paper (Toshev et al. 2024, arXiv:2403.04750), "
           "run or not run. Paper values and tolerances: " + d.link("docs/paper_values.yaml") + ".", "",
           *([SMOKE_NOTE, ""] if rep.profile == "smoke" else []),
           "## Provenance", "", "| | |", "|---|---|"]
    out += [f"| {k} | {cell(v)} |" for k, v in provenance.display(rep.provenance).items()]
    out += ["", "## Summary", "", "Verdict: what the paper's figure or table shows; beyond the paper: our own checks "
            "against data the paper does not use, each with its own verdict.", "",
            "| target | paper | verdict | beyond the paper | wall time of the runs | ms per step |",
            "|---|---|---|---|---|---|"]
    for t in rep.targets:
        wall, ms = timing.cells(d.num, t.timing) if t.run else ("-", "-")
        prof = f" ({t.profile} profile)" if t.fallback else ""
        v, beyond = verdict_cells(t)
        out.append(f"| {t.name}{prof} | {t.paper_where} | {cell(v)} | {cell(beyond)} | {wall} | {ms} |")
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
