"""The reproduction at a glance (report/): `make report PROFILE=smoke` on smoke outputs of the
smallest targets (Fig. 10 and the heat validation, ~40 s; every other target must then be listed as
"not run"), the traces behind every number, `make -n all PROFILE=smoke` (dependency order and the
time plan), `make snapshot`, the README tables from a snapshot, and the run-folder lock."""
import json
import os
import re
import shutil
import subprocess
import sys
import time
from html.parser import HTMLParser
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from report import fmt, paper, plan, readme_tables, snapshot, timing
from report.trace import Trace

ROOT = Path(__file__).resolve().parents[2]
FIXTURES = ROOT / "tests" / "fixtures"
RUN_TARGETS = ("fig10",)  # what the smoke fixture runs; every other target is "not run"


def make(*args, check=True, timeout=900) -> subprocess.CompletedProcess:
    out = subprocess.run(["make", "--no-print-directory", *args], cwd=ROOT, capture_output=True, text=True,
                         timeout=timeout)
    if check and out.returncode != 0:
        raise AssertionError(f"make {' '.join(args)} failed ({out.returncode}):\n{out.stdout[-3000:]}\n{out.stderr[-3000:]}")
    return out


@pytest.fixture(scope="module")
def smoke(tmp_path_factory):
    """results/smoke of the smallest targets (Fig. 10 + heat validation), then its report."""
    results = tmp_path_factory.mktemp("results") / "smoke"
    make("fig10", "PROFILE=smoke", f"RESULTS={results}")
    make("report", "PROFILE=smoke", f"RESULTS={results}")
    return results


class Page(HTMLParser):
    """Collects images, traced numbers, section ids and the text of non-label table cells that lies
    outside traced numbers."""

    def __init__(self):
        super().__init__()
        self.images, self.nums, self.ids, self.stack = [], [], set(), []
        self.cell_text, self.in_cell, self.in_num, self.num_attrs, self.num_text = [], False, 0, None, ""
        self.tags = set()

    def handle_starttag(self, tag, attrs):
        a = dict(attrs)
        self.tags.add(tag)
        if "id" in a:
            self.ids.add(a["id"])
        if tag == "img":
            self.images.append(a["src"])
        if tag == "td":
            self.in_cell = "label" not in (a.get("class") or "")
            self.cell_text.append("")
        if tag == "span" and "num" in (a.get("class") or "").split():
            self.in_num, self.num_attrs, self.num_text = 1, a, ""
        elif tag == "span" and self.in_num:
            self.in_num += 1

    def handle_endtag(self, tag):
        if tag == "td":
            self.in_cell = False
        if tag == "span" and self.in_num:
            self.in_num -= 1
            if not self.in_num:
                self.nums.append((self.num_attrs, self.num_text))

    def handle_data(self, data):
        if self.in_num:
            self.num_text += data
        elif self.in_cell:
            self.cell_text[-1] += data


def parse(path) -> Page:
    p = Page()
    p.feed(Path(path).read_text())
    p.close()
    return p


def shown(trace: Trace, text: str) -> str:
    """What the page shows for `trace` (the number as the report formats it, with its unit)."""
    v = trace.value()
    if trace.display == "duration":
        return fmt.duration(v)
    unit = text.split(" ", 1)[1] if " " in text else ""
    return fmt.number(v) + (f" {unit}" if unit else "")


def as_float(text: str) -> float:
    num, _, unit = text.partition(" ")
    return float(num) * {"min": 60.0, "h": 3600.0}.get(unit, 1.0)


# -- make report PROFILE=smoke -----------------------------------------------------------------------
def test_page_parses_as_html_and_every_image_exists(smoke):
    page = smoke / "report" / "index.html"
    p = parse(page)
    assert {"html", "head", "body", "title", "table", "img"} <= p.tags
    assert p.images, "the smoke report shows Fig. 10's figures"
    for src in p.images:
        f = (page.parent / src).resolve()
        assert f.is_file() and f.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n", src
    assert (smoke / "report" / "report.md").stat().st_size > 0


def test_every_target_appears_run_or_not_run(smoke):
    p = parse(smoke / "report" / "index.html")
    md = (smoke / "report" / "report.md").read_text()
    html = (smoke / "report" / "index.html").read_text()
    for name in paper.ALL_TARGETS:
        assert name in p.ids, name
        section = html.split(f'id="{name}"', 1)[1].split("<h2", 1)[0]
        assert ("not run" in section) == (name not in RUN_TARGETS), name
        assert f"`make {paper.targets()[name].get('make', name)} PROFILE=smoke`" in md
    assert "Stability matrix" in html and "cheapest setting" in html and "Provenance" in html


def test_every_number_traces_to_a_metrics_file_or_the_paper_values(smoke):
    page = smoke / "report" / "index.html"
    p = parse(page)
    assert len(p.nums) >= 10
    files = set()
    for attrs, text in p.nums:
        tr = Trace.from_json(attrs["data-src"], page.parent)
        assert tr.file.exists(), tr.file
        files.add(tr.file.name)
        assert text == shown(tr, text), (text, attrs["data-src"])
        assert as_float(text) == pytest.approx(tr.value() if tr.display != "duration" else as_float(fmt.duration(tr.value())),
                                               rel=6e-3), text
        assert tr.file.name in attrs["title"]  # the tooltip names the file
    assert {"metrics.csv", "paper_values.yaml"} <= files
    # no number on the page outside a traced span (label cells aside: names, settings)
    for cell in p.cell_text:
        assert not re.search(r"\d", cell), f"untraced number in a table cell: {cell!r}"


def test_numbers_equal_the_metrics_read_independently(smoke):
    """The shown numbers are the files' numbers: Fig. 10's largest temperature and the heat
    operator's decay-rate error at the finest dx, read with pandas here."""
    md = (smoke / "report" / "report.md").read_text()
    ch = pd.read_csv(smoke / "fig10" / "metrics.csv").iloc[0]
    assert f"| {fmt.number(ch['T_fluid_max'])}[^" in md
    hv = pd.read_csv(smoke / "heat_validation" / "metrics.csv")
    err = abs(hv.loc[hv["dx"].idxmin(), "decay_rate_relerr"]) * 100
    assert f"| {fmt.number(err)} %[^" in md
    notes = dict(re.findall(r"^\[\^(\d+)\]: (.+)$", md, re.M))
    refs = set(re.findall(r"\[\^(\d+)\](?!:)", md))
    assert refs and refs <= set(notes)
    for n in refs:
        path = notes[n].split(";")[0]
        assert (ROOT / path).exists() or Path(path).exists(), notes[n]


def test_a_target_without_outputs_has_no_numbers(smoke):
    html = (smoke / "report" / "index.html").read_text()
    section = html.split('id="fig9"', 1)[1].split("<h2", 1)[0]
    assert 'class="num"' not in section and "<img" not in section


# -- make all ----------------------------------------------------------------------------------------
SCRIPTS = [("fig1", "gradcheck/plot_fig1.py"), ("fig2", "inverse/plot_fig2.py"), ("fig4", "experiments/tgv2d/plot_fig4.py"),
           ("fig5", "experiments/tgv2d/plot_fig5.py"), ("fig6", "experiments/ldc2d/plot_fig6.py"),
           ("fig7", "experiments/ldc2d/plot_fig7.py"),
           ("fig8", "experiments/dambreak2d/plot_fig8.py"), ("fig9", "experiments/tgv3d/plot_fig9.py"),
           ("fig10", "experiments/thermal/plot_fig10.py"), ("table1", "sitl/table1.py"), ("fig3", "experiments/sitl/plot_fig3.py"),
           ("stability", "experiments/stability/plot_stability.py"),
           ("accuracy", "experiments/accuracy/plot_accuracy.py"),
           ("report", "-m report.build")]


def test_make_all_dry_run_lists_every_target_in_dependency_order_after_the_plan(smoke):
    out = make("-n", "all", "PROFILE=smoke", f"RESULTS={smoke}", timeout=300).stdout
    plan_end = out.index("  total ")
    first = [out.find(s, plan_end) for _, s in SCRIPTS]
    assert all(i > 0 for i in first), [t for (t, _), i in zip(SCRIPTS, first) if i < 0]
    assert first == sorted(first), "targets out of dependency order"
    head = out[:plan_end]
    rows = [re.match(r"\s+(\S+)\s+smoke\s+", line) for line in head.splitlines()]
    assert [m.group(1) for m in rows if m] == list(paper.ALL_TARGETS)
    assert re.search(r"fig10\s+smoke\s+[\d.]+ s\s+measured: ", head)  # the smoke fixture's own records
    assert re.search(r"fig9\s+smoke\s+[\d.]+ \w+\s+estimate: ", head)
    assert re.search(r"  total\s+[\d.]+ (s|min|h)", out)


def test_timing_cells_say_how_busy_the_machine_was_only_when_every_run_measured_it(tmp_path):
    """The wall-time cell names the most other work any run ran beside (lab.other_load)
    when every run of the target measured it; with one run made before that, it names none."""
    (tmp_path / "x").mkdir()
    rows = {"wall_s": [60.0, 30.0], "compile_s": [2.0, 1.0], "ms_per_step": [10.0, 5.0], "other_load": [0.02, 0.97]}
    pd.DataFrame(rows).to_csv(tmp_path / "x" / "metrics.csv", index=False)
    target = {"timing": "x/metrics.csv"}
    num = lambda tr: fmt.duration(tr.value()) if tr.display == "duration" else fmt.number(tr.value())  # noqa: E731
    wall, ms = timing.cells(num, timing.traces(target, tmp_path))
    assert (wall, ms) == ("90 s (+ 3 s compile; other work meanwhile: up to 0.97 cores)", "5 - 10")
    pd.DataFrame({**rows, "other_load": [0.02, np.nan]}).to_csv(tmp_path / "x" / "metrics.csv", index=False)
    assert timing.cells(num, timing.traces(target, tmp_path))[0] == "90 s (+ 3 s compile)"


def test_plan_total_is_the_sum_of_its_rows(smoke):
    rows = plan.plan_rows("smoke", smoke, paper.ALL_TARGETS)
    assert all(sec is not None and sec > 0 for _, _, sec, _ in rows)
    text = plan.render(rows, "smoke")
    assert "total" in text and fmt.duration(sum(r[2] for r in rows)) in text
    paper_rows = {r[0]: r for r in plan.plan_rows("paper", smoke.parent / "paper", paper.ALL_TARGETS, "cpu")}
    assert paper_rows["table1"][1] == "cpu" and paper_rows["fig9"][3].startswith("estimate")


# -- make snapshot, make readme-tables ---------------------------------------------------------------
@pytest.fixture
def clean_tree(monkeypatch):
    """The checkout as `make snapshot` needs it, committed (a session editing the tree would be
    refused: tests/harness/test_snapshot_provenance.py tests that refusal)."""
    from report import provenance
    monkeypatch.setattr(provenance, "dirty_paths", lambda: [])


def test_snapshot_is_small_self_contained_and_traceable(smoke, tmp_path, clean_tree):
    out = snapshot.snapshot("smoke", smoke, tmp_path / "docs" / "results" / "smoke")
    assert snapshot.size_mb(out) <= snapshot.LIMIT_MB
    assert (out / "provenance.json").exists() and (out / "fig10" / "metrics.csv").exists()
    assert json.loads((out / "provenance.json").read_text())["profile"] == "smoke"
    assert list(out.rglob("record.json"))
    page = out / "report" / "index.html"
    p = parse(page)
    for src in p.images:
        assert (page.parent / src).resolve().is_relative_to(out), src
        assert (page.parent / src).exists()
    for attrs, text in p.nums:
        tr = Trace.from_json(attrs["data-src"], page.parent)
        assert tr.file.is_relative_to(out) or tr.file.name == "paper_values.yaml", tr.file
        assert text == shown(tr, text)


def test_a_snapshot_figure_compressed_again_keeps_its_bytes(tmp_path):
    """A figure restored from a snapshot (already a palette PNG) goes into the next snapshot unchanged:
    quantizing it again would rewrite every committed figure for nothing."""
    from report import figures

    src = next((FIXTURES / "snapshot" / "paper").rglob("*.png"))
    once = figures.compress_png(src, tmp_path / "once.png")
    twice = figures.compress_png(once, tmp_path / "twice.png")
    assert twice.read_bytes() == once.read_bytes()


def test_snapshot_leaves_out_the_records_of_an_experiment_still_running(tmp_path):
    """Records are copied from a results folder only once its experiment wrote its table: a sweep in
    progress (records, no runs.csv yet) would hand over a partial set the report calls not run."""
    src, dst = tmp_path / "results", tmp_path / "snap"
    for rel in ("done/a/record.json", "running/tgv/b/record.json"):
        (src / rel).parent.mkdir(parents=True)
        (src / rel).write_text("{}")
    (src / "done" / "metrics.csv").write_text("x\n1\n")
    assert snapshot.copy_results(src, dst, []) == 2  # the table and the finished experiment's record
    assert (dst / "done" / "a" / "record.json").exists() and not (dst / "running").exists()


def test_benchmark_tables_go_into_the_snapshot_and_come_back_without_overwriting(tmp_path):
    """results/bench's tables (the benchmarks the README quotes) are committed beside the profiles
    (docs/results/bench): a new table replaces the snapshot's, one results/bench lacks stays in the
    snapshot, a trajectory or figure is not copied; restore brings back only what results/bench lacks."""
    from report import restore

    bench, snap = tmp_path / "results" / "bench", tmp_path / "docs" / "bench"
    bench.mkdir(parents=True)
    snap.mkdir(parents=True)
    (bench / "grad_memory.csv").write_text("steps,rss_GB\n100,0.6\n")
    (bench / "big.h5").write_bytes(b"0" * 10)
    (snap / "grad_memory.csv").write_text("steps,rss_GB\n100,9.9\n")
    (snap / "peer.csv").write_text("case,ms\ntgv,1.3\n")
    assert snapshot.copy_bench(bench, snap) == ["grad_memory.csv"]
    assert (snap / "grad_memory.csv").read_text().endswith("0.6\n") and (snap / "peer.csv").exists()
    assert not (snap / "big.h5").exists()
    (bench / "grad_memory.csv").write_text("steps,rss_GB\n100,0.5\n")  # measured here since
    assert restore.restore_bench(snap, bench) == ["peer.csv"]
    assert (bench / "grad_memory.csv").read_text().endswith("0.5\n")  # never overwritten by the snapshot
    assert restore.restore_bench(snap, bench) == [] and snapshot.copy_bench(tmp_path / "none", snap) == []


def test_snapshot_refuses_to_drop_a_target_until_restore_seeds_it_from_the_committed_one(smoke, tmp_path, clean_tree):
    """A fresh clone (results/ without a target the committed snapshot holds) cannot wipe that target by
    `make snapshot`: it refuses naming it; `make restore` copies the snapshot's folder back (never over a
    folder run here), the report's provenance names what was restored, and the snapshot then keeps it."""
    from report import build, model, provenance, restore

    out = snapshot.snapshot("smoke", smoke, tmp_path / "docs" / "smoke")
    fresh = tmp_path / "results" / "smoke"
    shutil.copytree(smoke, fresh, ignore=shutil.ignore_patterns("fig10", "report"))
    (fresh / "heat_validation" / "heat_validation.png").unlink()  # a folder run here: never mixed with the snapshot's
    build.write(model.build(fresh, "smoke"), fresh / "report")
    with pytest.raises(RuntimeError, match=r"results have no smoke/fig10, .*make restore PROFILE=smoke"):
        snapshot.snapshot("smoke", fresh, out)
    assert (out / "fig10" / "metrics.csv").exists()  # the refusal touched nothing
    assert restore.restore_one(out, fresh) == ["fig10"]
    assert restore.restore_one(out, fresh) == []  # nothing twice
    assert not (fresh / "heat_validation" / "heat_validation.png").exists()
    assert (fresh / "fig10" / "metrics.csv").read_bytes() == (out / "fig10" / "metrics.csv").read_bytes()
    assert not (fresh / "report" / provenance.FILE).read_text().count("restored")
    build.write(model.build(fresh, "smoke"), fresh / "report")
    assert "fig10: from the snapshot of" in (fresh / "report" / provenance.FILE).read_text()
    snapshot.snapshot("smoke", fresh, out)
    assert [t.name for t in model.build(out, "smoke").targets if t.run] == list(RUN_TARGETS)
    assert "restored from snapshot" in json.loads((out / provenance.FILE).read_text())


def test_readme_tables_regenerate_the_fixture_readme_unchanged(tmp_path):
    snap = FIXTURES / "snapshot" / "paper"
    readme = FIXTURES / "readme" / "README.md"
    text = readme.read_text()
    assert set(readme_tables.markers(text)) == {"tgv2d", "table1", "atlas", "figures"}
    assert readme_tables.regenerate(text, snap, readme) == text
    # a number typed by hand into a marked table is put back to the record's
    copy = tmp_path / "README.md"
    copy.write_text(text.replace("| 13.3 % |", "| 12.0 % |"))
    rc = readme_tables.main(["--snapshot", str(snap), "--readme", str(copy), "--check"])
    assert rc == 1
    fixed = readme_tables.regenerate(copy.read_text(), snap, readme)
    assert fixed == text


def test_verdict_and_provenance_tables_are_the_reports_and_the_snapshots(tmp_path):
    """The README's verdict table is the report's (Fig. 2 with both starts, Fig. 8's paper verdict apart
    from its checks against experiments, beyond the paper), and its provenance line the snapshot's
    commit and date, saying when the tree was dirty and what came from an earlier snapshot."""
    snap = tmp_path / "paper"
    shutil.copytree(FIXTURES / "snapshot" / "paper", snap)
    prov = {"profile": "paper", "cpu": "some CPU (2 cores available)", "gpu": "none",
            "snapshot_date": "2030-01-02 03:04 UTC", "snapshot_commit": "abcdef0123456789 (with uncommitted changes)",
            "restored from snapshot": "fig1, fig2: from the snapshot of 9876543210fedcba (2030-01-01 00:00 UTC)"}
    (snap / "provenance.json").write_text(json.dumps(prov))
    text = "<!-- table:provenance -->\n<!-- /table:provenance -->\n<!-- table:verdicts -->\n<!-- /table:verdicts -->\n"
    new = readme_tables.regenerate(text, snap, tmp_path / "README.md")
    line = new.split("<!-- table:provenance -->\n")[1].split("\n")[0]
    assert "commit `abcdef0` on 2030-01-02 03:04 UTC" in line and "uncommitted changes" in line
    assert "2 of its target folders were restored from an earlier snapshot (commit `9876543`" in line
    rows = {r.split(" | ")[0].strip("| ").split(" ")[0]: r for r in new.splitlines() if r.startswith("| ")}
    assert "random start, as in the paper's text: differs" in rows["fig2"]
    assert "displaced start, as in the authors' notebook: reproduced" in rows["fig2"]
    fig8 = rows["fig8"].split(" | ")
    assert fig8[2] == "figure only" and "Buchner (2002)" in fig8[3] and "Martin & Moyce (1952)" in fig8[3]
    assert rows["fig7"].split(" | ")[2] == "not run" and rows["table1"].split(" | ")[2] == "differs"
    prov.update(snapshot_commit="abcdef0123456789")
    prov.pop("restored from snapshot")
    (snap / "provenance.json").write_text(json.dumps(prov))
    line = readme_tables.regenerate(text, snap, tmp_path / "README.md").split("<!-- table:provenance -->\n")[1]
    assert "commit `abcdef0`" in line.split("\n")[0] and "uncommitted" not in line and "restored" not in line


def test_the_readme_states_the_snapshots_commit_and_date():
    prov = json.loads((ROOT / "docs" / "results" / "paper" / "provenance.json").read_text())
    readme = (ROOT / "README.md").read_text()
    glance = readme.split("## At a glance", 1)[1].split("\n## ", 1)[0]
    line = glance.split("<!-- table:provenance -->\n", 1)[1].split("<!-- /table:provenance -->")[0]
    assert f"`{prov['snapshot_commit'][:7]}`" in line and prov["snapshot_date"] in line
    own = line.split(" of its target folders were restored")[0]   # the snapshot's own sentence (an origin may be dirty)
    assert ("uncommitted changes" in own) == ("uncommitted changes" in prov["snapshot_commit"] or
                                              bool(prov.get("dirty_tree")))
    assert "<!-- table:verdicts -->" in glance and "<!-- table:figures -->" in glance


def test_fig9_table_says_how_busy_the_machine_was(tmp_path):
    """The 3D TGV table's last column is each run's other_load, "not measured" for runs made before
    it was recorded; every other cell is the metrics file's."""
    from report import readme_tgv3d
    row = {"case": "tgv3d", "method": "tvf", "n_side": 20, "t_end": 10.0, "e_kin_rms_rel": 0.134,
           "e_kin_end_relerr": -0.207, "dissipation_rms_rel": 0.119, "peak_t": 3.7, "peak_dissipation": 0.0146,
           "ms_per_step": 50.3, "wall_s": 70.5, "ref_peak_t": 4.81, "ref_peak_dissipation": 0.0129}
    (tmp_path / "fig9").mkdir()
    pd.DataFrame([{**row, "other_load": 0.98}, {**row, "method": "sph", "other_load": np.nan}]).to_csv(
        tmp_path / "fig9" / "metrics.csv", index=False)
    lines = readme_tgv3d.fig9(tmp_path)
    sph, tvf = lines[2], lines[3]  # sorted by resolution, then method (SPH before TVF)
    assert sph.startswith("| 20³ | SPH |") and sph.endswith("| not measured |")
    assert tvf.startswith("| 20³ | SPH + TVF | 13.4 % | -20.7 % (t = 10) | 11.9 % | 3.7, 0.0146 | 50.3 |")
    assert tvf.endswith("| 70 s | 0.98 |")


def test_readme_tables_unknown_marker_or_missing_source_is_an_error(tmp_path):
    r = tmp_path / "README.md"
    r.write_text("<!-- table:nonsense -->\n<!-- /table:nonsense -->\n")
    assert readme_tables.main(["--snapshot", str(FIXTURES / "snapshot" / "paper"), "--readme", str(r)]) == 2
    r.write_text("<!-- table:tgv2d -->\n<!-- /table:tgv2d -->\n")
    assert readme_tables.main(["--snapshot", str(tmp_path / "none"), "--readme", str(r)]) == 2


def test_a_table_whose_target_is_not_in_the_snapshot_says_so_and_table1_falls_back_to_cpu(tmp_path):
    snap, cpu = tmp_path / "paper", tmp_path / "cpu"
    shutil.copytree(FIXTURES / "snapshot" / "paper" / "fig5", snap / "fig5")
    shutil.copytree(FIXTURES / "snapshot" / "paper" / "table1", cpu / "table1")
    (cpu / "fig3").mkdir()
    shutil.copyfile(FIXTURES / "snapshot" / "paper" / "fig5" / "fig5.png", cpu / "fig3" / "fig3.png")
    text = ("<!-- table:atlas -->\n| 1 % | hand-typed | 3 s |\n<!-- /table:atlas -->\n"
            "<!-- table:table1 -->\n<!-- /table:table1 -->\n<!-- table:figures -->\n<!-- /table:figures -->\n")
    new = readme_tables.regenerate(text, snap, tmp_path / "README.md")
    atlas_body = new.split("<!-- /table:atlas -->")[0]
    assert "Not in this snapshot yet" in atlas_body and "hand-typed" not in atlas_body
    assert not re.search(r"\d+(\.\d+)? ?%", atlas_body.replace("1 %", ""))   # no number without a record
    t1 = new.split("<!-- table:table1 -->")[1]
    assert "Profile `cpu`" in t1 and "| MSE_20 |" in t1
    # every Table 1 number with its interval, and the paired comparisons (the fixture's csv files)
    assert "| MSE_20 | **2.0e-7** [1.8e-7, 2.2e-7] / 7.9e-6 |" in t1
    assert "| SitL / GNS | MSE_20 | 0.087 [0.074, 0.101] | lower |" in t1
    # Fig. 3 (fallback cpu, like Table 1) is embedded from the cpu snapshot, labelled; Fig. 5 from the paper's
    figs = new.split("<!-- table:figures -->")[1]
    assert "(fig3, profile `cpu`)" in figs and "](cpu/fig3/fig3.png)" in figs, figs
    assert "(fig5)" in figs and "](paper/fig5/fig5.png)" in figs, figs
    # the same through `python -m report.readme_tables` (one module instance: a table module's
    # missing source is the placeholder there too, not a traceback)
    r = tmp_path / "README.md"
    r.write_text("<!-- table:fig9 -->\n<!-- /table:fig9 -->\n<!-- table:cavity -->\n<!-- /table:cavity -->\n")
    proc = subprocess.run([sys.executable, "-m", "report.readme_tables", "--snapshot", str(snap), "--readme", str(r)],
                          cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert r.read_text().count("Not in this snapshot yet") == 2


def test_experiment_tables_show_the_records_cells(tmp_path):
    """The cavity, dam-break, heat and gradient tables (report/readme_walls.py, readme_gradients.py)
    show the snapshot's own cells, read here independently with the csv module; a figure missing
    from the snapshot is named, never filled in."""
    import csv

    snap = FIXTURES / "snapshot" / "paper"
    text = "".join(f"<!-- table:{n} -->\n<!-- /table:{n} -->\n" for n in ("cavity", "dambreak", "heat", "gradients"))
    new = readme_tables.regenerate(text, snap, tmp_path / "README.md")
    body = {n: new.split(f"<!-- table:{n} -->")[1].split(f"<!-- /table:{n} -->")[0]
            for n in ("cavity", "dambreak", "heat", "gradients")}

    def rows(rel):
        with (snap / rel).open() as f:
            return list(csv.DictReader(f))

    names = {"sph": "SPH", "tvf": "SPH + TVF", "riemann": "Riemann SPH"}
    for r in rows("fig6/metrics.csv"):
        assert f"| fig6 | {names[r['method']]} | {float(r['dx']):g} | {float(r['u_rms']):.4f} / {float(r['v_rms']):.4f} |" \
            in body["cavity"]
    assert "fig7: not in this snapshot yet" in body["cavity"]
    tall = next(r for r in rows("fig8/metrics.csv") if r["column"] == "tall")
    assert f"| {float(tall['p_arrival_t']):.4g} | {float(tall['ref_p_arrival_t']):.4g} (Buchner) |" in body["dambreak"]
    square = next(r for r in rows("fig8/metrics.csv") if r["column"] == "square")
    assert f"{100 * float(square['front_relerr_max']):.3g} %" in body["dambreak"]
    for r in rows("heat_validation/metrics.csv"):
        assert f"{100 * abs(float(r['decay_rate_relerr'])):.2g} %" in body["heat"]
    tgv64 = next(r for r in rows("fig1/metrics.csv") if r["case"] == "tgv" and r["dtype"] == "float64")
    m, e = f"{float(tgv64['rel_l2']):.1e}".split("e")
    assert f"| {m}e{int(e)} |" in body["gradients"]
    # Fig. 9 and the stability matrix
    more = readme_tables.regenerate("<!-- table:fig9 -->\n<!-- /table:fig9 -->\n<!-- table:stability -->\n"
                                    "<!-- /table:stability -->\n", snap, tmp_path / "README.md")
    for r in rows("fig9/metrics.csv"):
        assert f"| {r['n_side']}³ | {names[r['method']]} | {100 * float(r['e_kin_rms_rel']):.1f} % |" in more, more
    st = rows("stability/stability.csv")
    for r in st:
        assert f"| {r['case']} | {r['method']} | {r['expected']} | {'pass' if r['passed'] == 'True' else 'fail'}" in more
    assert f"{sum(r['as_expected'] == 'True' for r in st)} of {len(st)} cases ended as expected" in more
    # without fig1 / fig2 the gradient table is a placeholder, with no number
    part = tmp_path / "part"
    shutil.copytree(snap / "fig6", part / "fig6")
    gone = readme_tables.regenerate("<!-- table:gradients -->\n<!-- /table:gradients -->\n", part, tmp_path / "R.md")
    assert "Not in this snapshot yet" in gone and not re.search(r"\de-\d", gone)


@pytest.mark.parametrize("readme", readme_tables.READMES)
def test_the_readme_matches_its_snapshot(readme):
    """The README's marked tables are what the committed snapshot gives. Until a snapshot is
    committed, the markers must name tables the generator knows (the fixture test above checks the
    generation itself)."""
    text = (ROOT / readme).read_text()
    snap = ROOT / "docs" / "results" / "paper"
    assert snap.is_dir(), "the paper snapshot is committed (make snapshot)"
    assert readme_tables.regenerate(text, snap, ROOT / readme) == text, "run `make readme-tables`"
    known = set(readme_tables.tables(snap, ROOT / readme, "paper"))
    assert readme_tables.markers(text) and set(readme_tables.markers(text)) <= known
    assert text.count("<!-- table:") == text.count("<!-- /table:")


def test_every_readme_with_generated_tables_is_checked():
    """A README outside READMES would carry marked tables that neither `make readme-tables` nor the
    test above looks at."""
    skip = ("results", "tests", "docs", "node_modules")
    found = {str(p.relative_to(ROOT)) for p in ROOT.rglob("README.md")
             if not p.relative_to(ROOT).parts[0].startswith(".") and p.relative_to(ROOT).parts[0] not in skip
             and "<!-- table:" in p.read_text()}
    assert found <= set(readme_tables.READMES), found - set(readme_tables.READMES)


def test_sitl_study_table_is_the_studys_own_from_the_cpu_snapshot(tmp_path):
    """The study's tables come verbatim from its study.md (title left out), labelled with the
    profile they were taken from when the paper snapshot has none."""
    from report import readme_sitl
    (tmp_path / "paper").mkdir()
    (tmp_path / "cpu" / "sitl_study").mkdir(parents=True)
    (tmp_path / "cpu" / "sitl_study" / "study.md").write_text("# SitL study\n\n| run | MSE_20 |\n|---|---|\n| a | 1e-07 |\n\n")
    lines = readme_sitl.verbatim(tmp_path / "paper", "sitl_study/study.md")
    assert lines[0].startswith("_Profile `cpu` (cpu/sitl_study/study.md") and lines[2:] == ["| run | MSE_20 |", "|---|---|", "| a | 1e-07 |"]
    with pytest.raises(readme_tables.SourceMissing):
        readme_sitl.verbatim(tmp_path / "cpu" / "nothing", "sitl_study/study.md")


# -- make -j2 ----------------------------------------------------------------------------------------
TIMING = {"wall_s", "compile_s", "ms_per_step", "peak_rss_mb", "other_load"}


def test_make_j2_gives_the_serial_outputs(smoke, tmp_path):
    """`make -j2` runs independent run steps at once (Fig. 10's channel and the heat validation's
    sine runs) and gives what the fixture's serial make gave: every metrics and series table equal
    column by column (the timings aside), to round-off."""
    par = tmp_path / "smoke"
    out = make("-j2", "fig10", "PROFILE=smoke", f"RESULTS={par}")
    assert "-j" not in out.stderr  # no jobserver warning (recursive makes share the slots)
    for rel in ("fig10/metrics.csv", "fig10/series.csv", "heat_validation/metrics.csv",
                "thermal/channel_metrics.csv", "thermal/sine_metrics.csv"):
        a, b = pd.read_csv(smoke / rel), pd.read_csv(par / rel)
        assert list(a.columns) == list(b.columns) and len(a) == len(b) > 0, rel
        for c in a.columns:
            if c in TIMING:
                continue
            if pd.api.types.is_numeric_dtype(a[c]):
                assert (a[c].isna() == b[c].isna()).all(), (rel, c)
                pd.testing.assert_series_equal(a[c], b[c], rtol=1e-12, atol=1e-14, obj=f"{rel}:{c}")
            else:
                assert a[c].astype(str).tolist() == b[c].astype(str).tolist(), (rel, c)
    for fig in ("fig10/fig10.png", "heat_validation/heat_validation.png"):
        assert (par / fig).stat().st_size > 10_000


# -- the run-folder lock -----------------------------------------------------------------------------
def test_a_second_writer_waits_for_the_first_and_says_who_holds_the_folder(tmp_path):
    code = ("import sys, time; from lab.lock import folder_lock\n"
            "with folder_lock(sys.argv[1]):\n"
            "    print('start', time.time(), flush=True); time.sleep(float(sys.argv[2])); print('end', time.time(), flush=True)\n")
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    a = subprocess.Popen([sys.executable, "-c", code, str(tmp_path / "run"), "1.5"], stdout=subprocess.PIPE, text=True, env=env)
    time.sleep(0.5)
    b = subprocess.run([sys.executable, "-c", code, str(tmp_path / "run"), "0"], capture_output=True, text=True, env=env,
                       timeout=60)
    out_a = a.communicate(timeout=60)[0]
    end_a = float(re.search(r"end (\S+)", out_a).group(1))
    start_b = float(re.search(r"start (\S+)", b.stdout).group(1))
    assert start_b >= end_a
    assert f"pid {a.pid}" in b.stdout and "waiting" in b.stdout
    assert (tmp_path / "run" / ".run.lock").exists()
