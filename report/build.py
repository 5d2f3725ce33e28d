"""`make report [PROFILE=...]`: results/<profile>/report/index.html and report.md.

    python -m report.build --profile smoke [--results results/smoke] [--out DIR] [--compress]

Reads only what the targets wrote (metrics csv, run records, figures) and docs/paper_values.yaml;
runs nothing. Figures are copied beside the page (./figures/; --compress: downscaled palette PNGs);
provenance.json records where the numbers were made (a snapshot's own one is kept)."""
import argparse
import json
import os
import shutil
import sys
from pathlib import Path

from . import figures, html, markdown, model, paper, provenance


def write(rep: model.Report, out_dir, compress: bool = False, copy_figures: bool = True) -> Path:
    """index.html, report.md and provenance.json into `out_dir`; the figures copied into
    out_dir/figures/ (compressed with `compress`), or, with copy_figures=False (a snapshot, whose
    figures are already small), linked where they are."""
    out_dir = Path(out_dir).resolve()
    if (out_dir / "figures").exists():
        shutil.rmtree(out_dir / "figures")
    out_dir.mkdir(parents=True, exist_ok=True)
    links = {str(f): figures.place(f, out_dir, t.name, compress) if copy_figures else os.path.relpath(f, out_dir)
             for t in rep.targets for f in t.figures}
    (out_dir / "index.html").write_text(html.render(rep, out_dir, links))
    (out_dir / "report.md").write_text(markdown.render(rep, out_dir, links))
    (out_dir / provenance.FILE).write_text(json.dumps(rep.provenance, indent=2) + "\n")
    return out_dir / "index.html"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--profile", default="paper")
    ap.add_argument("--results", default=None, help="default: results/<profile>")
    ap.add_argument("--out", default=None, help="default: <results>/report")
    ap.add_argument("--values", default=str(paper.PAPER_VALUES))
    ap.add_argument("--compress", action="store_true")
    a = ap.parse_args(argv)
    results = Path(a.results or f"results/{a.profile}")
    rep = model.build(results, a.profile, a.values)
    page = write(rep, a.out or results / "report", a.compress)
    counts = {}
    for t in rep.targets:
        counts[t.verdict] = counts.get(t.verdict, 0) + 1
    print(f"report -> {page} ({', '.join(f'{n} {v}' for v, n in counts.items())})", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
