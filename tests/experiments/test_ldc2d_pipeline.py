"""End-to-end 2D lid-driven cavity pipeline (experiments/ldc2d), smoke profile at its Fig. 6 spacing
(dx = 0.05, 400 fluid particles, t_end = 4, three methods): runs -> traj.h5 + metadata.json ->
centreline profiles -> metrics.csv -> figure; skipping of finished runs; the Ghia reference parser;
the Shepard interpolation; configuration errors.

About a minute on an idle 2-core CPU (three runs of ~3500 steps plus compilation). At t = 4 the flow
is not yet steady, but the primary vortex has formed: the checks are qualitative (lid-driven profile
shapes as in Ghia et al. 1982) with loose bounds on the deviation from Ghia.
"""
import dataclasses
import json

import numpy as np
import pandas as pd
import pytest

import sph
from sph.cases import ldc_reference as LR
from lab import io
from lab.configtools import ConfigError
from lab.experiment import Experiment, load_settings, run_key
from sph.kernels import make_kernel
from experiments.ldc2d import analysis as A
from experiments.ldc2d import plot_fig6 as P
from sph_test_helpers import ROOT

LDC2D = ROOT / "experiments" / "ldc2d"
DX = 0.05
METHODS = ("sph", "tvf", "riemann")


def load(profile, overrides=None):
    return load_settings(LDC2D, profile, overrides)


def run_dir(results, method, dx):
    return results / "ldc2d" / f"{method}_dx{dx:g}"


@pytest.fixture(scope="module")
def exp():
    return load("smoke")


@pytest.fixture(scope="module")
def finished(exp, tmp_path_factory):
    """The three smoke runs of Fig. 6 (dx = 0.05): (results folder, metrics rows)."""
    assert exp.figures["fig6"] == DX
    harness = Experiment(LDC2D, "smoke", tmp_path_factory.mktemp("ldc_smoke"))
    harness.run_all([r.name for r in harness.runs if "fig6" in r.groups], progress=False)
    return harness.results, [harness.metrics(harness.run(f"{m}_dx{DX:g}")) for m in METHODS]


def test_metrics_csv_has_one_physical_row_per_method(exp, finished):
    results, _ = finished
    table = pd.read_csv(results / "ldc2d" / "metrics.csv")
    assert list(table["method"]) == list(METHODS)
    assert np.allclose(table["dx"], DX) and set(table["dtype"]) == {"float64"}
    for _, got in table.iterrows():
        assert got["n_fluid"] == 400 and got["n_particles"] == 26 * 26
        assert got["n_steps"] == round(exp.t_end / got["dt"]) and abs(got["t_end"] - exp.t_end) < 1e-9
        assert got["wall_s"] > 0 and got["compile_s"] > 0 and np.isfinite(got["ms_per_step"])
        for col in ("u_rms", "u_maxdev", "v_rms", "v_maxdev", "u_rms_interior", "v_rms_interior",
                    "profile_change", "e_kin_change", "density_error_max"):
            assert np.isfinite(got[col]), col
        assert got["u_maxdev"] >= got["u_rms"] > 0 and got["v_maxdev"] >= got["v_rms"] > 0
        # coarse and not yet steady, but already near Ghia's (1982) profiles, an independent reference:
        # measured 2026-12-06 u_rms 0.031-0.040, v_rms 0.034-0.036 over the three methods (a fluid at
        # rest: 0.35 / 0.24); the bounds are twice the worst method's
        assert got["u_rms"] < 0.08 and got["v_rms"] < 0.075, got["method"]
        assert got["density_error_max"] < 0.05  # weakly compressible, Ma = 0.1
        assert got["fluid_outside"] == 0  # no fluid particle has entered a wall
        assert got["avg_t_to"] == pytest.approx(exp.t_end) and got["avg_t_from"] < got["avg_t_to"]


@pytest.mark.parametrize("method", METHODS)
def test_profiles_are_finite_and_lid_driven(exp, finished, method):
    results, _ = finished
    p = A.evaluate(exp, method, DX, run_dir(results, method, DX))[1]
    y, u, x, v = p["y"], p["u"], p["x"], p["v"]
    for a in (u, v, p["sim_u"], p["sim_v"], p["u_std"], p["v_std"]):
        assert np.all(np.isfinite(a))
    assert y[0] == 0.0 and y[-1] == 1.0 and len(p["sim_u"]) == len(p["ghia_u"]) == 17
    # u(y) at x = 0.5: largest at the lid, close to the lid speed (Shepard interpolation over the fluid
    # only, so one-sided at the wall: at dx = 0.05 about 0.7 of it), about 0 at the bottom wall
    assert u[-1] == u.max() and u[-1] > 0.6 * exp.lid_velocity
    assert abs(u[0]) < 0.05
    # return flow: a negative minimum about the cavity centre, slightly below it as in Ghia (y = 0.45)
    i = int(np.argmin(u))
    assert u[i] < -0.1 and 0.3 <= y[i] <= 0.55, (u[i], y[i])
    # v(x) at y = 0.5: up on the left, down (stronger) on the right, about 0 at the side walls
    left, right = x < 0.5, x > 0.5
    assert v[left].max() > 0.08 and v[right].min() < -0.1
    assert x[np.argmax(v)] < 0.35 and x[np.argmin(v)] > 0.65
    assert abs(v[0]) < 0.1 and abs(v[-1]) < 0.1


def test_trajectory_and_metadata(exp, finished):
    results, _ = finished
    folder = run_dir(results, "riemann", DX)
    tr = io.read_trajectory(folder / "traj.h5")
    meta = json.loads((folder / "metadata.json").read_text())
    n = 26 * 26
    assert tr["position"].shape == (exp.frames + 1, n, 2)
    assert tr["velocity"].shape == tr["momentum_velocity"].shape == (exp.frames + 1, n, 2)
    assert bool(tr["attrs"]["complete"])
    fluid = tr["particle_type"] == sph.FLUID
    lid = tr["particle_type"] == sph.MOVING_WALL
    assert fluid.sum() == 400 and lid.sum() == 3 * 20  # lid_corners: fixed, the lid spans the cavity only
    # walls stay put; the lid keeps its prescribed velocity in u
    np.testing.assert_array_equal(tr["position"][-1][~fluid], tr["position"][0][~fluid])
    np.testing.assert_allclose(tr["momentum_velocity"][-1][lid], [[exp.lid_velocity, 0.0]] * int(lid.sum()))
    assert meta["cavity_offset"] == pytest.approx(3 * DX) and meta["re"] == pytest.approx(100.0)
    assert meta["periodic_boundary_conditions"] == [False, False]
    assert "walls=no_slip" in meta["effects"] and "riemann" in meta["effects"]


@pytest.mark.parametrize("walls", ["mirror", "fluid"])
def test_script_profiles_equal_the_experiment_ones(exp, finished, walls):
    """sph.cases.ldc_reference.compare (a script's states and solver) gives the profiles and deviations
    of the experiment's analysis (its stored frames) at the same frames."""
    from types import SimpleNamespace
    from experiments.ldc2d import analysis

    results, _ = finished
    an = dataclasses.replace(exp.analysis, walls=walls)
    ip = analysis.Interpolator(run_dir(results, "tvf", DX), an)
    frames = range(ip.n_frames - 3, ip.n_frames)
    yg, xg = LR.ghia("u", 100)[0], LR.ghia("v", 100)[0]
    u, _, v, _ = ip.averaged(frames, yg, xg)
    states = [SimpleNamespace(r=r, v=vel, u=None, rho=rho, mass=ip.mass) for r, vel, rho in map(ip.frame, frames)]
    run = Experiment(LDC2D, "smoke", results).run(f"tvf_dx{DX:g}")
    got = LR.compare(sph.build_solver(*Experiment(LDC2D, "smoke", results).study.scene(run)), states, re=100,
                     walls=walls)
    np.testing.assert_allclose(got["u"], u, rtol=0, atol=1e-14)
    np.testing.assert_allclose(got["v"], v, rtol=0, atol=1e-14)
    assert got["u_rms"] == pytest.approx(LR.deviations(u, v, 100)["u_rms"], abs=1e-14)


def test_finished_run_is_skipped_and_plotted(exp, finished):
    results, rows = finished
    traj = run_dir(results, "tvf", DX) / "traj.h5"
    before = traj.stat().st_mtime_ns
    harness = Experiment(LDC2D, "smoke", results)
    assert harness.run_one(harness.run(f"tvf_dx{DX:g}"), progress=False).status == "skipped"
    harness.write_table()
    again = harness.metrics(harness.run(f"tvf_dx{DX:g}"))
    assert traj.stat().st_mtime_ns == before
    assert again["wall_s"] == rows[1]["wall_s"] and again["u_rms"] == pytest.approx(rows[1]["u_rms"])
    assert len(pd.read_csv(results / "ldc2d" / "metrics.csv")) == 3  # rebuilt, not appended
    out = results / "fig6"
    out.mkdir()
    png = P.plot(harness, out)
    assert png.exists() and png.with_suffix(".pdf").exists()
    assert len(pd.read_csv(png.parent / "metrics.csv")) == 3


def test_plot_refuses_missing_runs(tmp_path):
    from lab.io import MissingOutput

    with pytest.raises(MissingOutput, match=r"run sph_dx0\.04 of profile smoke is absent"):
        P.figure(Experiment(LDC2D, "smoke", tmp_path), tmp_path, "fig7")


# -- reference data and interpolation --------------------------------------------------------------
def test_ghia_tables_parse_including_decimal_comma():
    y, u = LR.ghia("u", 100)
    x, v = LR.ghia("v", 100)
    assert len(y) == len(x) == 17 and np.all(np.diff(y) > 0) and np.all(np.diff(x) > 0)
    assert (y[0], u[0]) == (0.0, 0.0)  # written "0,00000" in the file
    assert (y[-1], u[-1]) == (1.0, 1.0)
    assert u[np.isclose(y, 0.5)][0] == pytest.approx(-0.20581)
    assert u.min() == pytest.approx(-0.21090) and y[np.argmin(u)] == pytest.approx(0.4531)
    assert v[np.isclose(x, 0.5)][0] == pytest.approx(0.05454)
    assert v[0] == v[-1] == 0.0 and v.min() == pytest.approx(-0.24533)
    y4, u4 = LR.ghia("u", 400)
    np.testing.assert_array_equal(y4, y)
    assert u4.min() == pytest.approx(-0.32726)


def test_ghia_parser_tolerates_quotes_and_commas(tmp_path):
    f = tmp_path / "g.csv"
    f.write_text('129- grid,,,Re\npt. no.,y,100,"10,000"\n129,1.0000,1.00000,1.0\n'
                 '65,"0,5000", -0.20581 ,0.03111\n1,0.0000,"0,00000",0.00000\n')
    y, u = LR.ghia("u", 100, f)
    np.testing.assert_allclose(y, [0.0, 0.5, 1.0])
    np.testing.assert_allclose(u, [0.0, -0.20581, 1.0])
    assert LR.ghia("u", 10000, f)[1][1] == pytest.approx(0.03111)


def test_shepard_interpolation_reproduces_linear_fields():
    dx = 0.05
    g = (np.arange(40) + 0.5) * dx
    r = np.stack(np.meshgrid(g, g, indexing="ij"), -1).reshape(-1, 2)
    vol = np.full(len(r), dx * dx)
    k = make_kernel("quintic", dx, 2)
    pts = np.array([[0.5, 0.5], [1.013, 0.77], [0.31, 1.52]])
    f = np.stack([np.full(len(r), 3.0), 2.0 * r[:, 0] - r[:, 1]], 1)
    got = LR.shepard(pts, r, f, vol, k)
    np.testing.assert_allclose(got[:, 0], 3.0, rtol=1e-12)
    np.testing.assert_allclose(got[:, 1], 2.0 * pts[:, 0] - pts[:, 1], atol=1e-4)  # lattice sums: ~1e-5
    assert np.all(np.isnan(LR.shepard(np.array([[9.0, 9.0]]), r, f[:, 0], vol, k)))


# -- configuration errors --------------------------------------------------------------------------
@pytest.mark.parametrize("override, match", [
    ({"analysis": {"average_frame": 5}}, r"analysis\.average_frame: unknown key"),
    ({"figures": {"fig8": 0.02}}, r"figures\.fig8: unknown figure"),
    ({"figures": {"fig6": 0.03}}, r"figures\.fig6: must divide"),
    ({"figures": {"fig6": "fine"}}, r"figures\.fig6: expected a particle spacing"),
    ({"t_end": 0}, r"t_end: must be positive"),
    ({"material": {"eta": 0.02}}, r"material\.eta: Re = .*50 differs from ghia_re = 100"),
    ({"ghia_re": 150}, r"ghia_re: not a Reynolds number"),
    ({"analysis": {"walls": "ghost"}}, r"analysis\.walls: 'ghost' is not one of"),
    ({"analysis": {"velocity": "momentum"}, "keep": ["velocity", "density"]}, r"analysis\.velocity"),
    ({"keep": ["velocity"]}, r"keep: the profiles need 'density'"),
    ({"analysis": {"average_frames": 50}}, r"analysis\.average_frames: must not exceed"),
    ({"lid_corners": "sliding"}, r"lid_corners: 'sliding' is not one of"),
    ({"lid_velocity": 2.0}, r"lid_velocity: must not exceed material\.u_ref"),
    ({"methods": [{"name": "r", "effects": {"riemann": True}}]}, r"methods\[0\]\.effects\.riemann: .*density_evolution"),
    ({"methods": [{"name": "s", "effects": {"walls": "free_slip"}}]}, r"methods\[0\]\.effects\.walls: the cavity walls are no-slip"),
    ({"methods": [{"name": "s", "numerics": {"p_bg": 0.01}}]}, r"methods\[0\]\.numerics\.p_bg: unknown key"),
    ({"methods": [{"name": "s"}, {"name": "s"}]}, r"methods\[1\]\.name: 's' appears twice"),
])
def test_config_errors_name_the_key(override, match):
    with pytest.raises(ConfigError, match=match):
        load("smoke", overrides=override)


def test_unknown_profile_and_method_numerics_merge():
    with pytest.raises(ConfigError, match=r"profiles\.nope: no such profile"):
        load("nope")
    exp = load("paper")
    assert exp.dx == (0.02, 0.01) and exp.re == pytest.approx(100.0)
    sph_num = exp.numerics_of(exp.method("sph"))
    assert sph_num.p_bg_factor == 0.01 and sph_num.cfl == exp.numerics.cfl
    assert exp.numerics_of(exp.method("tvf")).p_bg_factor == 0.0
    assert exp.effects(exp.method("riemann")).walls == "no_slip"
    # the post-processing settings do not change what a run is
    def key(overrides):
        harness = Experiment(LDC2D, "paper", "unused", overrides)
        return run_key(harness.run("tvf_dx0.02")), harness.spec(harness.run("tvf_dx0.02")).fingerprint

    assert key({"analysis": {"average_frames": 40, "walls": "mirror"}}) == key({})
    assert key({"t_end": 30.0})[0] != key({})[0]
