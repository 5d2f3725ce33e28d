"""A headline number beside the paper's value, its reference, tolerance and verdict.

`evaluate(name, cid, check, results)` reads the number (a `Trace` into results/<profile>/) and the
paper's value and tolerance (traces into docs/paper_values.yaml) and judges it:

  max: x      value <= x                 min: x     value >= x
  abs: x      |value - paper| <= x       factor: f  paper / f <= value <= paper * f
  below_paper value <= paper

No tolerance, or no value (the run or its row is missing): not judged (passed is None)."""
from dataclasses import dataclass
from pathlib import Path
from typing import Optional

from . import paper
from .trace import Trace, safe_value

KINDS = ("max", "min", "abs", "factor", "below_paper")


@dataclass
class CheckResult:
    cid: str
    label: str
    unit: str
    value: Optional[float]
    value_trace: Trace
    paper: Optional[float]
    paper_trace: Optional[Trace]
    source_kind: str             # docs/paper_values.yaml source.kind of the compared value ('' without one)
    source_locator: str
    reference: str
    tol_kind: Optional[str]
    tol: Optional[float]
    tol_trace: Optional[Trace]
    tol_why: str
    passed: Optional[bool]
    group: Optional[str] = None  # a key of the target's `groups`; None: a headline check

    @property
    def is_paper(self) -> bool:
        """The compared value is the paper's own (its text or a figure read off), not a reference's."""
        return self.source_kind in paper.PAPER_KINDS

    @property
    def source_label(self) -> str:
        """'authors' code: tumaer/jax-sph ...' for the report's source column ('' without a value)."""
        if not self.source_kind:
            return ""
        return f"{paper.KIND_LABELS.get(self.source_kind, self.source_kind)}: {self.source_locator}"


def yaml_trace(target: str, cid: str, key: str, values_path=paper.PAPER_VALUES) -> Trace:
    return Trace(file=Path(values_path).resolve(), column=f"targets.{target}.checks.{cid}.{key}")


def judge(value, paper_value, kind, tol) -> Optional[bool]:
    if value is None or kind is None:
        return None
    if kind == "max":
        return value <= tol
    if kind == "min":
        return value >= tol
    if paper_value is None:
        return None
    if kind == "abs":
        return abs(value - paper_value) <= tol
    if kind == "factor":
        return paper_value / tol <= value <= paper_value * tol
    if kind == "below_paper":
        return value <= paper_value
    raise ValueError(f"unknown tolerance kind {kind!r} (one of {KINDS})")


def evaluate(target: str, cid: str, check: dict, results, values: dict, values_path=paper.PAPER_VALUES) -> CheckResult:
    results = Path(results)
    vt = Trace(file=(results / check["file"]).resolve(), column=check["column"], where=dict(check.get("where") or {}),
               absolute=bool(check.get("absolute")), scale=float(check.get("scale", 1.0)))
    value = safe_value(vt)
    p = check.get("paper")
    src = check.get("source") or {}
    pt = yaml_trace(target, cid, "paper", values_path) if p is not None else None
    tol = dict(check.get("tolerance") or {})
    why = tol.pop("why", "")
    kind = next((k for k in KINDS if k in tol), None)
    tv = None if kind in (None, "below_paper") else float(tol[kind])
    tt = yaml_trace(target, cid, f"tolerance.{kind}", values_path) if tv is not None else None
    return CheckResult(cid=cid, label=check["label"], unit=check.get("unit", ""), value=value, value_trace=vt,
                       paper=float(p) if p is not None else None, paper_trace=pt,
                       source_kind=str(src.get("kind", "")) if p is not None else "",
                       source_locator=str(src.get("locator", "")) if p is not None else "",
                       reference=paper.reference_text(values, check.get("reference")),
                       tol_kind=kind, tol=tv, tol_trace=tt, tol_why=why,
                       passed=judge(value, float(p) if p is not None else None, kind, tv), group=check.get("group"))
