"""README tables of the verdicts and of the snapshot's provenance, generated from the committed
snapshot by `make readme-tables` (report/readme_tables.py registers them):

    verdicts    per target of `make all`: the paper's figure / table, the verdict on what it shows
                (each reading of it where there are several, e.g. Fig. 2's two starts) and the
                verdicts of our own checks beyond the paper (report/model.py, as the report gives them)
    provenance  one line: the commit and date the snapshot was made at, whether its tree had
                uncommitted changes, the machine, and the target folders it took from an earlier
                snapshot (its provenance.json, written by `make snapshot`)

Nothing is typed by hand: the verdicts are the report's, the provenance is the snapshot's."""
import json
import os
from collections import Counter
from pathlib import Path

from . import provenance as prov_mod
from .readme_cells import SourceMissing

DIRTY_MARK = "(with uncommitted changes)"


def _report_link(snapshot: Path, readme: Path) -> str:
    page = snapshot / "report" / "report.md"
    return f"[report]({os.path.relpath(page, readme.parent)})" if page.exists() else "report"


def verdicts(snapshot: Path, readme: Path, profile: str) -> list:
    from . import model
    from .markdown import cell, verdict_cells

    if not (Path(snapshot) / "provenance.json").exists():
        raise SourceMissing(f"provenance.json is not in the {Path(snapshot).name} snapshot")
    rep = model.build(snapshot, profile)
    lines = ["| target | paper | verdict on what it shows | beyond the paper (our own checks) |",
             "|---|---|---|---|"]
    for t in rep.targets:
        v, beyond = verdict_cells(t)
        prof = f" (profile `{t.profile}`)" if t.fallback else ""
        lines.append(f"| {t.name}{prof} | {cell(t.paper_where)} | {cell(v)} | {cell(beyond)} |")
    return lines + ["", "reproduced: every judged number within its tolerance; differs: one outside (the reason is "
                        "in the report); figure only: the paper's figure carries no number to compare with. "
                        f"Numbers, sources and reasons: the snapshot's {_report_link(Path(snapshot), readme)}."]


def _short(commit: str) -> tuple:
    """('aaf16db', dirty) from provenance's 'aaf16db6... (with uncommitted changes)'."""
    sha = (commit or "unknown").split()[0]
    return sha[:7], DIRTY_MARK in (commit or "")


def provenance(snapshot: Path) -> list:
    f = Path(snapshot) / "provenance.json"
    if not f.exists():
        raise SourceMissing(f"provenance.json is not in the {Path(snapshot).name} snapshot")
    p = json.loads(f.read_text())
    sha, dirty = _short(p.get("snapshot_commit") or p.get("commit"))
    dirty = dirty or bool(p.get("dirty_tree"))
    text = (f"Snapshot `{Path(snapshot).name}`: made at commit `{sha}` on {p.get('snapshot_date') or p.get('date')}"
            + (", from a working tree with uncommitted changes (its files are not exactly that commit's)" if dirty else "")
            + f"; report made on {p.get('cpu', 'an unrecorded CPU')}, GPU: {p.get('gpu', 'unrecorded')}.")
    origins = prov_mod.parse_restored(p.get("restored from snapshot"))
    if origins:
        groups = Counter((o["commit"], o["date"]) for o in origins.values())
        n_part = sum("part" in o for o in origins.values())
        parts = []
        for (commit, date), k in groups.items():
            osha, odirty = _short(commit)
            parts.append((f"{k} from " if len(groups) > 1 else "") + f"commit `{osha}`"
                         + (", uncommitted changes" if odirty else "") + (f", {date}" if date else ""))
        text += (f" {len(origins)} of its target folders were restored from "
                 + ("an earlier snapshot" if len(groups) == 1 else "earlier snapshots")
                 + f" ({'; '.join(parts)}) and not run again"
                 + (f", {n_part} of them only in part (their other files made for this snapshot)" if n_part else "")
                 + ".")
    return [text]
