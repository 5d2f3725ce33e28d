"""Fig. 9: kinetic-energy dissipation rate -dE/dt(t) (left) and kinetic energy E_kin(t) (right) of the
3D Taylor-Green vortex at Re = 100, every method and resolution of the profile, against the
JAX-Fluids reference (open circles), log scale as in the paper.

Reads results/<profile>/tgv3d/*/traj.h5 (the per-frame series only) and metrics.csv; writes
results/<profile>/fig9/fig9.{png,pdf} and results/<profile>/fig9/metrics.csv (a copy of the run metrics).

    python experiments/tgv3d/plot_fig9.py --profile smoke [--results results/smoke]
"""
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from sph.harness import tables  # noqa: E402
try:  # noqa: E402
    from . import analysis, settings as S
except ImportError:  # run as a script: its folder comes first on the import path (a copied folder works unchanged)
    import analysis
    import settings as S

COLORS = {"sph": "tab:blue", "tvf": "tab:orange", "riemann": "tab:green"}
LABELS = {"sph": "SPH", "tvf": "TVF", "riemann": "Riemann"}
STYLES = ["-", "--", "-.", ":"]


def plot(exp: "S.Experiment", results, out=None) -> Path:
    out = Path(out) if out is not None else Path(results) / "fig9"
    out.mkdir(parents=True, exist_ok=True)
    ref = analysis.load_reference(exp)
    fig, (ax_d, ax_e) = plt.subplots(1, 2, figsize=(10.0, 4.2), constrained_layout=True)
    shown = ref["t"] <= exp.t_end * (1 + 1e-9)
    every = max(1, int(shown.sum()) // 50)
    dots = dict(s=18, facecolors="none", edgecolors="k", lw=0.8, zorder=3, label="JAX-Fluids (reference)")
    ax_d.scatter(ref["t"][shown][::every], ref["dissipation"][shown][::every], **dots)
    ax_e.scatter(ref["t"][shown][::every], ref["e_kin"][shown][::every], **dots)
    ns = sorted(exp.n_side, reverse=True)  # finest first: solid lines
    for i, m in enumerate(exp.methods):
        color = COLORS.get(m.name, f"C{i + 3}")
        for j, n in enumerate(ns):
            s = analysis.energy_series(exp, analysis.read_series(S.run_dir(results, m.name, n) / "traj.h5"))
            label = f"{LABELS.get(m.name, m.name)}, ${n}^3$"
            style = dict(color=color, ls=STYLES[j % len(STYLES)], lw=1.3)
            ax_d.plot(s["t_mid"], s["dissipation"], label=label, **style)
            ax_e.plot(s["t"], s["e_kin"], label=label, **style)
    ax_d.set(yscale="log", xlabel="t", ylabel=r"$-dE_{kin}/dt$", xlim=(0, exp.t_end),
             title=f"dissipation rate (central differences over $\\Delta t$ = {exp.analysis.dissipation_span:g})")
    ax_e.set(yscale="log", xlabel="t", ylabel=r"$E_{kin}$", xlim=(0, exp.t_end),
             title=r"kinetic energy per volume, $\frac{1}{2}\sum m|v|^2 / (\rho (2\pi)^3)$")
    ax_e.legend(fontsize=7, ncol=1)
    for ax in (ax_d, ax_e):
        ax.grid(True, which="both", alpha=0.3)
    fig.suptitle(f"3D Taylor-Green vortex, Re = {exp.re:g} ({exp.start} start)")
    for ext in ("png", "pdf"):
        fig.savefig(out / f"fig9.{ext}", dpi=150)
    plt.close(fig)
    table = tables.read_table(S.metrics_path(results))  # an error naming the file when it is damaged
    if len(table) != len(exp.methods) * len(exp.n_side):
        raise RuntimeError(f"{S.metrics_path(results)}: {len(table)} rows for {len(exp.methods) * len(exp.n_side)} "
                           "runs of the config; re-run experiments/tgv3d/run.py (it rebuilds the table)")
    table.to_csv(out / "metrics.csv", index=False)
    print(f"fig9 -> {out / 'fig9.png'}, {out / 'metrics.csv'}")
    return out / "fig9.png"


def options(ap):
    ap.add_argument("--out", default=None, help="figure folder (default <results>/fig9)")


def main(args):
    plot(S.load(args.profile), args.results, args.out)


if __name__ == "__main__":
    from sph.harness.cli import profile_main

    profile_main(main, __doc__, options)
