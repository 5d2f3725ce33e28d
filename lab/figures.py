"""What the plot scripts share: the look of a method's curves, where a figure goes, writing it, copying
its table.

    out = figure_dir(results, "fig5", out)                                # <results>/fig5 by default
    for m, res, label, style in method_lines(exp.methods, resolutions):   # a colour per method,
        ax.plot(t, y, label=f"{label}, dx = {res:g}", lw=1.4, **style)    # a dash per resolution
    png = save_figure(fig, out, "fig5")                                   # fig5.png and fig5.pdf
    copy_metrics(metrics_path, out, n_runs, "python -m lab.experiment experiments/tgv2d")

Only reads finished results and writes figures: number-neutral (lab.keys.NUMBER_NEUTRAL).
"""
from pathlib import Path

from . import tables

METHOD_COLORS = {"sph": "tab:blue", "tvf": "tab:orange", "riemann": "tab:green"}
METHOD_LABELS = {"sph": "SPH", "tvf": "TVF", "riemann": "Riemann"}
LINE_STYLES = ("-", "--", ":", "-.")
"""The dash of the i-th resolution of a figure (cycled), the first one solid."""


def method_lines(methods, resolutions):
    """(method, resolution, label, style) of every curve of a methods x resolutions figure: a colour
    per method (METHOD_COLORS, else C3, C4, ...), a dash per resolution (LINE_STYLES), the label the
    method's (METHOD_LABELS, else its name)."""
    for i, m in enumerate(methods):
        color = METHOD_COLORS.get(m.name, f"C{i + 3}")
        for j, res in enumerate(resolutions):
            yield m, res, METHOD_LABELS.get(m.name, m.name), dict(color=color, ls=LINE_STYLES[j % len(LINE_STYLES)])


def figure_dir(results, name: str, out=None) -> Path:
    """The folder a figure goes to, created: `out`, else <results>/<name>."""
    out = Path(out) if out is not None else Path(results) / name
    out.mkdir(parents=True, exist_ok=True)
    return out


def save_figure(fig, out: Path, name: str, dpi: int = 150, formats=("png", "pdf")) -> Path:
    """Write `fig` as out/<name>.<format> for each of `formats` and close it; returns the first file."""
    import matplotlib.pyplot as plt  # the caller has chosen the backend

    for ext in formats:
        fig.savefig(Path(out) / f"{name}.{ext}", dpi=dpi)
    plt.close(fig)
    return Path(out) / f"{name}.{formats[0]}"


def copy_metrics(path, out: Path, n_runs: int, run_script: str) -> Path:
    """Copy the metrics table `path` beside a figure as out/metrics.csv, once it holds one row per run
    of the config (`n_runs`); a damaged or stale table is an error naming `run_script`, which
    rebuilds it."""
    table = tables.read_table(path)  # an error naming the file when it is damaged
    if len(table) != n_runs:
        raise RuntimeError(f"{path}: {len(table)} rows for {n_runs} runs of the config; re-run {run_script} "
                           "(it rebuilds the table)")
    table.to_csv(Path(out) / "metrics.csv", index=False)
    return Path(out) / "metrics.csv"
