"""README table of the 3D Taylor-Green vortex (Fig. 9), generated from the snapshot's
fig9/metrics.csv by `make readme-tables` (report/readme_tables.py registers it): per resolution
and method, E_kin against JAX-Fluids (RMS relative deviation, and at the end), -dE/dt against it
(RMS deviation relative to the reference peak), the dissipation peak and the cost. Every number is
a cell of that file."""
from pathlib import Path

import pandas as pd

from lab.other_load import cell

from .readme_cells import METHODS, find_source, duration


def _pct(v) -> str:
    return "-" if pd.isna(v) else f"{100 * float(v):+.1f} %"


def fig9(snapshot: Path) -> list:
    t = pd.read_csv(find_source(snapshot, "fig9/metrics.csv"))
    order = {m: i for i, m in enumerate(METHODS)}
    t = t.assign(_m=t["method"].map(order).fillna(99)).sort_values(["n_side", "_m"])
    lines = ["| particles | method | E_kin RMS rel. deviation | E_kin at the end | -dE/dt RMS dev. / ref. peak | "
             "-dE/dt peak: t, height | ms per step | wall | other work meanwhile [cores] |",
             "|---|---|---|---|---|---|---|---|---|"]
    for _, r in t.iterrows():
        lines.append(f"| {int(r['n_side'])}³ | {METHODS.get(r['method'], r['method'])} | "
                     f"{100 * float(r['e_kin_rms_rel']):.1f} % | {_pct(r['e_kin_end_relerr'])} (t = {r['t_end']:.3g}) | "
                     f"{100 * float(r['dissipation_rms_rel']):.1f} % | {r['peak_t']:.3g}, {r['peak_dissipation']:.3g} | "
                     f"{float(r['ms_per_step']):.3g} | {duration(r['wall_s'])} | {cell(r.get('other_load'))} |")
    ref = t.iloc[0]
    return lines + ["", f"Reference (JAX-Fluids): dissipation peak {ref['ref_peak_dissipation']:.4g} at "
                        f"t = {ref['ref_peak_t']:.3g}. Other work meanwhile: the cores other processes kept busy "
                        "while the run was timed (a resumed run: its last session; not measured: made before "
                        "it was recorded)."]
