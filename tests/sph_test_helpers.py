"""Small shared builders for the core tests: periodic lattices, pair geometry, scenes, diagnostics,
and copies of an experiment folder (a folder is a template) with a smaller smoke profile.

Everything here only assembles inputs from the public pieces of `sph`; no expected values live here.
"""
import fcntl
import json
import os
import shutil
import subprocess
from contextlib import contextmanager
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import yaml

import sph
from sph.domain import Domain
from sph.kernels import make_kernel
from sph.lattice import cartesian, jitter
from sph.pvec import PVec
from sph.views import rows, sides, whole_list_pairs
from sph.scene import Scene
from sph.state import FLUID

UNIT_SQUARE = Domain(box=(1.0, 1.0), periodic=(True, True))
ROOT = Path(__file__).resolve().parents[1]
SHARED_SMOKE = ROOT / ".pytest_cache" / "shared-results" / "smoke"
"""The SitL smoke dataset the tests make once and share (shared_sitl_dataset): the tests' own folder,
never the repository's results/smoke."""


def require_lb_env() -> None:
    """Fail (not skip) when LagrangeBench's environment .venv-lb is missing."""
    import pytest

    if not (ROOT / ".venv-lb" / ".stamp").exists():
        pytest.fail(f"{ROOT / '.venv-lb'} is missing or incomplete: run `make setup-lb`", pytrace=False)


XLA_O0 = "--xla_backend_optimization_level=0"
"""XLA's CPU backend at LLVM -O0, for the processes of the SitL tests (sitl_env): a smoke training runs
20 steps of a tiny network, so compiling its programs is most of its time. Measured on this project's
2-core machine under the same load (2026-12-06): a smoke SitL training 98 -> 72 s (XLA compilation
70 -> 41 s, the same validation MSE_20 8.54e-7). Not for the solver's own tests: a run of thousands of
steps is slower at -O0 (the droplet test 4x), so the tests' own processes keep XLA's default."""


def sitl_env() -> dict:
    """The environment the SitL tests run make and .venv-lb in (CPU, no wandb, no user site; XLA at
    -O0, XLA_O0, unless XLA_FLAGS already names a level). Every SitL process of the tests, the
    dataset's generation included, compiles alike, so a dataset made again is the same to the bit."""
    env = dict(os.environ, JAX_PLATFORMS="cpu", WANDB_MODE="disabled", PYTHONNOUSERSITE="1")
    env.pop("VIRTUAL_ENV", None)
    if "--xla_backend_optimization_level" not in env.get("XLA_FLAGS", ""):
        env["XLA_FLAGS"] = f"{env.get('XLA_FLAGS', '')} {XLA_O0}".strip()
    return env


@contextmanager
def _shared_lock():
    """An exclusive lock on the shared smoke folder, across the xdist workers of a session and across
    sessions in one checkout (fcntl: released when the process ends, however it ends)."""
    SHARED_SMOKE.parent.mkdir(parents=True, exist_ok=True)
    with (SHARED_SMOKE.parent / ".smoke.lock").open("a") as f:
        fcntl.flock(f, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(f, fcntl.LOCK_UN)


_SHARED_MADE = []


def shared_sitl_dataset() -> Path:
    """The smoke RPF dataset in SHARED_SMOKE, made by `make sitl-data PROFILE=smoke` once per process
    under the shared lock: the first worker of a session generates it, the others wait and then find
    it current (make checks its fingerprint and the digests it recorded, and regenerates a stale or
    damaged one). The tests only read it; one that changes data works on a copy (seed_sitl_dataset)."""
    data = SHARED_SMOKE / "sitl" / "data" / "2D_RPF"
    if not _SHARED_MADE:
        require_lb_env()
        with _shared_lock():
            proc = subprocess.run(["make", "sitl-data", "PROFILE=smoke", f"RESULTS={SHARED_SMOKE}"], cwd=ROOT,
                                  env=sitl_env(), capture_output=True, text=True, timeout=1800)
        assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
        _SHARED_MADE.append(data)
    return data


def seed_sitl_dataset(results) -> None:
    """Copy the shared smoke RPF dataset (shared_sitl_dataset, made first if need be) into `results`,
    so that a test file need not generate it again; make checks the copy against the digests
    recorded when it was made, as any dataset. The record of how it was made (lab.deliver's
    manifest) names the shared folder in its command and its file paths: they are renamed to
    `results`, as if it had been made there (the files are the same to the bit), else make would see
    "its command changed" and generate it again (14-20 s a test file)."""
    shared = shared_sitl_dataset()
    dest = Path(results) / "sitl" / "data" / "2D_RPF"
    with _shared_lock():
        shutil.copytree(shared, dest, ignore=shutil.ignore_patterns("*.stale-*"))
    old, new = (json.dumps(str(p))[1:-1] for p in (SHARED_SMOKE, Path(results)))
    for manifest in dest.glob(".*.made.json"):
        manifest.write_text(manifest.read_text().replace(old, new))


def lattice(dx, dim=2):
    """Cell-centred lattice filling the periodic unit square/cube."""
    return cartesian([0.0] * dim, [1.0] * dim, dx)


def jittered_lattice(dx, std_factor, seed, dim=2):
    return jitter(lattice(dx, dim), std_factor * dx, seed, box=[1.0] * dim)


def min_image(r, box, periodic):
    """All pair displacements r_i - r_j (N, N, dim), minimum image in the periodic dimensions."""
    r = np.asarray(r, float)
    d = r[:, None, :] - r[None, :, :]
    box, per = np.asarray(box, float), np.asarray(periodic, bool)
    return np.where(per, d - box * np.round(d / box), d)


def listed_pairs(idx):
    """The set of pairs (i, j) of a dense (N, K) neighbour list padded with N; fails on a duplicate
    or a self pair."""
    idx = np.asarray(idx)
    n = idx.shape[0]
    i, k = np.nonzero(idx < n)
    pairs = list(zip(i.tolist(), idx[i, k].tolist()))
    assert len(set(pairs)) == len(pairs), "duplicate pairs in the neighbour list"
    assert all(a != b for a, b in pairs), "self pairs in the neighbour list"
    return set(pairs)


def brute_force_neighbors(r, radius, box=(1.0, 1.0), periodic=(True, True)):
    """Dense (N, K) neighbour indices of all j != i with |r_ij| < radius, padded with N (numpy, O(N^2))."""
    n = len(r)
    d = np.linalg.norm(min_image(r, box, periodic), axis=-1)
    near = (d < radius) & ~np.eye(n, dtype=bool)
    k = int(near.sum(axis=1).max())
    idx = np.full((n, k), n, dtype=np.int32)
    for i in range(n):
        js = np.flatnonzero(near[i])
        idx[i, :len(js)] = js
    return idx


def periodic_pairs(r, dx, kernel_name="quintic", h_factor=1.0, domain=UNIT_SQUARE):
    """Kernel and Pairs for positions `r` in a periodic box.

    The neighbour list is a brute-force numpy one (independent of the cell-list search tested in
    test_neighbors.py); pair geometry is evaluated under `jit` to keep compile time small.
    """
    kernel = make_kernel(kernel_name, h_factor * dx, domain.dim)
    idx = brute_force_neighbors(r, kernel.cutoff, domain.box, domain.periodic)
    pairs = jax.jit(lambda r, idx: whole_list_pairs(r, idx, domain, kernel.cutoff, kernel))(
        jnp.asarray(r, jnp.float64), idx)
    return kernel, pairs


def per_particle(fn, pairs, **fields):
    """fn(pairs, i, j) over the whole list (`sph.views.sides` of the named per-particle fields),
    jitted, as per-particle arrays: (N,) or (N, dim)."""
    def run(pairs, fields):
        i, j = sides(pairs, **fields)
        return jax.tree_util.tree_map(rows, fn(pairs, i, j), is_leaf=lambda x: isinstance(x, PVec))

    return jax.jit(run)(pairs, fields)


def periodic_scene(dx, r, u, effects=sph.Effects(), material=sph.Material(), name="box"):
    """A fluid-only scene in the periodic unit square with the given positions and velocities."""
    r = np.asarray(r, float)
    return Scene(name=name, dx=dx, domain=UNIT_SQUARE, material=material, effects=effects, r=r,
                 u=np.asarray(u, float), tag=np.full(len(r), FLUID, np.int32))


def momentum(state):
    """Total linear momentum sum_i m_i u_i."""
    return jnp.sum(state.mass[:, None] * state.u, axis=0)


def kinetic_energy(state):
    """(1/2) sum_i m_i |u_i|^2."""
    return 0.5 * jnp.sum(state.mass[:, None] * state.u**2)


def tree_allclose(a, b, rtol=1e-12, atol=1e-12):
    la, lb = jax.tree_util.tree_leaves(a), jax.tree_util.tree_leaves(b)
    assert len(la) == len(lb)
    return all(np.allclose(np.asarray(x), np.asarray(y), rtol=rtol, atol=atol) for x, y in zip(la, lb))


def copied_experiment(name: str, dest, **smoke) -> Path:
    """A copy of experiments/<name> at `dest` (an experiment of its own, named after its folder) whose
    smoke profile has the keys `smoke` replaced."""
    dest = Path(dest)
    shutil.copytree(ROOT / "experiments" / name, dest, ignore=shutil.ignore_patterns("__pycache__"))
    cfg = yaml.safe_load((dest / "config.yaml").read_text())
    cfg["profiles"]["smoke"].update(smoke)
    (dest / "config.yaml").write_text(yaml.safe_dump(cfg))
    return dest
