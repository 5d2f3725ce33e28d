"""The accuracy-cost atlas (`make accuracy`, experiments/accuracy): the smoke sweep runs, the four
outputs are written, and what they claim follows from the run records by an independent recount
(Pareto front by brute force, cheapest run per error level, fitted orders of known power laws)."""
import json
import re
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

import sph
from experiments.accuracy import plot_accuracy as A
from experiments.accuracy import study as S
from lab import record
from lab.experiment import Experiment, load_settings

FOLDER = Path(S.__file__).parent


def load(profile, overrides=None):
    """The atlas's settings (the study's Settings through the harness)."""
    return load_settings(FOLDER, profile, overrides)


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    results = tmp_path_factory.mktemp("results")
    exp = Experiment(FOLDER, "smoke", results)
    atlas = exp.settings
    exp.run_all(progress=False)  # the sweep: the study's parts, tgv2d per kernel and dtype
    n = len(exp.runs)
    # a cavity record as its own experiment writes it (lab.record), gathered without re-running
    cav = results / "ldc2d" / "tvf_dx0.02"
    cav.mkdir(parents=True)
    (cav / "record.json").write_text(json.dumps(
        {"experiment": "ldc2d", "target": "fig6", "method": "tvf", "kernel": "quintic", "dx": 0.02, "dim": 2,
         "dtype": "float64", "n_particles": 2500, "n_steps": 100, "wall_s": 12.0, "err_ghia_rms": 0.0066}))
    out = A.build(atlas, results)
    assert out == results / "accuracy"
    return atlas, n, out, pd.read_csv(out / "runs.csv")


def test_sweep_writes_the_four_outputs_and_a_record_per_run(built):
    atlas, n, out, table = built
    sw = atlas.tgv
    assert n == len(sw.methods) * len(sw.dx) * len(sw.dtypes) * len(sw.kernels)
    for name in ("runs.csv", "accuracy.png", "accuracy.pdf", "convergence.png", "accuracy.md"):
        assert (out / name).stat().st_size > 0, name
    import matplotlib.image as mpimg

    h, w = mpimg.imread(out / "accuracy.png").shape[:2]  # the two problems side by side, legend below
    assert w == round(A.ATLAS_WIDTH_IN * 150) and 0.3 * w < h < w
    tgv = table[table["experiment"] == "tgv2d"]
    assert len(tgv) == n
    assert set(record.RECORD_COLUMNS) <= set(table.columns)
    assert np.all(np.isfinite(tgv["err_u_max_mean"])) and np.all(tgv["wall_s"] > 0)
    assert set(tgv["dtype"]) == set(sw.dtypes) and set(tgv["dx"]) == set(sw.dx)
    assert (table["experiment"] == "ldc2d").sum() == 1  # the gathered record
    # every sweep run measured the other work beside it; the hand-made cavity record predates that
    assert np.all(tgv["other_load"] >= 0) and table.query("experiment == 'ldc2d'")["other_load"].isna().all()
    md = (out / "accuracy.md").read_text()
    assert "Timing: timed alone" in md and "not measured: 1 runs" in md and "other work meanwhile [cores]" in md


def test_float32_and_float64_errors_agree(built):
    """Round-off in float32 (1e-7 relative) is far below the discretization error of these runs, so
    the same method at the same dx has the same error in both precisions."""
    tgv = built[3].query("experiment == 'tgv2d'")
    pairs = tgv.pivot_table(index=["method", "dx", "kernel"], columns="dtype", values="err_u_max_mean")
    assert len(pairs) == len(tgv) // 2
    np.testing.assert_allclose(pairs["float32"], pairs["float64"], rtol=1e-2, atol=1e-4)


def test_pareto_front_is_the_non_dominated_set(built):
    atlas, _, _, table = built
    t = A.problem_table(table, atlas, "Taylor-Green 2D")
    front = set(A.pareto(t).index)
    brute = {i for i, r in t.iterrows()
             if not any((o["wall_s"] <= r["wall_s"]) and (o["error"] < r["error"]) or
                        (o["wall_s"] < r["wall_s"]) and (o["error"] <= r["error"]) for j, o in t.iterrows() if j != i)}
    assert front == brute and front


def test_accuracy_md_names_the_cheapest_run_per_level(built):
    atlas, _, out, table = built
    md = (out / "accuracy.md").read_text()
    t = A.problem_table(table, atlas, "Taylor-Green 2D")
    section = md.split("## Taylor-Green 2D")[1].split("## ")[0]
    for lv in atlas.levels:
        row = re.search(rf"^\| {lv:g} \|(.*)$", section, re.M)
        assert row, f"level {lv} missing"
        ok = t[t["error"] <= lv]
        if ok.empty:
            assert row.group(1).strip().startswith("-")
        else:
            best = ok.loc[ok["wall_s"].idxmin()]
            assert f"{best['label']} | {best['dx']:g} |" in row.group(1)
    assert "## lid-driven cavity" in md and "tvf quintic float64" in md.split("## lid-driven cavity")[1]


def test_fitted_order_recovers_a_power_law():
    x = np.array([0.04, 0.02, 0.01])
    assert A.fitted_order(x, 3.0 * x ** 2) == pytest.approx(2.0)
    assert A.fitted_order(1 / x, 0.5 * (1 / x) ** 1.0) == pytest.approx(1.0)
    assert np.isnan(A.fitted_order([0.02, 0.02], [1.0, 2.0]))


def test_checkpointing_section_compares_each_strategy_with_the_plain_gradient(tmp_path):
    """accuracy.md's checkpointing table (from bench_grad_memory.py's csv): one row per measurement,
    the gradient norm against the plain one of the same dtype and length (1 + 3e-13 -> 3.0e-13), '-'
    where the plain gradient did not run (over the memory limit), the other load beside each timing
    ('not measured' where the table has none), and a note when there is no table."""
    csv = tmp_path / "grad_memory.csv"
    pd.DataFrame([
        dict(dtype="float64", steps=100, checkpoint="none", segments=1, run_s=2.0, rss_GB=1.5, est_GB=1.4,
             grad_norm=4.0, status="ok", other_load=0.7),
        dict(dtype="float64", steps=100, checkpoint="segments", segments=10, run_s=3.0, rss_GB=0.2, est_GB=0.2,
             grad_norm=4.0 * (1 + 3e-13), status="ok"),
        dict(dtype="float64", steps=5000, checkpoint="none", segments=1, run_s=np.nan, rss_GB=np.nan, est_GB=278.0,
             grad_norm=np.nan, status="over limit"),
        dict(dtype="float64", steps=5000, checkpoint="nested", segments=71, run_s=186.0, rss_GB=0.19, est_GB=0.2,
             grad_norm=7.0, status="ok"),
    ]).to_csv(csv, index=False)
    rows = [line for line in A.checkpointing_lines(csv) if line.startswith("| float64")]
    assert len(rows) == 4
    cells = [[c.strip() for c in r.strip("|").split("|")] for r in rows]
    assert cells[0][8] == "0.0e+00" and cells[1][8] == "3.0e-13"
    assert cells[3][8] == "-" and cells[3][4] == "186"
    assert cells[0][5] == "0.7" and cells[1][5] == "not measured"  # other work beside the timing, in cores
    assert cells[2][5] == "-"  # not run
    assert any("bench_grad_memory.py" in line for line in A.checkpointing_lines(tmp_path / "missing.csv"))


def test_kernel_entries_with_their_own_smoothing_length():
    """A sweep kernel "name@factor" runs tgv2d with numerics.h_factor = factor, into its own folder;
    a bad entry fails naming the key."""
    atlas = load("smoke", overrides={"tgv": {"kernels": ["quintic", "wendland_c2@1.5"]}})
    exp = S.tgv_experiment(atlas, "wendland_c2@1.5", "float64")
    assert exp.settings.numerics.kernel == "wendland_c2" and exp.settings.numerics.h_factor == 1.5
    base = S.tgv_experiment(atlas, "quintic", "float64").settings.numerics.h_factor
    assert base == 1.0
    assert S.tgv_results("r", "wendland_c2@1.5", "float32").name == "wendland_c2_h1.5_float32"
    assert S.tgv_results("r", "quintic", "float32").name == "quintic_float32"
    for bad in ("wendland_c2@", "wendland_c2@-1", "wendland_c2@x", "cubic@1.5"):
        with pytest.raises(sph.ConfigError, match=r"tgv\.kernels\[1\]"):
            load("smoke", overrides={"tgv": {"kernels": ["quintic", bad]}})


def synthetic_runs(n_problems: int, seed: int = 0) -> pd.DataFrame:
    """Run records of the first `n_problems` problems of the atlas: three methods, two kernels (one
    also at h = 1.5 dx), both dtypes, three spacings each; errors and wall times over one to three
    decades (a narrow span exercises the 1-2-5 tick labels)."""
    rng = np.random.default_rng(seed)
    rows = []
    for k, (name, (exp, col, _)) in enumerate(list(A.PROBLEMS.items())[:n_problems]):
        col = col or "err_u_max_mean"
        span = 1 + k % 3  # decades
        for method in ("sph", "tvf", "riemann"):
            for kernel, h in (("quintic", 1.0), ("wendland_c2", 1.0), ("wendland_c2", 1.5)):
                for dtype in ("float64", "float32"):
                    for dx in (0.04, 0.02, 0.01):
                        rows.append({"experiment": exp, "method": method, "kernel": kernel, "h_factor": h,
                                     "dtype": dtype, "dx": dx, "n_particles": int(1 / dx ** 2),
                                     "wall_s": 10 ** rng.uniform(2, 2 + span), col: 10 ** rng.uniform(-3, -3 + span)})
    return pd.DataFrame(rows)


def drawn_texts(fig) -> list:
    """(text, window extent) of every non-empty text the drawn figure shows: titles, axis labels, the
    tick labels inside their axis's range, legend titles and entries."""
    from matplotlib.text import Text

    fig.canvas.draw()
    r = fig.canvas.get_renderer()
    ticks, hidden = {}, set()
    for ax in fig.axes:
        for i, axis in enumerate((ax.xaxis, ax.yaxis)):
            for t in axis.get_ticklabels(which="both") + [axis.label]:
                ticks[id(t)] = (ax.get_window_extent(r), i)
                if not ax.axison:  # the legend row's axes: not drawn
                    hidden.add(id(t))
        ticks.pop(id(ax.xaxis.label)), ticks.pop(id(ax.yaxis.label))
    out = []
    for t in fig.findobj(Text):
        if not t.get_visible() or not t.get_text().strip() or id(t) in hidden:
            continue
        bb = t.get_window_extent(r)
        if id(t) in ticks:  # a tick label outside its axis's range is not drawn
            axbb, i = ticks[id(t)]
            c = (bb.x0 + bb.x1) / 2 if i == 0 else (bb.y0 + bb.y1) / 2
            lo, hi = (axbb.x0, axbb.x1) if i == 0 else (axbb.y0, axbb.y1)
            if not lo - 1 <= c <= hi + 1:
                continue
        out.append((t.get_text(), bb))
    return out


@pytest.mark.parametrize("n, grid", [(6, (2, 3)), (7, (3, 3)), (2, (1, 2))])
def test_atlas_is_a_grid_readable_at_readme_width(n, grid):
    """The atlas is a grid of at most three columns, 9 in wide (a 9-point label ~11 px at the README's
    ~800 px), every panel with both axis labels and no legend of its own; one shared legend below every
    panel; no two texts (titles, labels, drawn tick labels, legend entries) overlap."""
    import matplotlib.pyplot as plt

    atlas = load("smoke")
    runs = synthetic_runs(n)
    tables = {name: A.problem_table(runs, atlas, name) for name in A.PROBLEMS}
    fig, panels = A.atlas_figure(tables)
    try:
        assert A.atlas_layout(n) == grid and len(panels) == n
        assert fig.get_figwidth() == pytest.approx(A.ATLAS_WIDTH_IN) and fig.get_figheight() < 1.3 * fig.get_figwidth()
        for k, ax in enumerate(panels):
            rows, cols, *_ = ax.get_subplotspec().get_geometry()
            assert (rows - 1, cols) == grid  # the grid has one more row, the legend's
            spec = ax.get_subplotspec()
            assert (spec.rowspan.start, spec.colspan.start) == divmod(k, grid[1])
            assert ax.get_xlabel() and ax.get_ylabel() and ax.get_title()
            assert ax.get_legend() is None  # nothing over the data or the Pareto front
        texts = drawn_texts(fig)
        r = fig.canvas.get_renderer()
        legends = [a.get_legend() for a in fig.axes if a.get_legend() is not None]
        assert len(legends) == 3  # method (colour), kernel (shape), precision (fill) + the front
        bottom = min(ax.get_tightbbox(r).y0 for ax in panels)
        for leg in legends:
            assert leg.get_window_extent(r).y1 <= bottom + 1
            assert leg.get_window_extent(r).y0 >= 0  # inside the figure
        for i, (a, ba) in enumerate(texts):
            for b, bb in texts[i + 1:]:
                assert not ba.overlaps(bb.shrunk(0.98, 0.98)), f"{a!r} runs into {b!r}"
        labels = [t for t, _ in texts]
        assert "float64: filled marker" in labels and "float32: open marker" in labels
    finally:
        plt.close(fig)


def test_one_marker_shape_per_kernel_and_one_colour_per_method():
    """Across the atlas's panels a kernel (with its smoothing length) has one marker shape, whatever
    its dtype or method, and no two kernels share one; a method one colour; the dtype only the fill."""
    atlas = load("smoke")
    runs = synthetic_runs(6)
    tables = [A.problem_table(runs, atlas, name) for name in A.PROBLEMS]
    styles = A.family_styles(pd.concat([t for t in tables if len(t)]))
    by_kernel, by_method = {}, {}
    for st in styles.values():
        by_kernel.setdefault(st["kernel"], set()).add(st["marker"])
        by_method.setdefault(st["method"], set()).add(st["color"])
        assert (st["mfc"] == "none") == (st["dtype"] == "float32")
    assert all(len(m) == 1 for m in by_kernel.values()) and len(by_kernel) == 3
    assert len({m for ms in by_kernel.values() for m in ms}) == len(by_kernel)
    assert all(len(c) == 1 for c in by_method.values())
    assert len({c for cs in by_method.values() for c in cs}) == len(by_method)
