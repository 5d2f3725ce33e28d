"""Scale-out of the RPF dataset generation (sitl/generate.py): many seeds as one vmapped program,
sharded across devices with jax.sharding. Two (forced host) devices must give the same
trajectories as one; each run is a subprocess because the device count is fixed at JAX start-up."""
import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]

_RUN = textwrap.dedent(
    """
    import json, sys
    import jax, numpy as np
    from sph.relax import Relaxation
    from sitl import generate, settings as S
    data = S.Data(dx=0.1, dt=0.002, write_every=5, t_discard=0.02, frames=(3, 3, 3), seeds=2,
                  relaxation=Relaxation(steps=20, p_bg_factor=0.02, noise_factor=0.1, seed=0, quench_every=10),
                  profile_window=2)
    r0 = generate.relaxed_batch(data, progress=False)
    pos, times, info = generate.simulate_batch(data, r0, progress=False)
    np.save(sys.argv[1], pos)
    print(json.dumps({"devices": info["devices"], "visible": jax.device_count(), "steps": info["steps"]}))
    """
)


def _run(tmp_path, n_devices: int):
    out = tmp_path / f"pos_{n_devices}.npy"
    env = dict(os.environ, PYTHONPATH=str(ROOT), JAX_PLATFORMS="cpu",
               XLA_FLAGS=f"--xla_force_host_platform_device_count={n_devices}")
    proc = subprocess.run([sys.executable, "-c", _RUN, str(out)], cwd=ROOT, env=env, capture_output=True,
                          text=True, timeout=900)
    assert proc.returncode == 0, proc.stderr[-4000:]
    return np.load(out), json.loads(proc.stdout.strip().splitlines()[-1])


def test_two_devices_give_the_same_trajectories_as_one(tmp_path):
    pos1, info1 = _run(tmp_path, 1)
    pos2, info2 = _run(tmp_path, 2)
    assert info1["devices"] == 1 and info2["devices"] == 2 and info2["visible"] == 2
    assert pos1.shape == pos2.shape == (2, 9, 200, 2)
    np.testing.assert_allclose(pos2, pos1, rtol=0, atol=1e-6)
    # the two seeds are different trajectories, not one broadcast
    assert np.abs(pos1[0] - pos1[1]).max() > 1e-3
    # the flow moves: +x below y = 1, -x above
    d = pos1[0, -1] - pos1[0, 0]
    d -= np.round(d / np.array([1.0, 2.0])) * np.array([1.0, 2.0])
    low = pos1[0, 0, :, 1] < 1.0
    assert d[low, 0].mean() > 0 > d[~low, 0].mean()
