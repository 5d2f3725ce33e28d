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


def reference_text(values: dict, key) -> str:
    """The description of a reference (a key of `references`, or free text as written)."""
    if not key:
        return ""
    return values.get("references", {}).get(key, key)
