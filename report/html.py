"""The report as one HTML page (results/<profile>/report/index.html): figures linked from
./figures/, every number a <span class="num"> carrying its trace (data-src: JSON, title: the file,
row and column in words), label cells marked class="label"."""
import html
import os
from pathlib import Path

from . import fmt, provenance, timing
from .atlas import OTHER_LOAD_NOTE, setting_label
from .markdown import NO_REASON, SMOKE_NOTE, value_header, value_word, verdict_cells
from .model import Report, TargetReport
from .paper import ROOT

CSS = """
body{font-family:system-ui,sans-serif;max-width:1100px;margin:2em auto;padding:0 1em;color:#222}
table{border-collapse:collapse;margin:.6em 0}td,th{border:1px solid #ccc;padding:.25em .5em;vertical-align:top}
th{background:#f4f4f4}img{max-width:100%;border:1px solid #ddd}.num{border-bottom:1px dotted #888}
.v-reproduced,.v-as-expected{color:#176b1f;font-weight:bold}.v-differs{color:#a4161a;font-weight:bold}
.v-not-run{color:#777;font-weight:bold}.note{color:#555;font-size:.92em}code{background:#f4f4f4;padding:0 .2em}
"""


def esc(s) -> str:
    return html.escape(str(s), quote=True)


class Page:
    def __init__(self, rep: Report, out_dir: Path, links: dict):
        self.rep, self.out, self.links = rep, Path(out_dir), links

    def num(self, trace, unit: str = "", value=None) -> str:
        """A traced number: <span class="num" data-src=... title=...>text</span>."""
        v = trace.value() if value is None else value
        text = fmt.duration(v) if trace.display == "duration" else fmt.number(v) + (f" {unit}" if unit else "")
        return (f'<span class="num" data-src="{esc(trace.to_json(self.out))}" '
                f'title="{esc(trace.describe(ROOT))}">{esc(text)}</span>')

    def link(self, repo_path: str, text: str = None) -> str:
        href = os.path.relpath(ROOT / repo_path, self.out)
        return f'<a href="{esc(href)}">{esc(text or repo_path)}</a>'

    @staticmethod
    def verdict(v: str) -> str:
        return f'<span class="v-{v.replace(" ", "-")}">{esc(v)}</span>'


def summary(p: Page) -> list:
    out = ["<h2>Summary</h2>", '<p class="note">Verdict: what the paper\'s figure or table shows; beyond the paper: '
           "our own checks against data the paper does not use, each with its own verdict.</p>",
           "<table><tr><th>target</th><th>paper</th><th>verdict</th><th>beyond the paper</th>"
           "<th>wall time of the runs</th><th>ms per step</th></tr>"]
    for t in p.rep.targets:
        wall, ms = timing.cells(p.num, t.timing) if t.run else ("-", "-")
        prof = f" ({esc(t.profile)} profile)" if t.fallback else ""
        v, beyond = verdict_cells(t)
        v = p.verdict(t.verdict) + esc(v[len(t.verdict):])
        out.append(f'<tr><td class="label"><a href="#{t.name}">{esc(t.name)}</a>{prof}</td>'
                   f'<td class="label">{esc(t.paper_where)}</td><td class="label">{v}</td>'
                   f'<td class="label">{esc(beyond)}</td><td>{wall}</td><td>{ms}</td></tr>')
    return out + ["</table>"]


def tolerance(p: Page, c) -> str:
    if c.tol_kind is None:
        return "-"
    w = value_word(c)
    body = {"max": lambda: f"&le; {p.num(c.tol_trace, c.unit)}", "min": lambda: f"&ge; {p.num(c.tol_trace, c.unit)}",
            "abs": lambda: f"{w} &plusmn; {p.num(c.tol_trace, c.unit)}",
            "factor": lambda: f"within a factor {p.num(c.tol_trace)} of the {w}",
            "below_paper": lambda: f"&le; {w}"}[c.tol_kind]()
    return f'<span title="{esc(c.tol_why)}">{body}</span>'


def checks_table(p: Page, checks: list) -> list:
    if not checks:
        return []
    out = [f"<table><tr><th>quantity</th><th>here</th><th>{value_header(checks)}</th><th>source</th>"
           "<th>reference data</th><th>tolerance</th><th>verdict</th></tr>"]
    for c in checks:
        here = p.num(c.value_trace, c.unit, c.value) if c.value is not None else "n/a (not in this profile's outputs)"
        pap = p.num(c.paper_trace, c.unit) if c.paper_trace is not None else "-"
        v = {True: "within", False: "outside", None: "-"}[c.passed]
        out.append(f'<tr><td class="label">{esc(c.label)}</td><td>{here}</td><td>{pap}</td>'
                   f'<td class="label">{esc(c.source_label) or "-"}</td>'
                   f'<td class="label">{esc(c.reference) or "-"}</td><td>{tolerance(p, c)}</td>'
                   f'<td class="label">{v}</td></tr>')
    return out + ["</table>"]


def group_section(p: Page, t: TargetReport, g) -> list:
    head = f"beyond the paper: {g.title}" if g.beyond_paper else g.title
    out = [f'<h3 id="{t.name}-{g.gid}">{esc(t.paper_where)}, {esc(head)}</h3>', f"<p>Verdict: {p.verdict(g.verdict)}.</p>"]
    out += checks_table(p, g.checks)
    if g.verdict == "differs":
        out.append(f"<p><b>Why it differs:</b> {esc(g.reason or NO_REASON)} (details: {p.link(t.readme)})</p>")
    return out


def target_section(p: Page, t: TargetReport) -> list:
    out = [f'<h2 id="{t.name}">{esc(t.paper_where)}: {esc(t.title)}</h2>',
           f"<p>Verdict: {p.verdict(t.verdict)}. Experiment: {p.link(t.readme)}; "
           f"<code>make {esc(t.make)} PROFILE={esc(t.profile)}</code>.</p>"]
    if t.paper_locator:
        out.append(f'<p class="note">In the paper: {esc(t.paper_locator)}.</p>')
    if t.fallback:
        out.append(f'<p class="note">Shown from the <b>{esc(t.profile)}</b> profile (the {esc(p.rep.profile)} '
                   "profile of this target needs a GPU and was not run here).</p>")
    if not t.run:
        return out + [f"<p>not run: no outputs under <code>results/{esc(t.profile)}/</code> yet "
                      f"(<code>make {esc(t.make)} PROFILE={esc(t.profile)}</code>).</p>"]
    if t.note:
        out.append(f'<p class="note">{esc(t.note)}</p>')
    for f in t.figures:
        out.append(f'<p><img src="{esc(p.links[str(f)])}" alt="{esc(t.name)}: {esc(f.name)}"></p>')
    for f in t.missing_figures:
        out.append(f'<p class="note">figure not made: {esc(os.path.relpath(f, p.rep.results))}</p>')
    out += checks_table(p, t.checks)
    if t.verdict == "differs":
        out.append(f"<p><b>Why it differs:</b> {esc(t.reason or NO_REASON)} (details: {p.link(t.readme)})</p>")
    for g in t.groups:
        out += group_section(p, t, g)
    if t.timing:
        wall, ms = timing.cells(p.num, t.timing)
        n = p.num(t.timing["n"]) if "n" in t.timing else "-"
        out.append(f"<p>Wall time of the {n} {esc(t.count_label)} (solve): {wall}; ms per step: {ms}.</p>")
    return out


def atlas_section(p: Page) -> list:
    out = ['<h2 id="atlas-table">What accuracy costs: the cheapest setting per error level (2D TGV)</h2>']
    if not p.rep.atlas_rows:
        return out + ["<p>not run (<code>make accuracy</code>).</p>"]
    out.append("<table><tr><th>error you accept</th><th>cheapest setting that reaches it</th><th>its error</th>"
               "<th>wall time of the run</th><th>other work meanwhile [cores]</th></tr>")
    for r in p.rep.atlas_rows:
        level = f"{100 * r.level:g} %"
        if r.run is None:
            out.append(f'<tr><td class="label">{level}</td><td class="label">no run</td><td>-</td><td>-</td>'
                       f'<td>-</td></tr>')
            continue
        tr = r.traces
        setting = f"{esc(setting_label(r.run))}, dx {p.num(tr['dx'])} ({p.num(tr['n_particles'])} particles)"
        if not r.reached:
            setting = f"no setting of the sweep (best: {setting})"
        load = p.num(tr["other_load"]) if "other_load" in tr else '<span class="label">not measured</span>'
        out.append(f'<tr><td class="label">{level}</td><td>{setting}</td><td>{p.num(tr["error"], "%")}</td>'
                   f'<td>{p.num(tr["wall_s"]) if r.reached else "-"}</td><td>{load}</td></tr>')
    return out + ["</table>", f'<p class="note">error: time-averaged |u_max / exact - 1|; every run: '
                              f'{p.link(os.path.relpath(p.rep.atlas_file, ROOT)) if _inside(p.rep.atlas_file) else esc(p.rep.atlas_file)}. '
                              f'{esc(OTHER_LOAD_NOTE)}</p>']


def _inside(path) -> bool:
    try:
        Path(path).resolve().relative_to(ROOT)
        return True
    except ValueError:
        return False


def stability_section(p: Page) -> list:
    from .stability import NUMBERS
    out = ['<h2 id="stability-matrix">Stability matrix</h2>']
    if not p.rep.stability_rows:
        return out + ["<p>not run (<code>make stability</code>).</p>"]
    head = "".join(f"<th>{esc(h)}</th>" for _, h in NUMBERS)
    out.append(f"<table><tr><th>case</th><th>method</th><th>expected</th><th>outcome</th><th>as expected</th>{head}</tr>")
    for r in p.rep.stability_rows:
        cells = "".join(f"<td>{p.num(r.traces[c]) if c in r.traces else '-'}</td>" for c, _ in NUMBERS)
        out.append(f'<tr><td class="label">{esc(r.case)}</td><td class="label">{esc(r.method)}</td>'
                   f'<td class="label">{esc(r.expected)}</td><td class="label">{"pass" if r.passed else "fail"}</td>'
                   f'<td class="label">{p.verdict("as expected") if r.as_expected else p.verdict("differs")}</td>{cells}</tr>')
    return out + ["</table>"]


def provenance_section(p: Page) -> list:
    rows = "".join(f'<tr><th>{esc(k)}</th><td class="label">{esc(v)}</td></tr>' for k, v in provenance.display(p.rep.provenance).items())
    return ['<h2 id="provenance">Provenance</h2>', f'<table class="provenance">{rows}</table>',
            f'<p class="note">Paper values and tolerances: {p.link("docs/paper_values.yaml")}. Hover a number '
            "for the file, row and column it comes from.</p>"]


def render(rep: Report, out_dir, links: dict) -> str:
    p = Page(rep, out_dir, links)
    body = [f"<h1>JAX-SPH reproduction: {esc(rep.profile)} profile</h1>",
            f'<p class="note">Every target of <code>make all PROFILE={esc(rep.profile)}</code> beside the paper '
            "(Toshev et al. 2024, arXiv:2403.04750), run or not run.</p>"]
    if rep.profile == "smoke":
        body.append(f'<p class="note">{esc(SMOKE_NOTE)}</p>')
    body += provenance_section(p) + summary(p)
    for t in rep.targets:
        body += target_section(p, t)
    body += atlas_section(p) + stability_section(p)
    return ("<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">"
            f"<title>JAX-SPH reproduction ({esc(rep.profile)})</title><style>{CSS}</style></head><body>\n"
            + "\n".join(body) + "\n</body></html>\n")
