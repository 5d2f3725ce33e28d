"""Gradient check of the SPH solver (JAX-SPH, Toshev et al. 2024, Sec. 3 / Fig. 1).

Check (`--part check`, for every case and precision of the profile):
  scene (20 x 20 fluid lattice, standard SPH) -> `warmup_steps` forward steps -> positions r* of the
  fluid at the start of the checked window. Loss L(r) = E_kin = sum_fluid 1/2 m |u|^2 after
  `loss_steps` more steps (`sph.rollout.scan_rollout`) started from the state `solver.state_at`
  builds at fluid positions r (density by summation, pressure, wall values and accelerations
  recomputed from r; velocities and wall positions held fixed). Then
    AD:  jax.grad(L)(r*)                                                (reverse mode, one pass)
    FD:  (L(r* + eps e_k) - L(r* - eps e_k)) / (2 eps)  for every fluid coordinate k, eps = 1e-3 dx,
  and the eps sweep: along `sweep_directions` random unit directions d, the central difference
  against grad L . d for every eps of `sweep_eps_factors` (truncation error ~ eps^2, round-off
  ~ u_mach L / eps: the two meet at the minimum). One neighbour list, allocated at t = 0 with
  `extra_capacity` spare slots, serves the warm-up and every evaluation; each asserts no overflow.
  The FD evaluations run in chunks of `fd_chunk` through one jitted `lax.map`, compiled once.

Growth (`--part growth`): |d E_kin(n steps) / d r0| at the initial lattice for every n of
  `growth.steps` (scan_rollout with segments = isqrt(n), i.e. gradient checkpointing), optionally
  checked against a central difference along one random direction.

Writes results/<profile>/gradcheck/{<case>_<dtype>.npz, metrics.csv, sweep.csv, grad_growth.csv}.

    python gradcheck/run.py --profile smoke [--results results/smoke] [--part check|growth|all]
"""
import math
import time
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import pandas as pd

import sph
from sph.cases import ldc, tgv
from sph.rollout import scan_rollout
try:
    from . import settings as S
except ImportError:  # run as a script: its folder comes first on the import path (a copied folder works unchanged)
    import settings as S

METRIC_COLUMNS = ["case", "dtype", "dx", "n_fluid", "n_particles", "dt", "warmup_steps", "loss_steps", "eps",
                  "loss", "grad_norm_ad", "grad_norm_fd", "rel_l2", "max_abs", "mse", "nonfinite_ad", "ad_rel_l2_vs_ad64",
                  "fd_rel_l2_vs_ad64", "ad_s", "ad_compile_s", "fd_s", "fd_compile_s", "n_fd_evals"]
SWEEP_COLUMNS = ["case", "dtype", "eps_factor", "eps", "rel_l2", "max_abs", "n_directions"]


# -- scene and loss -------------------------------------------------------------------------------
def build(exp: "S.Experiment", case: "S.Case", dtype: str) -> sph.Solver:
    """Solver of `case` on the exp.dx lattice in precision `dtype`."""
    if case.kind == "tgv":
        scene = tgv.scene(exp.dx, exp.material, case.effects)
    else:
        scene = ldc.scene(exp.dx, exp.material, case.effects, layers=exp.wall_layers, lid_velocity=exp.lid_velocity)
    return sph.build_solver(scene, exp.numerics_for(dtype))


def fluid_index(solver) -> np.ndarray:
    return np.flatnonzero(np.asarray(solver.scene.tag) == sph.FLUID)


def kinetic_energy(state, fluid: np.ndarray):
    """E_kin = sum over fluid particles of 1/2 m |u|^2 (the walls' prescribed velocities excluded)."""
    return 0.5 * jnp.sum(state.mass[fluid, None] * state.u[fluid] ** 2)


def make_loss(solver, start, nbrs, n_steps: int, step0: int = 0, segments: int = 0):
    """loss(r_fluid) -> (E_kin after `n_steps`, overflowed), traceable in the fluid positions.

    The state at r_fluid is `solver.state_at` with the walls at their positions in `start` and the
    velocities of `start` (held fixed); positions are wrapped into the periodic box. `nbrs` must be a
    list valid at start.r with room for the perturbations and the motion of the rollout."""
    fluid = fluid_index(solver)
    domain = solver.scene.domain
    periodic = np.asarray(domain.periodic)

    def positions(r_fluid):
        r = start.r.at[fluid].set(r_fluid)
        return jnp.where(periodic, jnp.mod(r, jnp.asarray(domain.box, r.dtype)), r)

    def loss(r_fluid):
        state = solver.state_at(positions(r_fluid), start.u, nbrs)
        state, _, overflow = scan_rollout(solver.step_fn, state, nbrs, n_steps, step0=step0, segments=segments)
        return kinetic_energy(state, fluid), overflow

    return loss


def make_fd(loss, r0, vmap_width: int = 1):
    """fd(dirs (C, n, dim), eps (C,)) -> (central differences (C,) in float64, any overflow), one
    `lax.map` over the C evaluations (`vmap_width` of them side by side)."""

    def one(args):
        d, e = args
        lp, op = loss(r0 + e * d)
        lm, om = loss(r0 - e * d)
        return (lp.astype(jnp.float64) - lm.astype(jnp.float64)) / (2.0 * e.astype(jnp.float64)), op | om

    def fd(dirs, eps):
        vals, overflow = jax.lax.map(one, (dirs, eps), batch_size=None if vmap_width == 1 else vmap_width)
        return vals, jnp.any(overflow)

    return jax.jit(fd)


def _no_overflow(flag, what: str):
    if bool(flag):
        raise RuntimeError(f"gradcheck: the neighbour list overflowed during {what}; raise extra_capacity")


def run_fd_rows(fd, rows, chunk: int, shape, dtype, what: str):
    """Evaluate `rows` = [(direction or coordinate index, eps), ...] in chunks of `chunk`; a row's
    direction is a unit vector e_k when given as an int k. Returns (values (len(rows),), wall_s of all
    chunks, compile_s of the first)."""
    n = int(np.prod(shape))

    def dirs_of(part):
        d = np.zeros((chunk, n))
        e = np.full(chunk, 1.0)  # padding rows: zero direction, a harmless nonzero step
        for j, (dk, ek) in enumerate(part):
            if isinstance(dk, (int, np.integer)):
                d[j, dk] = 1.0
            else:
                d[j] = np.ravel(dk)
            e[j] = ek
        return jnp.asarray(d.reshape(chunk, *shape), dtype), jnp.asarray(e, dtype)

    parts = [rows[i:i + chunk] for i in range(0, len(rows), chunk)]
    t0 = time.perf_counter()
    vals, ov = fd(*dirs_of(parts[0]))
    jax.block_until_ready(vals)
    first = time.perf_counter() - t0  # compilation + one chunk
    out = []
    t0 = time.perf_counter()
    for part in parts:
        vals, ov = fd(*dirs_of(part))
        _no_overflow(ov, what)
        out.append(np.asarray(vals)[:len(part)])
    wall = time.perf_counter() - t0
    return np.concatenate(out), wall, max(first - wall / len(parts), 0.0)


# -- the check ------------------------------------------------------------------------------------
def timed_gradient(loss, r0, what: str):
    """(loss, gradient in float64, seconds of one evaluation, compile seconds) of the jitted
    value_and_grad of `loss` at r0: the first call compiles (and runs), the second is timed. An
    overflowed rollout is an error naming `what`."""
    value_and_grad = jax.jit(jax.value_and_grad(loss, has_aux=True))
    t0 = time.perf_counter()
    jax.block_until_ready(value_and_grad(r0))
    t1 = time.perf_counter()
    (l0, overflow), g = value_and_grad(r0)
    jax.block_until_ready(g)
    wall = time.perf_counter() - t1
    _no_overflow(overflow, what)
    return l0, np.asarray(g, np.float64), wall, max(t1 - t0 - wall, 0.0)


def check_one(exp: "S.Experiment", case: "S.Case", dtype: str, results, force: bool = False) -> Path:
    """AD and FD gradients and the eps sweep of one case in one precision -> <case>_<dtype>.npz."""
    path = S.check_path(results, case.name, dtype)
    fp = S.check_fingerprint(exp, case, dtype)
    if not force and path.exists():
        with np.load(path) as old:
            if str(old["fingerprint"]) == fp:
                print(f"{case.name} {dtype}: unchanged, skipped", flush=True)
                return path
    solver = build(exp, case, dtype)
    fluid = fluid_index(solver)
    state0, _ = solver.init_fn()
    nbrs = solver.neighbors.allocate(state0.r, extra_capacity=exp.extra_capacity)
    warm = jax.jit(lambda s, nb: scan_rollout(solver.step_fn, s, nb, exp.warmup_steps))
    start, nbrs, overflow = warm(state0, nbrs) if exp.warmup_steps else (state0, nbrs, False)
    _no_overflow(overflow, "the warm-up")
    loss = make_loss(solver, start, nbrs, exp.loss_steps, step0=exp.warmup_steps)
    r0 = start.r[fluid]

    l0, g_ad, ad_s, ad_compile_s = timed_gradient(loss, r0, "the AD evaluation")
    if not np.all(np.isfinite(g_ad)):
        print(f"{case.name} {dtype}: WARNING: {int(np.sum(~np.isfinite(g_ad)))} of {g_ad.size} AD gradient "
              f"entries are not finite (README: float32 walls)", flush=True)

    fd = make_fd(loss, r0, exp.fd_vmap)
    rows = [(k, exp.eps) for k in range(r0.size)]
    g_fd, fd_s, fd_compile_s = run_fd_rows(fd, rows, exp.fd_chunk, r0.shape, solver.dtype, "the FD evaluations")
    g_fd = g_fd.reshape(r0.shape)

    rng = np.random.default_rng(exp.seed)
    dirs = rng.normal(size=(exp.sweep_directions, *r0.shape))
    dirs /= np.linalg.norm(dirs.reshape(len(dirs), -1), axis=1)[:, None, None]
    eps_list = [f * exp.dx for f in exp.sweep_eps_factors]
    sweep_rows = [(d, e) for e in eps_list for d in dirs]
    sweep, _, _ = run_fd_rows(fd, sweep_rows, exp.fd_chunk, r0.shape, solver.dtype, "the eps sweep")
    sweep = sweep.reshape(len(eps_list), len(dirs))
    sweep_ad = np.einsum("kij,ij->k", dirs, g_ad)

    path.parent.mkdir(parents=True, exist_ok=True)
    np.savez(path, fingerprint=fp, r=np.asarray(start.r, np.float64), tag=np.asarray(solver.scene.tag),
             fluid=fluid, g_ad=g_ad, g_fd=g_fd, loss=float(l0), dt=solver.dt, eps=exp.eps,
             sweep_eps_factors=np.asarray(exp.sweep_eps_factors), sweep_fd=sweep, sweep_ad=sweep_ad,
             ad_s=ad_s, ad_compile_s=ad_compile_s, fd_s=fd_s, fd_compile_s=fd_compile_s,
             n_fd_evals=2 * len(rows))
    err = np.linalg.norm(g_ad - g_fd) / np.linalg.norm(g_fd)
    print(f"{case.name} {dtype}: {len(fluid)} fluid / {solver.scene.n} particles, E_kin = {float(l0):.6g}, "
          f"|grad| = {np.linalg.norm(g_ad):.4g}, AD vs FD rel. L2 {err:.3g}; AD {ad_s:.2f} s, "
          f"FD ({2 * len(rows)} rollouts) {fd_s:.1f} s", flush=True)
    return path


def _rel(a, b):
    """||a - b|| / ||b||: the error of `a` relative to the reference `b`."""
    return float(np.linalg.norm(a - b) / np.linalg.norm(b))


def metrics(exp: "S.Experiment", results) -> tuple[pd.DataFrame, pd.DataFrame]:
    """metrics.csv (one row per case and precision) and sweep.csv (one row per case, precision, eps).

    metrics: rel_l2 = ||g_AD - g_FD|| / ||g_FD||, max_abs = max |g_AD - g_FD|, mse = mean (g_AD - g_FD)^2
    over all fluid coordinates, both in the row's precision; *_vs_ad64 against the float64 AD gradient.
    sweep: rel_l2 = ||FD_eps(d) - g64 . d|| / ||g64 . d|| over the random directions d, the reference
    being the float64 AD gradient for every precision, so the curve shows the error of FD alone."""
    rows, sweep_rows = [], []
    for case in exp.cases:
        with np.load(S.check_path(results, case.name, "float64")) as ref:
            g64, sweep64 = ref["g_ad"], ref["sweep_ad"]  # the reference: float64 AD
        for dtype in exp.dtypes:
            with np.load(S.check_path(results, case.name, dtype)) as z:
                g_ad, g_fd, diff = z["g_ad"], z["g_fd"], z["g_ad"] - z["g_fd"]
                rows.append({"case": case.name, "dtype": dtype, "dx": exp.dx, "n_fluid": len(z["fluid"]),
                             "n_particles": len(z["tag"]), "dt": float(z["dt"]), "warmup_steps": exp.warmup_steps,
                             "loss_steps": exp.loss_steps, "eps": float(z["eps"]), "loss": float(z["loss"]),
                             "grad_norm_ad": float(np.linalg.norm(g_ad)), "grad_norm_fd": float(np.linalg.norm(g_fd)),
                             "rel_l2": _rel(g_ad, g_fd), "max_abs": float(np.max(np.abs(diff))),
                             "mse": float(np.mean(diff**2)), "nonfinite_ad": int(np.sum(~np.isfinite(g_ad))),
                             "ad_rel_l2_vs_ad64": _rel(g_ad, g64),
                             "fd_rel_l2_vs_ad64": _rel(g_fd, g64), "ad_s": float(z["ad_s"]),
                             "ad_compile_s": float(z["ad_compile_s"]), "fd_s": float(z["fd_s"]),
                             "fd_compile_s": float(z["fd_compile_s"]), "n_fd_evals": int(z["n_fd_evals"])})
                for f, fd_vals in zip(z["sweep_eps_factors"], z["sweep_fd"]):
                    sweep_rows.append({"case": case.name, "dtype": dtype, "eps_factor": float(f), "eps": f * exp.dx,
                                       "rel_l2": _rel(fd_vals, sweep64),
                                       "max_abs": float(np.max(np.abs(fd_vals - sweep64))),
                                       "n_directions": len(fd_vals)})
    table, sweep = pd.DataFrame(rows, columns=METRIC_COLUMNS), pd.DataFrame(sweep_rows, columns=SWEEP_COLUMNS)
    S.out_dir(results).mkdir(parents=True, exist_ok=True)
    table.to_csv(S.metrics_path(results), index=False)
    sweep.to_csv(S.sweep_path(results), index=False)
    return table, sweep


def check_all(exp: "S.Experiment", results, force: bool = False) -> pd.DataFrame:
    t0 = time.perf_counter()
    for case in exp.cases:
        for dtype in sorted(exp.dtypes, key=lambda d: d != "float64"):  # float64 first: the reference
            check_one(exp, case, dtype, results, force)
    table, _ = metrics(exp, results)
    print(f"gradcheck: {len(table)} checks in {time.perf_counter() - t0:.1f} s -> {S.metrics_path(results)}")
    return table


# -- gradient norm against rollout length -----------------------------------------------------------
GROWTH_COLUMNS = ["case", "dtype", "n_steps", "t", "segments", "loss", "grad_norm", "grad_max", "fd_dir_relerr",
                  "wall_s", "compile_s", "fingerprint"]


def growth_fingerprint(exp, case, n: int) -> str:
    return S.digest({"check": S.check_fingerprint(exp, case, exp.growth.dtype), "n": n,
                     "fd_check": exp.growth.fd_check})


def growth_one(exp: "S.Experiment", case: "S.Case", solver, state0, nbrs, n: int) -> dict:
    """|d E_kin(n) / d r0| at the initial positions, with gradient checkpointing over isqrt(n) segments."""
    fluid = fluid_index(solver)
    segments = math.isqrt(n)
    loss = make_loss(solver, state0, nbrs, n, step0=0, segments=segments)
    r0 = state0.r[fluid]
    l0, g, wall, compile_s = timed_gradient(loss, r0, f"the {n}-step rollout")
    fd_err = np.nan
    if exp.growth.fd_check:
        d = np.random.default_rng(exp.seed).normal(size=r0.shape)
        d = jnp.asarray(d / np.linalg.norm(d), r0.dtype)
        forward = jax.jit(loss)
        (lp, op), (lm, om) = forward(r0 + exp.eps * d), forward(r0 - exp.eps * d)
        _no_overflow(op | om, f"the {n}-step FD check")
        fd = (float(lp) - float(lm)) / (2 * exp.eps)
        ad = float(np.vdot(g, np.asarray(d)))
        fd_err = abs(ad - fd) / max(abs(fd), 1e-300)
    row = {"case": case.name, "dtype": exp.growth.dtype, "n_steps": n, "t": n * solver.dt, "segments": segments,
           "loss": float(l0), "grad_norm": float(np.linalg.norm(g)), "grad_max": float(np.max(np.abs(g))),
           "fd_dir_relerr": fd_err, "wall_s": wall, "compile_s": compile_s,
           "fingerprint": growth_fingerprint(exp, case, n)}
    print(f"{case.name} n = {n}: E_kin = {row['loss']:.4g}, |grad| = {row['grad_norm']:.4g}, "
          f"AD vs FD (direction) {fd_err:.2g}, {wall:.2f} s (+ {row['compile_s']:.1f} s compile)", flush=True)
    return row


def growth_all(exp: "S.Experiment", results, force: bool = False) -> pd.DataFrame:
    """Every (case, n) of growth.steps -> grad_growth.csv; rows with unchanged inputs are reused."""
    path = S.growth_path(results)
    old = pd.read_csv(path) if path.exists() and not force else pd.DataFrame(columns=GROWTH_COLUMNS)
    done = set(old["fingerprint"]) if len(old) else set()
    rows = []
    for case in exp.cases:
        todo = [n for n in exp.growth.steps if growth_fingerprint(exp, case, n) not in done]
        keep = [n for n in exp.growth.steps if n not in todo]
        rows += [r for r in old.to_dict("records") if r["case"] == case.name and r["n_steps"] in keep
                 and r["fingerprint"] == growth_fingerprint(exp, case, r["n_steps"])]
        if not todo:
            continue
        solver = build(exp, case, exp.growth.dtype)
        state0, _ = solver.init_fn()
        nbrs = solver.neighbors.allocate(state0.r, extra_capacity=exp.extra_capacity)
        for n in todo:
            rows.append(growth_one(exp, case, solver, state0, nbrs, n))
            table = pd.DataFrame(rows, columns=GROWTH_COLUMNS)
            path.parent.mkdir(parents=True, exist_ok=True)
            table.to_csv(path, index=False)  # after every row: an interrupted sweep keeps what it did
    order = {c.name: i for i, c in enumerate(exp.cases)}
    table = pd.DataFrame(rows, columns=GROWTH_COLUMNS)
    table = table.sort_values(["case", "n_steps"], key=lambda s: s.map(order) if s.name == "case" else s,
                              ignore_index=True)
    path.parent.mkdir(parents=True, exist_ok=True)
    table.to_csv(path, index=False)
    return table


def options(ap):
    ap.add_argument("--part", choices=("check", "growth", "all"), default="check")
    ap.add_argument("--force", action="store_true", help="recompute even if the inputs are unchanged")


def main(args):
    exp = S.load(args.profile)
    results = args.results
    if args.part in ("check", "all"):
        check_all(exp, results, args.force)
    if args.part in ("growth", "all"):
        growth_all(exp, results, args.force)


if __name__ == "__main__":
    from lab.cli import profile_main

    profile_main(main, __doc__, options)
