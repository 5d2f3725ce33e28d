"""The SitL haiku module (sitl/model.py), run in .venv-lb (it needs LagrangeBench's GNS): with the
correction off it equals our solver's coarse substeps exactly, and the gradient through it (GNN
weights -> L SPH substeps -> output) agrees with central finite differences along one weight
direction (float64); the untrained SitL (last layer zero) equals the solver alone on a batch; its
graph equals LagrangeBench's own; evaluation windows come from every seed; the solver's reaction to
training noise (sitl/noise_response.py) is linear and of the expected size. FAILS, not skips, when
.venv-lb is missing.

Each check is a script of its own, run in .venv-lb; the scripts of one dtype share one process (one
import of LagrangeBench and JAX instead of one per test: most of a script's time), each in a fresh
namespace with its own argv, its output and any exception kept apart, so each test still judges
exactly its own script's output."""
import json
import subprocess
import textwrap
from pathlib import Path

import pytest

from sph_test_helpers import require_lb_env, sitl_env

ROOT = Path(__file__).resolve().parents[2]
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
    # the last layer starts at zero (no gradient reaches the layers below it then): a trained one
    last = M.last_layer(params)
    params = {**params, last: jax.tree_util.tree_map(
        lambda x: 0.1 * jax.random.normal(jax.random.PRNGKey(3), x.shape, x.dtype), params[last])}
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


_ZERO_INIT = _COMMON + textwrap.dedent(
    """
    import dataclasses
    extras = tuple(sys.argv[2].split(",")) if len(sys.argv) > 2 and sys.argv[2] else ()
    cfg = dataclasses.replace(cfg, extra_inputs=extras)
    # a batch of three different input states, as LagrangeBench's Trainer applies the model (vmapped)
    batch = []
    for seed in (3, 4, 5):
        r = jitter(cartesian([0.0, 0.0], list(box), 0.1), 0.01, seed, box=box)
        v = np.stack([rpf.u_steady(r[:, 1], 1.0, 0.1) * frame_dt, np.zeros(len(r))], axis=1)
        batch.append(np.stack([np.mod(r - v, box), r], axis=1))
    feats = {"abs_pos": jnp.asarray(np.stack(batch), jdt)}
    ptypes = jnp.zeros((3, len(r0)), jnp.int32)
    sitl = M.build("sitl", meta, stats, r0, cfg, dtype)
    solver = M.build("solver", meta, stats, r0, cfg, dtype)
    p_sitl, s_sitl = sitl.init(jax.random.PRNGKey(0), (features, ptype))
    p_solver, s_solver = solver.init(jax.random.PRNGKey(0), (features, ptype))

    def apply(model, params, state):
        f = jax.jit(jax.vmap(lambda x, t: model.apply(params, state, (x, t))[0]["acc"]))
        return np.asarray(f(feats, ptypes), np.float64)

    a_sitl, a_solver = apply(sitl, p_sitl, s_sitl), apply(solver, p_solver, s_solver)
    last = M.last_layer(p_sitl)
    live = dict(p_sitl)
    live[last] = jax.tree_util.tree_map(lambda x: x + 0.1, p_sitl[last])
    a_live = apply(sitl, live, s_sitl)
    others = [k for k in p_sitl if k != last]
    print(json.dumps({
        "max_diff": float(np.abs(a_sitl - a_solver).max()), "scale": float(np.abs(a_solver).max()),
        "last_layer_zero": bool(all(float(jnp.abs(x).max()) == 0.0 for x in jax.tree_util.tree_leaves(p_sitl[last]))),
        "others_nonzero": bool(all(any(float(jnp.abs(x).max()) > 0 for x in jax.tree_util.tree_leaves(p_sitl[k]))
                                   for k in others if "linear" in k)),
        "n_others": len(others),
        "live_diff": float(np.abs(a_live - a_solver).max()), "finite": bool(np.isfinite(a_sitl).all()),
        "batch_differs": float(np.abs(a_solver[0] - a_solver[1]).max()),
        # the node encoder's input width: LagrangeBench's features plus the extra inputs
        "encoder_in": [int(v["w"].shape[0]) for k, v in sorted(p_sitl.items()) if "encoder" in k and "w" in v][0]}))
    """
)

_EDGES = textwrap.dedent(
    """
    import json, sys, warnings
    warnings.simplefilter("ignore")
    from pathlib import Path
    from sitl import common as C
    import jax, jax.numpy as jnp, numpy as np
    from sph.lattice import cartesian, jitter
    from sitl import model as M, settings as S

    exp = S.load("smoke")
    path = Path(sys.argv[2])
    data_train, _, _ = C.datasets(exp, path)
    case = C.case(exp, data_train, "sitl")
    meta = data_train.metadata
    box = np.array([1.0, 2.0])
    setup = M.make_setup(meta, case.normalization_stats, data_train[0][0][:, 0], exp.model.substeps)
    n = data_train[0][0].shape[0]
    frames = {f"train[{k}]": data_train[k] for k in (0, 17)}
    # a strongly jittered lattice: many pairs within 0.3 dx of the radius 1.45 dx (the diagonal 1.41 dx)
    rj = np.mod(jitter(cartesian([0.0, 0.0], list(box), meta["dx"]), 0.2 * meta["dx"], 7, box=box), box)
    frames["jittered"] = (np.stack([rj, rj, rj], axis=1).astype(np.float32), data_train[0][1])
    out = {}
    for name, (pos, ptype) in frames.items():
        sample = (jnp.asarray(pos[:, :3]), jnp.asarray(ptype))    # a training sample: 2 inputs + target
        _, lb_features, _, _ = case.allocate(jax.random.PRNGKey(0), sample, noise_std=0.0)   # LagrangeBench's own
        r = jnp.asarray(pos[:, 1], jnp.float32)
        u = (r - jnp.asarray(pos[:, 0])) / setup.frame_dt
        nbrs = setup.graph_search.update(r, setup.graph_nbrs)
        ours = M.graph_features(setup, r, u, nbrs)
        lb, mine = M.edge_set(lb_features, n), M.edge_set(ours, n)
        verlet = int((np.asarray(nbrs.idx) < n).sum()) + n          # the list's pairs, plus self edges
        d = np.asarray(r)[:, None] - np.asarray(r)[None]
        d -= box * np.round(d / box)
        dist = np.sqrt((d ** 2).sum(-1)) / meta["default_connectivity_radius"]
        near = int(((dist > 0.95) & (dist < 1.05)).sum())
        out[name] = {"lb": len(lb), "ours": len(mine), "equal": lb == mine, "verlet": verlet,
                     "only_lb": len(lb - mine), "only_ours": len(mine - lb), "near_radius": near,
                     "overflow": bool(nbrs.did_buffer_overflow),
                     "self_edges": sum(1 for i, j in lb if i == j)}
    print(json.dumps(out))
    """
)

_INTERLEAVED = textwrap.dedent(
    """
    import json, sys, warnings
    warnings.simplefilter("ignore")
    from pathlib import Path
    from sitl import common as C
    import numpy as np
    from sitl import generate, settings as S

    exp = S.load("smoke", overrides={"data": {"frames": [8, 8, 15], "profile_window": 3, "seeds": 3},
                                     "eval": {"n_rollout_steps": 5}, "fig3": {"stamps": [0, 5], "steps": 10},
                                     "train": {"eval_n_trajs": 1}})
    n = exp.data.n_particles
    pos = np.random.default_rng(0).uniform(0, 1, (3, 31, n, 2)).astype(np.float32)
    path = Path(sys.argv[2])
    generate.write(path, exp, pos, np.arange(31) * 0.02, {"dt": 0.002, "steps": 100})
    _, valid, test = C.datasets(exp, path)
    found = []
    for i in range(test.num_samples):
        w, _ = test[i]                         # (N, 7, 2): which seed, which start frame?
        hits = [(s, f) for s in range(3) for f in range(16, 31 - 6)
                if np.array_equal(w.transpose(1, 0, 2), pos[s, f:f + 7])]
        found.append(hits)
    print(json.dumps({"n": test.num_samples, "found": found, "seeds": [test.seed_of(i) for i in range(test.num_samples)]}))
    """
)

_NOISE = textwrap.dedent(
    """
    import json, sys, warnings
    warnings.simplefilter("ignore")
    import jax
    jax.config.update("jax_enable_x64", True)
    import lbcompat
    lbcompat.import_lagrangebench()
    from pathlib import Path
    import numpy as np
    from sitl import noise_response as NR

    path = Path(sys.argv[2])
    meta = json.loads((path / "metadata.json").read_text())
    s = 1e-7 * meta["dx"]
    def one(std):
        return NR.response(path, 3, [std], frame=2, seed=7, dtype="float64")[0]
    rows = {"zero": one(0.0), "small": one(s), "double": one(2 * s)}
    # the scaling estimate of a weakly compressible solver's reaction: displacements of std s change
    # rho by ~ rho s / dx, p by c^2 times that, the acceleration by ~ c^2 s / dx^2; in LagrangeBench's
    # normalised units (times frame_dt^2 / acc_std)
    c = meta["c_ref_factor"] * meta["u_ref"]
    acc_std = float(np.sqrt(np.mean(np.square(meta["acc_std"]))))
    estimate = c ** 2 * s / meta["dx"] ** 2 * meta["frame_dt"] ** 2 / acc_std
    print(json.dumps({"rows": rows, "estimate": estimate}))
    """
)


_DRIVER = textwrap.dedent(
    """
    import contextlib, io, json, sys, traceback
    jobs = json.loads(sys.stdin.read())
    results = {}
    for key, script, argv in jobs:
        sys.argv = ["-c", *argv]
        out = io.StringIO()
        try:
            with contextlib.redirect_stdout(out):
                exec(compile(script, f"<{key}>", "exec"), {"__name__": "__main__"})
            results[key] = {"stdout": out.getvalue()}
        except BaseException:
            results[key] = {"stdout": out.getvalue(), "error": traceback.format_exc()}
    print(json.dumps(results))
    """
)


def _run_all(jobs) -> dict:
    """Run the scripts `jobs` ((key, script, argv) each, argv[0] the dtype) in one .venv-lb process,
    one after the other, each as `python -c script *argv` would run it; {key: stdout, error}."""
    if not LB_PYTHON.exists():
        pytest.fail(f"{ROOT / '.venv-lb'} is missing or incomplete: run `make setup-lb`", pytrace=False)
    require_lb_env()
    env = dict(sitl_env(), PYTHONPATH=str(ROOT))
    proc = subprocess.run([str(LB_PYTHON), "-c", _DRIVER], input=json.dumps(jobs), cwd=ROOT, env=env,
                          capture_output=True, text=True, timeout=1800)
    assert proc.returncode == 0, proc.stderr[-4000:]
    return json.loads(proc.stdout.strip().splitlines()[-1])


def _result(results: dict, key: str) -> dict:
    """A script's output line (its last), or its failure as the test's."""
    r = results[key]
    assert "error" not in r, r["error"][-4000:]
    return json.loads(r["stdout"].strip().splitlines()[-1])


@pytest.fixture(scope="module")
def float64_runs(sitl_smoke_dataset):
    """The float64 scripts (jax_enable_x64 on for the whole process), in one process."""
    return _run_all([("solver_only", _SOLVER_ONLY, ["float64"]), ("gradient", _GRADIENT, ["float64"]),
                     ("noise", _NOISE, ["float64", str(sitl_smoke_dataset)])])


@pytest.fixture(scope="module")
def float32_runs(sitl_smoke_dataset, tmp_path_factory):
    """The float32 scripts (x64 never enabled), in one process."""
    return _run_all([("solver_only", _SOLVER_ONLY, ["float32"]), ("zero_init", _ZERO_INIT, ["float32", ""]),
                     ("zero_init:solver_acc,substep", _ZERO_INIT, ["float32", "solver_acc,substep"]),
                     ("edges", _EDGES, ["float32", str(sitl_smoke_dataset)]),
                     ("interleaved", _INTERLEAVED, ["float32", str(tmp_path_factory.mktemp("interleaved"))])])



@pytest.mark.parametrize("dtype,tol", [("float64", 1e-11), ("float32", 2e-5)])
def test_sitl_without_correction_equals_our_solver_coarse_substeps(dtype, tol, request):
    out = _result(request.getfixturevalue(f"{dtype}_runs"), "solver_only")
    assert out["n_params"] == 0          # the network is not even built
    assert out["finite"] and out["overflow"] == 0
    assert out["moved_vs_free_flight"] > 1e-5   # the SPH substeps do something
    assert out["max_diff"] < tol, out


def test_gradient_through_sitl_matches_finite_differences(float64_runs):
    out = _result(float64_runs, "gradient")
    assert out["grad_finite"]
    assert abs(out["ad"]) > 0
    assert out["rel"] < 1e-6, out


_ENCODER_IN = {}


@pytest.mark.parametrize("extras", ["", "solver_acc,substep"])
def test_untrained_sitl_equals_solver_only_on_a_batch(extras, float32_runs):
    """The corrector's last layer starts at zero (model.zero_last_layer), so the untrained SitL model
    is the solver alone, on every sample of a batch, to round-off; the corrector is live (a non-zero
    last layer changes the output) and only its last layer is zero. So also with the extra inputs
    (model.extra_inputs: the solver's acceleration, dim 2, and the substep one-hot, L = 3), which widen
    the node encoder's input by exactly 2 + 3."""
    out = _result(float32_runs, f"zero_init:{extras}" if extras else "zero_init")
    _ENCODER_IN[extras] = out["encoder_in"]
    if len(_ENCODER_IN) == 2:
        assert _ENCODER_IN["solver_acc,substep"] - _ENCODER_IN[""] == 2 + 3, _ENCODER_IN
    assert out["finite"] and out["last_layer_zero"] and out["others_nonzero"] and out["n_others"] > 3, out
    assert out["batch_differs"] > 1e-3 * out["scale"], out        # three different states
    assert out["max_diff"] <= 1e-6 * out["scale"], out
    assert out["live_diff"] > 0.05, out                            # normalised units: the corrector acts


def test_corrector_edges_are_lagrangebench_graph(float32_runs):
    """The corrector's edges at its input frame are exactly LagrangeBench's graph there (its own
    neighbour search, case.allocate, on the same positions): pairs closer than the connectivity
    radius, self edges included, no skin edges although the Verlet list behind them holds more
    pairs. Two training frames of the smoke data (the tests' shared smoke dataset, read only) and a
    jittered lattice with many pairs near the radius."""
    out = _result(float32_runs, "edges")
    for name, o in out.items():
        assert not o["overflow"], (name, o)
        assert o["equal"] and o["only_lb"] == o["only_ours"] == 0, (name, o)
        assert o["self_edges"] == 200 and o["lb"] > 200, (name, o)
        assert o["verlet"] > o["ours"], (name, o)                  # skin pairs exist and are left out
    assert out["jittered"]["near_radius"] > 50, out                # the mask's boundary is exercised


def test_evaluation_windows_come_round_robin_from_every_seed(float32_runs):
    """sitl.common.Interleaved: test (and validation) window i is window i // S of seed i % S, so the
    first n windows (LagrangeBench's n_trajs) cover every seed; every window is found in the data."""
    out = _result(float32_runs, "interleaved")
    assert out["n"] == 6 and out["seeds"] == [0, 1, 2, 0, 1, 2]
    # windows of 7 frames cut from the 15 test frames (frames 16..30 of each seed): starts 16 and 23
    assert out["found"] == [[[0, 16]], [[1, 16]], [[2, 16]], [[0, 23]], [[1, 23]], [[2, 23]]], out["found"]


def test_noise_response_is_the_linear_reaction_of_the_sph_substep(float64_runs):
    """sitl/noise_response.py on a smoke training frame, float64: no noise changes nothing; twice the
    noise (the same draw, scaled) changes the acceleration twice as much, to 0.1 % (the SPH acceleration
    is smooth in the positions, so a tiny perturbation acts linearly); and the change has the
    magnitude a weakly compressible solver's scaling predicts (c^2 s / dx^2, within a factor 10 either
    way), in LagrangeBench's normalised units, so the script's unit conversion is the right one."""
    out = _result(float64_runs, "noise")
    rows = out["rows"]
    assert rows["zero"]["rms_change"] == 0.0, rows
    assert rows["small"]["rms_change"] > 0 and rows["small"]["rms_clean"] > 0, rows
    assert rows["small"]["rms_clean"] == rows["double"]["rms_clean"], rows
    ratio = rows["double"]["rms_change"] / rows["small"]["rms_change"]
    assert abs(ratio - 2.0) < 2e-3, (ratio, rows)
    assert 0.1 < rows["small"]["rms_change"] / out["estimate"] < 10.0, out
