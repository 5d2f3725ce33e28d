"""Fig. 3's MSE-against-step table (experiments/sitl/plot_fig3.mse_table): a window that diverged is counted, not
averaged (its inf would make the mean inf), and the statistics are those of the finite windows."""
import math

from experiments.sitl.plot_fig3 import mse_table


def test_diverged_windows_are_counted_not_averaged():
    inf = math.inf
    records = {"gns": {"mse_steps": [[1.0, 2.0, inf, inf, inf], [3.0, 4.0, 5.0, 6.0, 7.0]]},
               "bad": {"mse_steps": [[inf] * 5, [math.nan] * 5]}}
    rows = {(r["model"], r["step"]): r for r in mse_table(records)}
    assert set(k for m, k in rows if m == "gns") == {1, 5}          # the table steps within the rollout
    first, last = rows[("gns", 1)], rows[("gns", 5)]
    assert (first["mean"], first["min"], first["max"], first["diverged"]) == (2.0, 1.0, 3.0, 0)
    assert (last["mean"], last["min"], last["max"], last["diverged"], last["n_windows"]) == (7.0, 7.0, 7.0, 1, 2)
    gone = rows[("bad", 5)]
    assert math.isnan(gone["mean"]) and gone["diverged"] == 2
