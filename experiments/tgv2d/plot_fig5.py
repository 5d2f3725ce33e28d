"""Fig. 5: maximum velocity u_max(t) and kinetic energy E_kin(t) of the 2D Taylor-Green vortex for
every method and dx of the profile, against the analytical decay (log scale).

Reads results/<profile>/tgv2d/*/traj.h5 and metrics.csv; writes results/<profile>/fig5/fig5.{png,pdf}
and results/<profile>/fig5/metrics.csv (a copy of the run metrics).

    python experiments/tgv2d/plot_fig5.py --profile smoke [--results results/smoke]
"""
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from sph.harness import io, tables  # noqa: E402
from sph.cases import tgv  # noqa: E402
try:  # noqa: E402
    from . import settings as S
except ImportError:  # run as a script: its folder comes first on the import path (a copied folder works unchanged)
    import settings as S

COLORS = {"sph": "tab:blue", "tvf": "tab:orange", "riemann": "tab:green"}
LABELS = {"sph": "SPH", "tvf": "TVF", "riemann": "Riemann"}
STYLES = ["-", "--", ":", "-."]


def plot(exp: "S.Experiment", results, out=None) -> Path:
    out = Path(out) if out is not None else Path(results) / "fig5"
    out.mkdir(parents=True, exist_ok=True)
    fig, (ax_u, ax_e) = plt.subplots(1, 2, figsize=(10.0, 4.0), constrained_layout=True)
    t = np.linspace(0.0, exp.t_end, 200)
    ax_u.plot(t, tgv.u_max_exact(t, exp.re), "k", lw=3, alpha=0.25, label="analytical")
    ax_e.plot(t, tgv.e_kin_exact(t, exp.re), "k", lw=3, alpha=0.25, label="analytical")
    dxs = sorted(exp.dx)  # finest first: solid lines
    for i, m in enumerate(exp.methods):
        color = COLORS.get(m.name, f"C{i + 3}")
        for j, dx in enumerate(dxs):
            tr = io.read_trajectory(S.run_dir(results, m.name, dx) / "traj.h5")
            label = f"{LABELS.get(m.name, m.name)}, dx = {dx:g}"
            style = dict(color=color, ls=STYLES[j % len(STYLES)], lw=1.4)
            ax_u.plot(tr["time"], tr["u_max"], label=label, **style)
            ax_e.plot(tr["time"], tr["e_kin"], label=label, **style)
    ax_u.set(yscale="log", xlabel="t", ylabel=r"$u_{max}$", xlim=(0, exp.t_end),
             title=r"max. velocity, exact $e^{-8\pi^2 t/Re}$")
    ax_e.set(yscale="log", xlabel="t", ylabel=r"$E_{kin}$", xlim=(0, exp.t_end),
             title=r"kinetic energy, exact $0.25\,e^{-16\pi^2 t/Re}$")
    ax_e.legend(fontsize=8, ncol=1)
    for ax in (ax_u, ax_e):
        ax.grid(True, which="both", alpha=0.3)
    fig.suptitle(f"2D Taylor-Green vortex, Re = {exp.re:g}")
    for ext in ("png", "pdf"):
        fig.savefig(out / f"fig5.{ext}", dpi=150)
    plt.close(fig)
    table = tables.read_table(S.metrics_path(results))  # an error naming the file when it is damaged
    if len(table) != len(exp.methods) * len(exp.dx):
        raise RuntimeError(f"{S.metrics_path(results)}: {len(table)} rows for {len(exp.methods) * len(exp.dx)} runs "
                           "of the config; re-run experiments/tgv2d/run.py (it rebuilds the table)")
    table.to_csv(out / "metrics.csv", index=False)
    print(f"fig5 -> {out / 'fig5.png'}, {out / 'metrics.csv'}")
    return out / "fig5.png"


def options(ap):
    ap.add_argument("--out", default=None, help="figure folder (default <results>/fig5)")


def main(args):
    plot(S.load(args.profile), args.results, args.out)


if __name__ == "__main__":
    from sph.harness.cli import profile_main

    profile_main(main, __doc__, options)
