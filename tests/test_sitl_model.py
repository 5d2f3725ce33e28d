"""The SitL haiku module (sitl/model.py), run in .venv-lb (it needs LagrangeBench's GNS): with the
correction off it equals our solver's coarse substeps exactly, and the gradient through it (GNN
weights -> L SPH substeps -> output) agrees with central finite differences along one weight
direction (float64). FAILS, not skips, when .venv-lb is missing."""
import json
import os
import subprocess
import textwrap
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
LB_PYTHON = ROOT / ".venv-lb" / "bin" / "python"

_COMMON = textwrap.dedent(
    """
    import json, sys, warnings
    warnings.simplefilter("ignore")
    import jax
    if sys.argv[1] == "float64":
        jax.config.update("jax_enable_x64", True)
    import lbcompat
    lbcompat.import_lagrangebench()
    import jax.numpy as jnp, numpy as np
    from sph.cases import rpf
    from sph.lattice import cartesian, jitter
    from sitl import model as M, settings as S

    dtype = sys.argv[1]
    jdt = jnp.float64 if dtype == "float64" else jnp.float32
    meta = {"dx": 0.1, "dt": 0.002, "write_every": 10, "viscosity": 0.1, "g_ext_magnitude": 1.0,
            "p_bg_factor": 0.05, "c_ref_factor": 10.0, "default_connectivity_radius": 0.145, "dim": 2,
            "bounds": [[0.0, 1.0], [0.0, 2.0]]}
    frame_dt = meta["dt"] * meta["write_every"]
    # a non-zero acceleration mean: the output normalisation must subtract it exactly once
    stats = {"velocity": {"mean": jnp.zeros(2, jdt), "std": jnp.asarray([0.01, 0.002], jdt)},
             "acceleration": {"mean": jnp.asarray([2e-5, -1e-5], jdt), "std": jnp.asarray([1e-4, 5e-5], jdt)}}
    box = np.array(rpf.BOX)
    r0 = jitter(cartesian([0.0, 0.0], list(box), 0.1), 0.01, 3, box=box)
    v0 = np.stack([rpf.u_steady(r0[:, 1], 1.0, 0.1) * frame_dt, np.zeros(len(r0))], axis=1)
    r_prev = np.mod(r0 - v0, box)
    features = {"abs_pos": jnp.asarray(np.stack([r_prev, r0], axis=1), jdt)}
    ptype = jnp.zeros(len(r0), jnp.int32)
    cfg = S.Model(latent_dim=8, num_mlp_layers=2, num_mp_steps=2, substeps=3)

    def periodic(d):
        return d - box * np.round(d / box)
    """
)

_SOLVER_ONLY = _COMMON + textwrap.dedent(
    """
    m = M.build("solver", meta, stats, r0, cfg, dtype)
    params, state = m.init(jax.random.PRNGKey(0), (features, ptype))
    out, state = jax.jit(m.apply)(params, state, (features, ptype))
    acc = np.asarray(out["acc"], np.float64)
    # LagrangeBench's integrator: r' = r0 + v0 + (sigma_a acc + mu_a)
    mu, sd = (np.asarray(stats["acceleration"][k], np.float64) for k in ("mean", "std"))
    v0_in = periodic(r0 - r_prev)
    r_next = np.mod(r0 + v0_in + acc * sd + mu, box)
    # our solver's coarse substeps from the same state
    solver = M.coarse_solver(meta, cfg.substeps, dtype)
    nb = solver.neighbors.allocate(jnp.asarray(r0, jdt))
    s = solver.state_at(jnp.asarray(r0, jdt), jnp.asarray(v0_in / frame_dt, jdt), nb)
    for k in range(cfg.substeps):
        s, nb = solver.step_fn(s, nb, k + 1)
    ref = np.asarray(s.r, np.float64)
    print(json.dumps({"n_params": len(jax.tree_util.tree_leaves(params)),
                      "max_diff": float(np.abs(periodic(r_next - ref)).max()),
                      "moved_vs_free_flight": float(np.abs(periodic(ref - (r0 + v0_in))).max()),
                      "overflow": M.overflowed(state), "finite": bool(np.isfinite(acc).all())}))
    """
)

_GRADIENT = _COMMON + textwrap.dedent(
    """
    m = M.build("sitl", meta, stats, r0, cfg, dtype)
    params, state = m.init(jax.random.PRNGKey(0), (features, ptype))
    target = jax.random.normal(jax.random.PRNGKey(1), features["abs_pos"][:, 0].shape, jdt)

    def loss(p):
        out, _ = m.apply(p, state, (features, ptype))
        return jnp.mean((out["acc"] - target) ** 2)

    leaves, treedef = jax.tree_util.tree_flatten(params)
    pick = max(range(len(leaves)), key=lambda i: leaves[i].size)   # the largest weight matrix
    d = jax.random.normal(jax.random.PRNGKey(2), leaves[pick].shape, jdt)
    d = d / jnp.linalg.norm(d)

    def along(eps):
        new = list(leaves)
        new[pick] = leaves[pick] + eps * d
        return jax.tree_util.tree_unflatten(treedef, new)

    g = jax.jit(jax.grad(loss))(params)
    ad = float(jnp.vdot(jax.tree_util.tree_leaves(g)[pick], d))
    f = jax.jit(lambda e: loss(along(e)))
    eps = 1e-5
    fd = float((f(eps) - f(-eps)) / (2 * eps))
    print(json.dumps({"ad": ad, "fd": fd, "rel": abs(ad - fd) / max(abs(fd), 1e-300),
                      "grad_finite": bool(all(jnp.isfinite(x).all() for x in jax.tree_util.tree_leaves(g)))}))
    """
)


def _run(script: str, dtype: str) -> dict:
    if not LB_PYTHON.exists() or not (ROOT / ".venv-lb" / ".stamp").exists():
        pytest.fail(f"{ROOT / '.venv-lb'} is missing or incomplete: run `make setup-lb`", pytrace=False)
    env = dict(os.environ, PYTHONPATH=str(ROOT), JAX_PLATFORMS="cpu", PYTHONNOUSERSITE="1", WANDB_MODE="disabled")
    env.pop("VIRTUAL_ENV", None)
    proc = subprocess.run([str(LB_PYTHON), "-c", script, dtype], cwd=ROOT, env=env, capture_output=True, text=True,
                          timeout=900)
    assert proc.returncode == 0, proc.stderr[-4000:]
    return json.loads(proc.stdout.strip().splitlines()[-1])


@pytest.mark.parametrize("dtype,tol", [("float64", 1e-11), ("float32", 2e-5)])
def test_sitl_without_correction_equals_our_solver_coarse_substeps(dtype, tol):
    out = _run(_SOLVER_ONLY, dtype)
    assert out["n_params"] == 0          # the network is not even built
    assert out["finite"] and out["overflow"] == 0
    assert out["moved_vs_free_flight"] > 1e-5   # the SPH substeps do something
    assert out["max_diff"] < tol, out


def test_gradient_through_sitl_matches_finite_differences():
    out = _run(_GRADIENT, "float64")
    assert out["grad_finite"]
    assert abs(out["ad"]) > 0
    assert out["rel"] < 1e-6, out
