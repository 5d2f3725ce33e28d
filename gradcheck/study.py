"""Gradient check of the SPH solver (JAX-SPH, Toshev et al. 2024, Sec. 3 / Fig. 1) as a study of the
protocol (lab.experiment): its runs are not simulations but computations (`compute`), each cached by
the harness under its key in <results>/gradcheck/<run>/ (result.json, arrays).

Check runs (`<case>_<dtype>`, group fig1), for every case and precision of the profile:
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
  Arrays: <run>/check.npz; row of metrics.csv: `metrics` (METRIC_COLUMNS).

Growth runs (`growth_<case>_n<n>`, group growth): |d E_kin(n steps) / d r0| at the initial lattice for
  every n of `growth.steps` (scan_rollout with segments = isqrt(n), i.e. gradient checkpointing),
  optionally checked against a central difference along one random direction; rows of grad_growth.csv.

The figures: plot_fig1.py (Fig. 1 and the eps sweep's table sweep.csv) and plot_grad_norm_vs_steps.py.

    python -m lab.experiment gradcheck --profile smoke [--results results/smoke] [--group fig1|growth]
"""
import math
import time
from dataclasses import dataclass, field, replace
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

import sph
from lab.configtools import require, require_finite
from lab.protocol import Table
from sph.cases import ldc, tgv
from sph.rollout import scan_rollout

KINDS = ("tgv", "ldc")
DTYPES = ("float64", "float32")
OUT = {"metadata": {"key": False}}
"""A field out of a run's key: it cannot change the run's numbers (chunking, groups)."""
METRIC_COLUMNS = ["case", "dtype", "dx", "n_fluid", "n_particles", "dt", "warmup_steps", "loss_steps", "eps",
                  "loss", "grad_norm_ad", "grad_norm_fd", "rel_l2", "max_abs", "mse", "nonfinite_ad", "ad_rel_l2_vs_ad64",
                  "fd_rel_l2_vs_ad64", "ad_s", "ad_compile_s", "fd_s", "fd_compile_s", "n_fd_evals"]
SWEEP_COLUMNS = ["case", "dtype", "eps_factor", "eps", "rel_l2", "max_abs", "n_directions"]
GROWTH_COLUMNS = ["case", "dtype", "n_steps", "t", "segments", "loss", "grad_norm", "grad_max", "fd_dir_relerr",
                  "wall_s", "compile_s", "fingerprint"]
CHECK_FILE = "check.npz"


@dataclass(frozen=True)
class Case:
    """A scene whose gradient is checked: `kind` tgv (periodic Taylor-Green vortex, sph.cases.tgv) or
    ldc (lid-driven cavity, sph.cases.ldc; needs effects.walls) with the effects its scene declares."""

    name: str
    kind: str
    effects: sph.Effects = field(default_factory=sph.Effects)

    def __post_init__(self):
        require(self.kind in KINDS, "kind", f"{self.kind!r} is not one of {list(KINDS)}")
        if self.kind == "ldc":
            require(self.effects.walls is not None, "effects.walls", "the cavity needs walls (no_slip or free_slip)")
        else:
            require(self.effects.walls is None and self.effects.gravity is None, "effects",
                    "the Taylor-Green vortex is a periodic box without walls or gravity")


@dataclass(frozen=True)
class Growth:
    """Gradient norm against rollout length: d E_kin(n steps) / d r0 for every n of `steps`.

    steps      rollout lengths n
    dtype      precision of these runs
    fd_check   also compare grad . d with a central difference along one random unit direction d
               (eps of the main check) for every n, to see whether AD and FD still agree after n steps
    """

    steps: tuple[int, ...] = (1, 3, 10, 30, 100, 300, 1000)
    dtype: str = "float64"
    fd_check: bool = True

    def __post_init__(self):
        require(len(self.steps) > 0, "steps", "needs at least one rollout length")
        for i, n in enumerate(self.steps):
            require(n >= 1, f"steps[{i}]", f"must be >= 1, got {n}")
        require(list(self.steps) == sorted(set(self.steps)), "steps", f"must be strictly increasing, got {list(self.steps)}")
        require(self.dtype in DTYPES, "dtype", f"{self.dtype!r} is not one of {list(DTYPES)}")


@dataclass(frozen=True)
class Settings:
    """One profile of the gradient check (see config.yaml for the meaning of each key)."""

    cases: tuple[Case, ...]
    dx: float = 0.05
    material: sph.Material = field(default_factory=lambda: sph.Material(rho_ref=1.0, eta=0.1, u_ref=1.0))
    numerics: sph.Numerics = field(default_factory=sph.Numerics)
    dtypes: tuple[str, ...] = DTYPES
    warmup_steps: int = 10
    loss_steps: int = 5
    eps_factor: float = 1e-3
    sweep_eps_factors: tuple[float, ...] = (1e-2, 1e-3, 1e-4, 1e-5, 1e-6, 1e-7)
    sweep_directions: int = 32
    seed: int = 0
    fd_chunk: int = 64
    fd_vmap: int = 1
    extra_capacity: int = 8
    wall_layers: int = 3
    lid_velocity: float = 1.0
    fig1_dtypes: tuple[str, ...] = ("float64", "float32")
    growth: Growth = field(default_factory=Growth)

    def __post_init__(self):
        require_finite(self)
        require(len(self.cases) > 0, "cases", "needs at least one case")
        names = [c.name for c in self.cases]
        for i, n in enumerate(names):
            require(names.index(n) == i, f"cases[{i}].name", f"{n!r} appears twice")
        require(self.dx > 0 and abs(1.0 / self.dx - round(1.0 / self.dx)) < 1e-6, "dx",
                f"must divide the unit square into whole cells (1/dx integer), got {self.dx}")
        require(len(self.dtypes) > 0, "dtypes", "needs at least one precision")
        for i, d in enumerate(self.dtypes):
            require(d in DTYPES, f"dtypes[{i}]", f"{d!r} is not one of {list(DTYPES)}")
        require("float64" in self.dtypes, "dtypes", "float64 is the reference precision and must be listed")
        for i, d in enumerate(self.fig1_dtypes):
            require(d in self.dtypes, f"fig1_dtypes[{i}]", f"{d!r} is not one of dtypes {list(self.dtypes)}")
        require(self.warmup_steps >= 0, "warmup_steps", f"must be >= 0, got {self.warmup_steps}")
        require(self.loss_steps >= 1, "loss_steps", f"must be >= 1, got {self.loss_steps}")
        require(self.eps_factor > 0, "eps_factor", f"must be positive, got {self.eps_factor}")
        require(len(self.sweep_eps_factors) >= 2, "sweep_eps_factors", "needs at least two values")
        for i, e in enumerate(self.sweep_eps_factors):
            require(e > 0, f"sweep_eps_factors[{i}]", f"must be positive, got {e}")
        require(any(abs(e / self.eps_factor - 1) < 1e-9 for e in self.sweep_eps_factors), "sweep_eps_factors",
                f"must contain eps_factor ({self.eps_factor:g}) so the sweep shows the checked step")
        require(self.sweep_directions >= 1, "sweep_directions", f"must be >= 1, got {self.sweep_directions}")
        require(self.fd_chunk >= 1, "fd_chunk", f"must be >= 1, got {self.fd_chunk}")
        require(self.fd_vmap >= 1 and self.fd_chunk % self.fd_vmap == 0, "fd_vmap",
                f"must be >= 1 and divide fd_chunk ({self.fd_chunk}), got {self.fd_vmap}")
        require(self.extra_capacity >= 0, "extra_capacity", f"must be >= 0, got {self.extra_capacity}")
        require(self.wall_layers >= 1, "wall_layers", f"must be >= 1, got {self.wall_layers}")
        require(self.lid_velocity > 0, "lid_velocity", f"must be positive, got {self.lid_velocity}")

    @property
    def eps(self) -> float:
        """Finite-difference step of the main check, eps_factor * dx (paper: 1e-3 dx = 5e-5)."""
        return self.eps_factor * self.dx

    def numerics_for(self, dtype: str) -> sph.Numerics:
        """`numerics` with its dtype replaced by `dtype` (precision is chosen by `dtypes`)."""
        return replace(self.numerics, dtype=dtype)

    def case(self, name: str) -> Case:
        return next(c for c in self.cases if c.name == name)




# -- the runs -------------------------------------------------------------------------------------
@dataclass(frozen=True)
class CheckRun:
    """AD and FD gradients and the eps sweep of one case in one precision (Fig. 1)."""

    name: str
    case: Case
    dtype: str
    dx: float
    material: sph.Material
    numerics: sph.Numerics
    warmup_steps: int
    loss_steps: int
    eps_factor: float
    sweep_eps_factors: tuple[float, ...]
    sweep_directions: int
    seed: int
    extra_capacity: int
    wall_layers: int
    lid_velocity: float
    fd_chunk: int = field(default=64, **OUT)
    fd_vmap: int = field(default=1, **OUT)
    groups: tuple[str, ...] = field(default=("fig1",), **OUT)

    @property
    def eps(self) -> float:
        return self.eps_factor * self.dx


@dataclass(frozen=True)
class GrowthRun:
    """|d E_kin(n) / d r0| of one case after n_steps steps (growth)."""

    name: str
    case: Case
    dtype: str
    n_steps: int
    fd_check: bool
    dx: float
    material: sph.Material
    numerics: sph.Numerics
    eps_factor: float
    seed: int
    extra_capacity: int
    wall_layers: int
    lid_velocity: float
    groups: tuple[str, ...] = field(default=("growth",), **OUT)

    @property
    def eps(self) -> float:
        return self.eps_factor * self.dx


def _common(s: Settings, dtype: str) -> dict:
    return {"dx": s.dx, "material": s.material, "numerics": s.numerics_for(dtype), "eps_factor": s.eps_factor,
            "seed": s.seed, "extra_capacity": s.extra_capacity, "wall_layers": s.wall_layers,
            "lid_velocity": s.lid_velocity}


def check_runs(s: Settings) -> list:
    """Per case, per precision (in the order of `dtypes`)."""
    return [CheckRun(name=f"{c.name}_{d}", case=c, dtype=d, warmup_steps=s.warmup_steps, loss_steps=s.loss_steps,
                     sweep_eps_factors=s.sweep_eps_factors, sweep_directions=s.sweep_directions,
                     fd_chunk=s.fd_chunk, fd_vmap=s.fd_vmap, **_common(s, d))
            for c in s.cases for d in s.dtypes]


def growth_runs(s: Settings) -> list:
    """Per case, per rollout length of growth.steps."""
    g = s.growth
    return [GrowthRun(name=f"growth_{c.name}_n{n}", case=c, dtype=g.dtype, n_steps=n, fd_check=g.fd_check,
                      **_common(s, g.dtype))
            for c in s.cases for n in g.steps]


def runs(s: Settings) -> list:
    return check_runs(s) + growth_runs(s)


TABLE = Table(rows="metrics", file=lambda run: "metrics.csv" if isinstance(run, CheckRun) else "grad_growth.csv")
"""metrics.csv: one row per check run; grad_growth.csv: one row per growth run."""


def compute(run, folder: Path, progress: bool = True) -> dict:
    """The run's gradients (`check` or `growth`): the harness caches the returned mapping under its key."""
    return check(run, Path(folder)) if isinstance(run, CheckRun) else growth(run)


# -- scene and loss -------------------------------------------------------------------------------
def scene(run):
    """(Scene, Numerics) of the run's case on the run.dx lattice in the run's precision."""
    case = run.case
    if case.kind == "tgv":
        sc = tgv.scene(run.dx, run.material, case.effects)
    else:
        sc = ldc.scene(run.dx, run.material, case.effects, layers=run.wall_layers, lid_velocity=run.lid_velocity)
    return sc, run.numerics


def build(run) -> sph.Solver:
    """Solver of the run's case (`scene`)."""
    return sph.build_solver(*scene(run))


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


def check(run: CheckRun, folder: Path) -> dict:
    """AD and FD gradients and the eps sweep of one case in one precision -> folder/check.npz; returns
    the loss, step and timings."""
    case, dtype = run.case, run.dtype
    solver = build(run)
    fluid = fluid_index(solver)
    state0, _ = solver.init_fn()
    nbrs = solver.neighbors.allocate(state0.r, extra_capacity=run.extra_capacity)
    warm = jax.jit(lambda s, nb: scan_rollout(solver.step_fn, s, nb, run.warmup_steps))
    start, nbrs, overflow = warm(state0, nbrs) if run.warmup_steps else (state0, nbrs, False)
    _no_overflow(overflow, "the warm-up")
    loss = make_loss(solver, start, nbrs, run.loss_steps, step0=run.warmup_steps)
    r0 = start.r[fluid]

    l0, g_ad, ad_s, ad_compile_s = timed_gradient(loss, r0, "the AD evaluation")
    if not np.all(np.isfinite(g_ad)):
        print(f"{case.name} {dtype}: WARNING: {int(np.sum(~np.isfinite(g_ad)))} of {g_ad.size} AD gradient "
              f"entries are not finite (README: float32 walls)", flush=True)

    fd = make_fd(loss, r0, run.fd_vmap)
    rows = [(k, run.eps) for k in range(r0.size)]
    g_fd, fd_s, fd_compile_s = run_fd_rows(fd, rows, run.fd_chunk, r0.shape, solver.dtype, "the FD evaluations")
    g_fd = g_fd.reshape(r0.shape)

    rng = np.random.default_rng(run.seed)
    dirs = rng.normal(size=(run.sweep_directions, *r0.shape))
    dirs /= np.linalg.norm(dirs.reshape(len(dirs), -1), axis=1)[:, None, None]
    eps_list = [f * run.dx for f in run.sweep_eps_factors]
    sweep_rows = [(d, e) for e in eps_list for d in dirs]
    sweep, _, _ = run_fd_rows(fd, sweep_rows, run.fd_chunk, r0.shape, solver.dtype, "the eps sweep")
    sweep = sweep.reshape(len(eps_list), len(dirs))
    sweep_ad = np.einsum("kij,ij->k", dirs, g_ad)

    folder.mkdir(parents=True, exist_ok=True)
    np.savez(folder / CHECK_FILE, r=np.asarray(start.r, np.float64), tag=np.asarray(solver.scene.tag),
             fluid=fluid, g_ad=g_ad, g_fd=g_fd, loss=float(l0), dt=solver.dt, eps=run.eps,
             sweep_eps_factors=np.asarray(run.sweep_eps_factors), sweep_fd=sweep, sweep_ad=sweep_ad,
             ad_s=ad_s, ad_compile_s=ad_compile_s, fd_s=fd_s, fd_compile_s=fd_compile_s,
             n_fd_evals=2 * len(rows))
    err = np.linalg.norm(g_ad - g_fd) / np.linalg.norm(g_fd)
    print(f"{case.name} {dtype}: {len(fluid)} fluid / {solver.scene.n} particles, E_kin = {float(l0):.6g}, "
          f"|grad| = {np.linalg.norm(g_ad):.4g}, AD vs FD rel. L2 {err:.3g}; AD {ad_s:.2f} s, "
          f"FD ({2 * len(rows)} rollouts) {fd_s:.1f} s", flush=True)
    return {"loss": float(l0), "dt": float(solver.dt), "ad_s": float(ad_s), "fd_s": float(fd_s),
            "n_fd_evals": 2 * len(rows)}


def check_arrays(folder) -> dict:
    """The arrays of a check run (its check.npz)."""
    with np.load(Path(folder) / CHECK_FILE) as z:
        return {k: z[k] for k in z.files}


def _rel(a, b):
    """||a - b|| / ||b||: the error of `a` relative to the reference `b`."""
    return float(np.linalg.norm(a - b) / np.linalg.norm(b))


def _reference(run: CheckRun, folder: Path) -> dict:
    """The float64 check of the run's case (the reference: float64 AD), beside the run's folder."""
    return check_arrays(Path(folder).parent / f"{run.case.name}_float64")


def check_metrics(run: CheckRun, traj: dict) -> dict:
    """One row of metrics.csv: rel_l2 = ||g_AD - g_FD|| / ||g_FD||, max_abs = max |g_AD - g_FD|, mse =
    mean (g_AD - g_FD)^2 over all fluid coordinates, both in the row's precision; *_vs_ad64 against the
    float64 AD gradient."""
    z = check_arrays(traj["folder"])
    g64 = _reference(run, traj["folder"])["g_ad"]
    g_ad, g_fd, diff = z["g_ad"], z["g_fd"], z["g_ad"] - z["g_fd"]
    return {"case": run.case.name, "dtype": run.dtype, "dx": run.dx, "n_fluid": len(z["fluid"]),
            "n_particles": len(z["tag"]), "dt": float(z["dt"]), "warmup_steps": run.warmup_steps,
            "loss_steps": run.loss_steps, "eps": float(z["eps"]), "loss": float(z["loss"]),
            "grad_norm_ad": float(np.linalg.norm(g_ad)), "grad_norm_fd": float(np.linalg.norm(g_fd)),
            "rel_l2": _rel(g_ad, g_fd), "max_abs": float(np.max(np.abs(diff))),
            "mse": float(np.mean(diff**2)), "nonfinite_ad": int(np.sum(~np.isfinite(g_ad))),
            "ad_rel_l2_vs_ad64": _rel(g_ad, g64),
            "fd_rel_l2_vs_ad64": _rel(g_fd, g64), "ad_s": float(z["ad_s"]),
            "ad_compile_s": float(z["ad_compile_s"]), "fd_s": float(z["fd_s"]),
            "fd_compile_s": float(z["fd_compile_s"]), "n_fd_evals": int(z["n_fd_evals"])}


def sweep_rows(run: CheckRun, folder) -> list:
    """Rows of sweep.csv of one check run (one per eps): rel_l2 = ||FD_eps(d) - g64 . d|| / ||g64 . d||
    over the random directions d, the reference being the float64 AD gradient for every precision, so
    the curve shows the error of FD alone."""
    z = check_arrays(folder)
    sweep64 = _reference(run, folder)["sweep_ad"]
    return [{"case": run.case.name, "dtype": run.dtype, "eps_factor": float(f), "eps": f * run.dx,
             "rel_l2": _rel(fd_vals, sweep64), "max_abs": float(np.max(np.abs(fd_vals - sweep64))),
             "n_directions": len(fd_vals)}
            for f, fd_vals in zip(z["sweep_eps_factors"], z["sweep_fd"])]


# -- gradient norm against rollout length -----------------------------------------------------------
def growth(run: GrowthRun) -> dict:
    """|d E_kin(n) / d r0| at the initial positions, with gradient checkpointing over isqrt(n) segments."""
    n, case = run.n_steps, run.case
    solver = build(run)
    state0, _ = solver.init_fn()
    nbrs = solver.neighbors.allocate(state0.r, extra_capacity=run.extra_capacity)
    fluid = fluid_index(solver)
    segments = math.isqrt(n)
    loss = make_loss(solver, state0, nbrs, n, step0=0, segments=segments)
    r0 = state0.r[fluid]
    l0, g, wall, compile_s = timed_gradient(loss, r0, f"the {n}-step rollout")
    fd_err = np.nan
    if run.fd_check:
        d = np.random.default_rng(run.seed).normal(size=r0.shape)
        d = jnp.asarray(d / np.linalg.norm(d), r0.dtype)
        forward = jax.jit(loss)
        (lp, op), (lm, om) = forward(r0 + run.eps * d), forward(r0 - run.eps * d)
        _no_overflow(op | om, f"the {n}-step FD check")
        fd = (float(lp) - float(lm)) / (2 * run.eps)
        ad = float(np.vdot(g, np.asarray(d)))
        fd_err = abs(ad - fd) / max(abs(fd), 1e-300)
    row = {"case": case.name, "dtype": run.dtype, "n_steps": n, "t": float(n * solver.dt), "segments": segments,
           "loss": float(l0), "grad_norm": float(np.linalg.norm(g)), "grad_max": float(np.max(np.abs(g))),
           "fd_dir_relerr": float(fd_err), "wall_s": float(wall), "compile_s": float(compile_s)}
    print(f"{case.name} n = {n}: E_kin = {row['loss']:.4g}, |grad| = {row['grad_norm']:.4g}, "
          f"AD vs FD (direction) {fd_err:.2g}, {wall:.2f} s (+ {row['compile_s']:.1f} s compile)", flush=True)
    return row


def metrics(run, traj: dict) -> dict:
    """A check run's row of metrics.csv (`check_metrics`), a growth run's of grad_growth.csv (its result,
    with its key as `fingerprint`)."""
    if isinstance(run, CheckRun):
        return check_metrics(run, traj)
    return {**{k: traj["result"][k] for k in GROWTH_COLUMNS[:-1]}, "fingerprint": traj["key"]}
