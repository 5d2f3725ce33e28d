"""Deliverables (figures, metrics tables, the atlas, the stability table) verified on every `make`.

    python -m lab.deliver OUTPUT ... --from INPUT ... -- COMMAND ...

Every deliverable rule of the Makefile runs its plot or table script through this (the rule is
FORCE'd, so the check happens on every `make`). A deliverable is a function of exactly its inputs:
the run stamps it depends on (each a manifest of the current runs, `lab.stamp`), its scripts,
and every file the script read that it declared (`note_input`: `tables.read_table`,
`io.read_trajectory`, the atlas's run records). After COMMAND succeeds, a manifest is written beside
the first OUTPUT (``.<name>.made.json``): the command, the digest of every input and of every OUTPUT.
On the next `make` COMMAND runs again only when

  - there is no manifest (never made here, or the last attempt failed or was interrupted),
  - the command or an input differs (a run added, removed or re-run; a method or dx removed from the
    profile changes the run stamp; an edited script), or
  - an OUTPUT is missing or differs from what was made (a truncated metrics.csv, an edited figure),

and prints one line saying which; otherwise one line "up to date". So a deliverable always shows
exactly the current runs, and a damaged one is made again.
"""
import json
import os
import sys
import tempfile
from pathlib import Path
from typing import Optional

from .stamp import file_digest, run_command
from .atomic import write_text

ENV = "SPH_DELIVERABLE_INPUTS"
"""The file a deliverable's script appends the inputs it read to (set by `main`)."""


def note_input(*paths) -> None:
    """Declare files a deliverable was made from (no-op outside `python -m lab.deliver`):
    their digests, taken now, go into its manifest and are compared on the next `make`."""
    target = os.environ.get(ENV)
    if not target:
        return
    with open(target, "a") as f:
        for p in paths:
            f.write(json.dumps([str(Path(p).resolve()), file_digest(p)]) + "\n")


def manifest_path(outputs) -> Path:
    first = Path(outputs[0])
    return first.with_name(f".{first.name}.made.json")


def read_manifest(outputs) -> Optional[dict]:
    try:
        m = json.loads(manifest_path(outputs).read_text())
    except (OSError, ValueError):
        return None
    return m if isinstance(m, dict) and {"command", "inputs", "outputs"} <= set(m) else None


def _show(p) -> str:
    """`p` relative to the working folder when inside it, else as it is."""
    rel = os.path.relpath(p)
    return str(p) if rel.startswith("..") else rel


def _digests(paths) -> dict:
    return {str(Path(p).resolve()): file_digest(p) for p in paths}


def why_remake(outputs, inputs, command) -> Optional[str]:
    """Why the deliverable `outputs` must be made again (one phrase), or None when it is current."""
    m = read_manifest(outputs)
    if m is None:
        return f"no record of how it was made ({manifest_path(outputs).name})"
    if m["command"] != list(command):
        return "its command changed"
    recorded = m["inputs"]
    for p, d in _digests(inputs).items():
        if recorded.get(p) != d:
            return f"{_show(p)} changed" if p in recorded else f"new input {_show(p)}"
    for p, d in recorded.items():
        if file_digest(p) != d:
            return f"{_show(p)} changed since it was made" if Path(p).exists() \
                else f"{_show(p)} is gone"
    for p in outputs:
        d = m["outputs"].get(str(Path(p).resolve()))
        now = file_digest(p)
        if now == "absent":
            return f"{p} is missing"
        if d != now:
            return f"{p} differs from what was made (damaged or edited)"
    return None


def make(outputs, inputs, command) -> int:
    """Run `command` when the deliverable is not current (see the module docstring); its exit code."""
    outputs, inputs = list(outputs), list(inputs)
    label = ", ".join(Path(p).name for p in outputs[:3]) + (", ..." if len(outputs) > 3 else "")
    why = why_remake(outputs, inputs, command)
    if why is None:
        print(f"{Path(outputs[0]).parent}/{{{label}}}: up to date with its runs", flush=True)
        return 0
    print(f"{Path(outputs[0]).parent}/{{{label}}}: making: {why}", flush=True)
    before = _digests(inputs)
    manifest_path(outputs).unlink(missing_ok=True)  # a failed or interrupted attempt leaves no record
    with tempfile.NamedTemporaryFile("r", prefix="sph-inputs-", suffix=".txt") as noted:
        rc = run_command(command, {ENV: noted.name})
        if rc != 0:
            return rc
        read = dict(json.loads(line) for line in noted.read().splitlines() if line.strip())
    missing = [p for p in outputs if not Path(p).is_file()]
    if missing:
        print(f"error: {missing[0]}: not written by {' '.join(command[:2])}", file=sys.stderr, flush=True)
        return 1
    record = {"command": list(command), "inputs": {**read, **before}, "outputs": _digests(outputs)}
    path = manifest_path(outputs)
    write_text(path, json.dumps(record, indent=1, sort_keys=True) + "\n")
    return 0


def main(argv=None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    usage = "usage: python -m lab.deliver OUTPUT ... --from INPUT ... -- COMMAND ..."
    if "--" not in argv or "--from" not in argv[:argv.index("--")]:
        print(usage, file=sys.stderr)
        return 2
    sep, frm = argv.index("--"), argv.index("--from")
    outputs, inputs, command = argv[:frm], argv[frm + 1:sep], argv[sep + 1:]
    if not outputs or not command:
        print(usage, file=sys.stderr)
        return 2
    return make(outputs, inputs, command)


if __name__ == "__main__":
    sys.exit(main())
