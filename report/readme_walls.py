"""README tables of the wall, free-surface and heat experiments (Figs. 6-8, 10), generated from the
snapshot's metrics tables by `make readme-tables` (report/readme_tables.py registers them):

    cavity    Figs. 6 / 7: RMS deviation of the centreline profiles from Ghia et al. (1982)
              (fig6/metrics.csv, fig7/metrics.csv; a figure not in the snapshot yet is named)
    dambreak  Fig. 8: sensor pressure against Buchner (2002), surge front and residual height of
              the square column against Martin & Moyce (1952) (fig8/metrics.csv)
    heat      Fig. 10 and heat-validation: decay rate of a sine temperature against the exact one,
              bounds, bulk velocity and Nusselt number of the heated channel

Every number is a cell of those files; nothing is typed by hand."""
from pathlib import Path

import pandas as pd

from .readme_cells import METHODS, SourceMissing, find_source, duration, pct, sig


def cavity(snapshot: Path) -> list:
    figs = {}
    for fig in ("fig6", "fig7"):
        try:
            figs[fig] = pd.read_csv(find_source(snapshot, f"{fig}/metrics.csv"))
        except SourceMissing:
            pass
    if not figs:
        raise SourceMissing("fig6/metrics.csv and fig7/metrics.csv are not in the snapshot")
    order = {m: i for i, m in enumerate(METHODS)}
    lines = ["| figure | method | dx | RMS deviation from Ghia, u / v | fluid-only interpolation, u / v | "
             "max density error | wall | ms per step |", "|---|---|---|---|---|---|---|---|"]
    for fig, t in figs.items():
        t = t.assign(_m=t["method"].map(order).fillna(99)).sort_values(["dx", "_m"], ascending=[False, True])
        for _, r in t.iterrows():
            lines.append(f"| {fig} | {METHODS.get(r['method'], r['method'])} | {r['dx']:g} | "
                         f"{r['u_rms']:.4f} / {r['v_rms']:.4f} | {r['u_rms_fluid']:.4f} / {r['v_rms_fluid']:.4f} | "
                         f"{pct(r['density_error_max'], 2)} | {duration(r['wall_s'])} | {sig(r['ms_per_step'])} |")
    missing = [f for f in ("fig6", "fig7") if f not in figs]
    if missing:
        lines += ["", f"_{', '.join(missing)}: not in this snapshot yet._"]
    return lines


def dambreak(snapshot: Path) -> list:
    t = pd.read_csv(find_source(snapshot, "fig8/metrics.csv")).set_index("column")
    tall, square = t.loc["tall"], (t.loc["square"] if "square" in t.index else None)
    lines = ["| quantity | here | reference |", "|---|---|---|",
             f"| pressure arrival at the downstream sensor, t sqrt(g/H) | {sig(tall['p_arrival_t'], 4)} | "
             f"{sig(tall['ref_p_arrival_t'], 4)} (Buchner) |",
             f"| first pressure peak, p / (rho g H) (smoothed) | {sig(tall['p_peak_smooth'])} at "
             f"{sig(tall['p_peak_t_smooth'])} | {sig(tall['ref_p_peak'])} at {sig(tall['ref_p_peak_t'])} (Buchner) |",
             f"| max density error / fluid particles that left the tank | {pct(tall['density_error_max'], 2)} / "
             f"{int(tall['n_left_tank'])} | - |"]
    if square is not None:
        lines += [f"| square column: surge front, max / mean \\|x / x_MM - 1\\| for t sqrt(g/H) <= 2.5 | "
                  f"{pct(square['front_relerr_max'])} / {pct(square['front_relerr_mean'])} | Martin & Moyce |",
                  f"| square column: residual height at the back wall, max \\|h - h_MM\\| / H | "
                  f"{sig(square['height_abserr_max'], 2)} | Martin & Moyce |"]
    walls = ", ".join(f"{c} {duration(r['wall_s'])} ({sig(r['ms_per_step'])} ms per step)" for c, r in t.iterrows())
    return lines + ["", f"Riemann SPH, dx {tall['dx']:g}, to t sqrt(g/H) = {tall['t_end']:.3g}; wall time: {walls}."]


def heat(snapshot: Path) -> list:
    v = pd.read_csv(find_source(snapshot, "heat_validation/metrics.csv")).sort_values("dx", ascending=False)
    lines = ["| heat operator: dx | " + " | ".join(f"{d:g}" for d in v["dx"]) + " |",
             "|---|" + "---|" * len(v),
             "| decay rate of a sine temperature against the exact one | "
             + " | ".join(pct(abs(e), 2) for e in v["decay_rate_relerr"]) + " |"]
    try:
        c = pd.read_csv(find_source(snapshot, "fig10/metrics.csv")).iloc[0]
    except SourceMissing:
        return lines + ["", "_fig10: not in this snapshot yet._"]
    return lines + ["", f"Heated channel (Fig. 10, dx {c['dx']:g}, to t = {c['t_end']:.3g}): fluid temperature within "
                        f"[{sig(c['T_fluid_min'])}, {sig(c['T_fluid_max'])}] (wall values [{sig(c['T_all_min'])}, "
                        f"{sig(c['T_all_max'])}]), bulk velocity {pct(abs(c['u_bulk_relerr_end']), 2)} from the laminar "
                        f"value, Nusselt number {sig(c['Nu_hot_end'])} at the heated segment, "
                        f"{_density(snapshot, c)}."]


def _density(snapshot: Path, c) -> str:
    """The channel's density error: at the start (its lattice), at most afterwards, at the end."""
    try:
        e = pd.read_csv(find_source(snapshot, "fig10/series.csv"))["density_error"]
    except (SourceMissing, KeyError):
        return f"density error at most {pct(c['density_error_max'], 2)}, {pct(c['density_error_end'], 2)} at the end"
    return (f"density error {pct(e.iloc[0], 2)} in the starting lattice, at most {pct(e.iloc[1:].max(), 2)} "
            f"after it, {pct(c['density_error_end'], 2)} at the end")
