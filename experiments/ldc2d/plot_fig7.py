"""Fig. 7: the 2D lid-driven cavity of Fig. 6 at figures.fig7's dx (paper: 0.01), drawn by plot_fig6.py's
`figure` (loaded through the harness, lab.experiment.load_study). Writes <out>/fig7.{png,pdf} and
<out>/metrics.csv (make: results/<profile>/fig7/).

    python experiments/ldc2d/plot_fig7.py --profile smoke [--results results/smoke] [--out DIR]
"""
from pathlib import Path

from lab.experiment import load_study, plot_main

FIG6 = load_study(Path(__file__).parent, "plot_fig6")


def plot(experiment, out):
    return FIG6.figure(experiment, out, "fig7")


if __name__ == "__main__":
    plot_main(plot, __file__, __doc__)
