"""Heat-operator validation: amplitude of T = T0 + A sin(k x) in the periodic unit square at rest
against the analytical decay exp(-alpha k^2 t), for every dx of the profile, and the decay-rate
error against dx.

Reads the current sine runs and sine_metrics.csv (lab.experiment: refused, naming them, when a run
is missing or stale); writes <out>/heat_validation.{png,pdf} and metrics.csv (the rows of the
profile's spacings; make: results/<profile>/heat_validation/). Exits with status 1 (after writing)
when the `report_dx` run misses `target_relerr`.

    python experiments/thermal/plot_heat_validation.py --profile smoke [--results results/smoke] [--out DIR]
"""
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from lab.experiment import plot_main  # noqa: E402
from lab.figures import save_figure  # noqa: E402


def plot(exp, out):
    """Write the figure and metrics; exit with status 1 (after writing) when `report_dx` misses its target."""
    row = validation(exp, out)
    if not row["meets_target"]:
        sys.exit(1)
    return out / "heat_validation.png"


def validation(exp, out) -> dict:
    """Write the figure and metrics; return the metrics row of `report_dx`."""
    d = exp.settings.diffusion
    sines = [r for r in exp.runs if r.kind == "sine"]
    table = exp.table(sines)
    table = table[[any(np.isclose(x, dx) for dx in d.dx) for x in table["dx"]]].reset_index(drop=True)
    table.to_csv(out / "metrics.csv", index=False)

    fig, (ax_a, ax_e) = plt.subplots(1, 2, figsize=(10.0, 4.0), constrained_layout=True)
    for i, run in enumerate(sorted(sines, key=lambda r: r.dx)):
        s, dx = exp.study.sine_series(run, exp.trajectory(run)), run.dx
        ax_a.plot(s["time"], 100 * s["relerr"], "o-", ms=3, lw=1, color=f"C{i}", label=f"SPH, dx = {dx:g}")
    ax_a.axhline(0.0, color="k", lw=0.8)
    ax_a.set(xlabel="t", ylabel=r"$A_{SPH}(t)/A_{exact}(t) - 1$ [%]", xlim=(0, d.t_end),
             title=rf"amplitude error, $A_{{exact}} = A_0 e^{{-\alpha k^2 t}}$, $\alpha$ = {d.alpha:.4g}, "
                   rf"$A_{{exact}}(t_{{end}})/A_0$ = {float(d.amplitude_exact(d.t_end) / d.amplitude):.3f}",)
    ax_a.title.set_fontsize(9)
    ax_a.legend(fontsize=8)
    dxs = table["dx"].to_numpy()
    rate = np.abs(table["decay_rate_relerr"].to_numpy())
    amp = np.abs(table["amplitude_relerr_tend"].to_numpy())
    ax_e.loglog(dxs, 100 * rate, "o-", label="decay rate")
    ax_e.loglog(dxs, 100 * amp, "s--", label=f"amplitude at t = {d.t_end:g}")
    if len(dxs) > 1:
        ref = np.array([dxs.min(), dxs.max()])
        ax_e.loglog(ref, 100 * rate.max() * (ref / dxs.max()) ** 2, "k:", lw=1, label=r"$\propto dx^2$")
    for x, e in zip(dxs, table["decay_rate_relerr"].to_numpy()):
        ax_e.annotate(f"{100 * e:+.3f} %", (x, 100 * abs(e)), textcoords="offset points", xytext=(4, -10), fontsize=7)
    ax_e.axhline(100 * d.target_relerr, color="C3", lw=1, label=f"target {100 * d.target_relerr:g} %")
    ax_e.set(xlabel="dx", ylabel="|relative error| [%]",
             title="error vs. resolution (h = dx, quintic; signed rate error annotated)")
    ax_e.title.set_fontsize(9)
    ax_e.legend(fontsize=8)
    for ax in (ax_a, ax_e):
        ax.grid(True, which="both", alpha=0.3)
    fig.suptitle("Heat operator (Cleary 1998) vs. analytical decay of a sine, periodic box at rest")
    save_figure(fig, out, "heat_validation")
    row = table[np.isclose(table["dx"], d.report_dx)].iloc[0].to_dict()
    print(f"dx = {d.report_dx:g}: decay-rate error {100 * row['decay_rate_relerr']:+.3f} %, amplitude error at "
          f"t = {d.t_end:g} {100 * row['amplitude_relerr_tend']:+.3f} % (target {100 * d.target_relerr:g} %): "
          f"{'met' if row['meets_target'] else 'MISSED'}")
    return row


if __name__ == "__main__":
    plot_main(plot, __file__, __doc__)
