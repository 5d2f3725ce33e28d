"""docs/paper_values.yaml: for each paper target its title, README, figures, timing source and
headline checks (the paper's value, the reference data, the tolerance), in one data file.

`load()` returns the parsed file; `targets()` the targets in the order of the file, which is the
order of the report and of `make all` (dependency order: Fig. 4 and 5 share runs, Table 1 before
Fig. 3, the atlas last, since it gathers every other run's record)."""
from pathlib import Path

import yaml

ROOT = Path(__file__).resolve().parents[1]
PAPER_VALUES = ROOT / "docs" / "paper_values.yaml"

PAPER_TARGETS = ("fig1", "fig2", "fig4", "fig5", "fig6", "fig7", "fig8", "fig9", "fig10", "table1", "fig3")
"""The paper's figures and table, in the order `make all` builds them."""
ALL_TARGETS = PAPER_TARGETS + ("stability", "accuracy")
"""`make all`: the paper targets, the stability matrix and the atlas (last: it gathers the records)."""


def load(path=PAPER_VALUES) -> dict:
    return yaml.safe_load(Path(path).read_text())


def targets(values: dict = None) -> dict:
    """name -> target entry, in ALL_TARGETS order (every name of ALL_TARGETS must be in the file)."""
    values = values or load()
    t = values["targets"]
    missing = [n for n in ALL_TARGETS if n not in t]
    if missing:
        raise KeyError(f"{PAPER_VALUES}: no entry for {', '.join(missing)}")
    return {n: t[n] for n in ALL_TARGETS}


KINDS = ("paper_text", "paper_figure_readoff", "authors_code", "lagrangebench", "literature")
"""Where a compared value is published (docs/paper_values.yaml `source.kind`)."""
PAPER_KINDS = ("paper_text", "paper_figure_readoff")
"""The kinds that are the paper's own: a value of another kind is shown as a "reference", not "paper"."""
REFERENCE_KINDS = KINDS + ("computed",)
"""A reference may also be computed by this reproduction (the analytical decay, finite differences)."""
KIND_LABELS = {"paper_text": "paper", "paper_figure_readoff": "paper, read off its figure",
               "authors_code": "authors' code", "lagrangebench": "LagrangeBench", "literature": "literature",
               "computed": "computed here"}


def reference_text(values: dict, key) -> str:
    """The description of a reference (a key of `references`, or free text as written)."""
    if not key:
        return ""
    ref = values.get("references", {}).get(key, key)
    return ref.get("text", key) if isinstance(ref, dict) else ref


def problems(values: dict) -> list:
    """What the file lacks for a reader to open every source: each value compared with (a check's
    `paper`) needs `source: {kind, locator}` with a kind of KINDS, each reference a kind of
    REFERENCE_KINDS and a locator, each target's `paper` block a locator. [] when complete."""
    out = []

    def need(where, d, kinds):
        if not isinstance(d, dict):
            out.append(f"{where}: no source (kind and locator)")
            return
        if d.get("kind") not in kinds:
            out.append(f"{where}: kind {d.get('kind')!r} is not one of {', '.join(kinds)}")
        if not str(d.get("locator") or "").strip():
            out.append(f"{where}: no locator")

    for key, ref in (values.get("references") or {}).items():
        need(f"references.{key}", ref, REFERENCE_KINDS)
        if isinstance(ref, dict) and not ref.get("text"):
            out.append(f"references.{key}: no text")
    for name, t in (values.get("targets") or {}).items():
        need(f"targets.{name}.paper", t.get("paper"), KINDS if not t.get("beyond_paper") else ("none",))
        groups = t.get("groups") or {}
        for cid, c in (t.get("checks") or {}).items():
            where = f"targets.{name}.checks.{cid}"
            if "paper_where" in c:
                out.append(f"{where}: paper_where (use source: {{kind, locator}})")
            if c.get("paper") is not None:
                need(f"{where}.source", c.get("source"), KINDS)
            elif "source" in c:
                out.append(f"{where}: a source but no value (paper)")
            if c.get("group") is not None and c["group"] not in groups:
                out.append(f"{where}: group {c['group']!r} is not in targets.{name}.groups")
            ref = c.get("reference")
            if ref and ref not in (values.get("references") or {}):
                out.append(f"{where}: reference {ref!r} is not a key of references")
    return out
