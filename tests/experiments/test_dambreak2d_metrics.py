"""Dam-break evaluation (experiments/dambreak2d/analysis.py) on synthetic particle fields with known
answers, the reference data it reads, and the config checks of experiments/dambreak2d/study.py's Settings.
No simulation: runs in a second or two."""
import numpy as np
import pytest

from lab.configtools import ConfigError
from sph.kernels import make_kernel
from experiments.dambreak2d import analysis as E
from lab.experiment import load_settings
from sph_test_helpers import ROOT

DAMBREAK = ROOT / "experiments" / "dambreak2d"


def test_first_peak_of_a_synthetic_signal():
    t = np.linspace(0.0, 5.0, 501)
    p = np.where(t > 2.0, 0.5, 0.0) + 0.4 * np.exp(-((t - 2.3) / 0.05) ** 2) + 0.9 * np.exp(-((t - 4.0) / 0.05) ** 2)
    t_a, t_p, p_p = E.first_peak(t, p, threshold=0.1, window=1.0)
    assert 2.0 <= t_a <= 2.01  # the jump at t = 2 (between samples)
    assert t_p == pytest.approx(2.3, abs=0.01) and p_p == pytest.approx(0.9, abs=0.01)  # not the later 1.4 peak
    assert np.isnan(E.first_peak(t, 0.0 * t, 0.1, 1.0)[0])  # never wet: no peak


def test_buchner_first_peak_matches_the_provenance():
    """PROVENANCE.md: first impact peak of about 0.69 near t sqrt(g/H) = 2.8; the pressure is still
    about zero (|p| < 0.03) before t = 2.45."""
    t, p = E.load_ref(E.BUCHNER)
    assert np.all(np.diff(t) >= 0) and t.size == 95
    t_a, t_p, p_p = E.first_peak(t, p, threshold=0.1, window=1.0)
    assert 2.45 < t_a < 2.5
    assert p_p == pytest.approx(0.69, abs=0.01) and t_p == pytest.approx(2.8, abs=0.05)
    assert p_p == pytest.approx(p[(t > 2.4) & (t < 3.5)].max())
    assert np.all(np.abs(p[t < 2.45]) < 0.03)


def test_martin_moyce_references_are_the_square_column():
    tf, xf = E.load_ref(E.MM_FRONT)
    th, hh = E.load_ref(E.MM_HEIGHT)
    assert xf[0] > 1.0 and xf[-1] == pytest.approx(5.0) and np.all(np.diff(xf) > 0)  # front from x = H = 1
    assert th[0] == 0 and hh[0] == 1.0 and np.all(np.diff(hh) < 0)  # height from the full column


def _block(width, height, dx, offset=0.0):
    xs = offset + (np.arange(round(width / dx)) + 0.5) * dx
    ys = offset + (np.arange(round(height / dx)) + 0.5) * dx
    X, Y = np.meshgrid(xs, ys, indexing="ij")
    return np.stack([X.ravel(), Y.ravel()], axis=1)


def test_sensor_reads_hydrostatic_pressure_on_the_wall_face():
    """Fluid filling x < 1 (the wall face), depth 1: at the face, height 0.2, the Shepard
    interpolation of p = 1 - y gives 0.8 (the field is linear in y and the kernel symmetric in y);
    a uniform field is reproduced exactly; a dry sensor reads 0."""
    dx = 0.02
    r = _block(1.0, 1.0, dx)
    n = r.shape[0]
    fluid = np.ones(n, bool)
    kernel = make_kernel("quintic", dx, 2)
    pos, mass, rho = r[None], np.full(n, dx**2), np.ones((1, n))
    p = (1.0 - r[:, 1])[None]
    got = E.sensor_pressure(pos, p, rho, mass, fluid, np.array([1.0, 0.2]), kernel, 0.1)
    assert got[0] == pytest.approx(0.8, abs=1e-9)
    got = E.sensor_pressure(pos, np.full((1, n), 0.37), rho, mass, fluid, np.array([1.0, 0.5]), kernel, 0.1)
    assert got[0] == pytest.approx(0.37, rel=1e-12)
    got = E.sensor_pressure(pos, p, rho, mass, fluid, np.array([1.5, 0.2]), kernel, 0.1)  # 0.5 beyond the water
    assert got[0] == 0.0
    # a half-space of fluid carries about half the kernel's volume: the wet threshold 0.1 is well below it
    d = np.linalg.norm(r - np.array([1.0, 0.5]), axis=1)
    assert 0.4 < np.sum(dx**2 * np.asarray(kernel.w(d))) < 0.6


def test_front_height_and_leaks_of_a_block():
    dx, off = 0.05, 0.15
    r = _block(1.0, 0.8, dx, off)
    fluid = np.ones(r.shape[0], bool)
    front, h = E.front_and_height(r[None], fluid, off, dx, band=0.1)
    assert front[0] == pytest.approx(1.0) and h[0] == pytest.approx(0.8)  # + dx/2: the block's own edges
    out = E.outside_tank(r[None], fluid, off, dx, length=2.0, height=1.0)
    assert not out.any()
    moved = r.copy()
    moved[0] = [off - 0.6 * dx, off + 0.5]            # 0.6 dx behind the left face: out
    moved[1] = [off + 2.0 + 0.4 * dx, off + 0.5]      # 0.4 dx beyond the right face: still in
    moved[2] = [off + 1.0, off + 1.0 + 0.7 * dx]      # above the lid: out
    out = E.outside_tank(moved[None], fluid, off, dx, length=2.0, height=1.0)
    assert out.sum() == 2 and out[0, 0] and out[0, 2] and not out[0, 1]


def test_moving_average_keeps_constants_and_lines():
    t = np.linspace(0.0, 1.0, 51)
    np.testing.assert_allclose(E.moving_average(t, np.full(51, 3.0), 0.1), 3.0)
    lin = E.moving_average(t, 2.0 * t, 0.1)
    np.testing.assert_allclose(lin[5:-5], 2.0 * t[5:-5], atol=1e-12)  # symmetric window: exact inside
    np.testing.assert_array_equal(E.moving_average(t, t, 0.0), t)


def test_config_profiles_load():
    for profile in ("paper", "smoke"):
        exp = load_settings(DAMBREAK, profile)
        assert exp.g == 1.0 and exp.effects.riemann and exp.effects.density_evolution
        assert exp.material(exp.column("tall")).u_ref == pytest.approx(np.sqrt(2.0))
    paper = load_settings(DAMBREAK, "paper")
    assert paper.dx == 0.02 and paper.column("tall").t_end == 8.0
    assert (paper.column("tall").width, paper.column("square").width) == (2.0, 1.0)
    # the surge-front checks: the paper's square column and its numerics, only dx and walls differ
    for profile, dx, walls in (("square_fine", 0.01, "free_slip"), ("square_coarse", 0.04, "free_slip"),
                               ("square_noslip", 0.02, "no_slip")):
        exp = load_settings(DAMBREAK, profile)
        assert (exp.dx, exp.effects.walls) == (dx, walls)
        assert [c.name for c in exp.columns] == ["square"] and exp.column("square").width == 1.0
        assert exp.numerics == paper.numerics and exp.effects.riemann and exp.effects.density_reinit_every == 20


@pytest.mark.parametrize("override, key", [
    ({"sensor_hieght": 0.2}, "sensor_hieght: unknown key"),
    ({"effects": {"gravity": None}}, "effects.gravity"),
    ({"effects": {"walls": None}}, "effects.walls"),
    ({"columns": [{"name": "tall", "width": 2.01, "height": 1.0, "t_end": 1.0}]}, "columns[0].width"),
    ({"columns": [{"name": "tall", "width": 6.0, "height": 1.0, "t_end": 1.0}]}, "columns[0]"),
    ({"pressure_column": "wide"}, "pressure_column"),
    ({"pressure_range": [1.0, 0.0]}, "pressure_range"),
    ({"keep": ["density"]}, "keep"),
])
def test_bad_config_names_the_key(override, key):
    with pytest.raises(ConfigError, match=key.replace("[", r"\[").replace("]", r"\]")):
        load_settings(DAMBREAK, "smoke", overrides=override)
