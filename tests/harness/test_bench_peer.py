"""`make bench-peer`'s driver logic without the peer environment: the summary and table of worker
rounds, the JSON-lines protocol against a fake worker process, and the setup file round trip.
No JAX, no .venv-peer (tests never build it); bench/peer_protocol.py and bench/jaxsph_peer.py import
only the standard library and NumPy at module level."""
import importlib.util
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[2]


def _load(name):
    spec = importlib.util.spec_from_file_location(f"bench_{name}", ROOT / "bench" / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


protocol = _load("peer_protocol")
jaxsph_peer = _load("jaxsph_peer")


def _rounds(wall_ms, cpu_ms, steps=10):
    return [{"steps": steps, "wall_s": w * steps / 1e3, "cpu_s": c * steps / 1e3} for w, c in zip(wall_ms, cpu_ms)]


def test_summary_ratios_and_table():
    peer = _rounds([8.0, 7.0, 9.0], [15.0, 14.0, 16.0])
    ours = _rounds([1.0, 2.0, 1.5], [2.0, 2.5, 3.0])
    s = protocol.summarize(peer, ours)
    assert s["jax_sph_min_ms"] == pytest.approx(7.0) and s["jax_sph_median_ms"] == pytest.approx(8.0)
    assert s["ours_min_ms"] == pytest.approx(1.0) and s["ours_median_ms"] == pytest.approx(1.5)
    assert s["ratio_min"] == pytest.approx(7.0) and s["ratio_median"] == pytest.approx(8.0 / 1.5)
    assert s["jax_sph_cpu_median_ms"] == pytest.approx(15.0) and s["ours_cpu_median_ms"] == pytest.approx(2.5)
    assert s["cpu_ratio_min"] == pytest.approx(7.0) and s["cpu_ratio_median"] == pytest.approx(6.0)

    row = dict(case="tgv2d_dx0.02_sph_f64", n=2500, **s, jax_sph_rss_base_gb=0.25, jax_sph_rss_peak_gb=0.75,
               ours_rss_base_gb=0.5, ours_rss_peak_gb=0.625)
    table = protocol.format_table([row, dict(row, case="shared", jax_sph_rss_peak_gb=None)], "title")
    lines = table.splitlines()
    assert lines[0] == "title" and "JAX-SPH min" in lines[1]
    own = lines[2].split()
    assert own[0] == "tgv2d_dx0.02_sph_f64" and own[1] == "2500"
    assert [own[i] for i in (3, 4, 5, 6, 7, 8)] == ["7.00", "8.00", "1.00", "1.50", "7.00", "5.33"]
    assert own[-2:] == ["0.50", "0.12"]  # peak - base, GB
    assert lines[3].split()[-2:] == ["-", "0.12"]  # not measured


FAKE_WORKER = textwrap.dedent("""
    import peer_protocol as p  # from PYTHONPATH
    out = p.open_channel()
    print("noise on stdout goes to stderr")
    done = []
    p.serve(out, lambda n: done.append(n), 3, {"code": "fake", "n": 7, "rss_base_gb": p.rss_gb()})
    assert done[0] == 3  # the warm-up round
""")


def test_protocol_with_a_fake_worker(tmp_path):
    script = tmp_path / "fake_worker.py"
    script.write_text(FAKE_WORKER)
    env = {**os.environ, "PYTHONPATH": str(ROOT / "bench")}
    w = protocol.Worker([sys.executable, str(script)], "fake", env=env)
    try:
        assert w.info["ready"] and w.info["n"] == 7 and w.info["code"] == "fake"
        a, b = protocol.interleave(w, w, 5, 2)
        assert [r["steps"] for r in a + b] == [5] * 4 and all(r["wall_s"] >= 0 and r["cpu_s"] >= 0 for r in a)
        final = w.quit()
        assert final["rss_peak_gb"] > 0 and final["rss_max_gb"] >= final["rss_peak_gb"] * 0.99
        assert final["rss_base_gb"] > 0
    finally:
        w.kill()


def test_worker_failure_is_reported(tmp_path):
    script = tmp_path / "broken.py"
    script.write_text("raise SystemExit(3)\n")
    with pytest.raises(protocol.WorkerError, match="exit code 3"):
        protocol.Worker([sys.executable, str(script)], "broken")


def test_setup_round_trip(tmp_path):
    rng = np.random.default_rng(0)
    setup = dict(name="ldc2d_dx0.02_sph_f64", dtype="float32", walls="no_slip", r=rng.random((5, 2)),
                 u=rng.random((5, 2)), tag=np.array([0, 0, 1, 2, 2], np.int32), box=np.array([1.12, 1.12]),
                 dim=2, n=5, ldc_layers=3, dx=0.02, rho_ref=1.0, eta=0.01, u_ref=1.0, c_ref_factor=10.0,
                 gamma=1.0, p_bg_factor=0.01, eta_limiter=3.0, dt=4e-4, riemann=False, tvf=True,
                 density_evolution=False)
    jaxsph_peer.save_setup(tmp_path / "s.npz", setup)
    back = jaxsph_peer.load_setup(tmp_path / "s.npz")
    assert set(back) == set(setup)
    for k, v in setup.items():
        if isinstance(v, np.ndarray):
            assert np.array_equal(back[k], v) and back[k].dtype == v.dtype
        else:
            assert back[k] == v and type(back[k]) is type(v), k


def test_make_test_never_builds_the_peer_env():
    proc = subprocess.run(["make", "-n", "-C", str(ROOT), "test"], capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    assert "pytest" in proc.stdout and "setup_peer" not in proc.stdout
