"""Inverse problem of paper Fig. 2 (JAX-SPH, Toshev et al. 2024, Sec. 4.1): recover the initial
positions r0 of a falling block of water from its final positions.

For every case (block origin) the target is simulated forward to t_end; then, for every start
(a displaced block, or particles placed at random) and every optimizer (optax GD and Adam),

    L(r0) = 1 / (2 N) sum_i |r_i(t_end; r0) - r_i^target(t_end)|^2          (MSE over coordinates)

is minimized over the N fluid positions r0 by `iterations` optimizer updates (an optimizer with
`loss: rmse` descends sqrt(L) instead, as JAX-SPH's notebook does; the recorded loss is L). r_i(t_end; r0) is a
`jax.lax.scan` rollout of the full solver (`sph.rollout.scan_rollout`, gradient checkpointing over
`segments` segments) from the state `solver.state_at(r0, u0, nbrs)` that `init_fn` would build, so
`jax.value_and_grad` differentiates through every step of standard WCSPH with density evolution,
gravity and no-slip walls. Walls stay where they are; only the fluid rows of r0 are optimized.
After every update the fluid positions are clipped to at least `clip_margin` inside the wall faces
(a projection onto the box; the targets lie inside it); an optimizer may also clip each coordinate
of its update to `max_step` (a trust region: rollouts in which particles hit a wall have gradients
far larger than the translation estimate, and an unclipped GD step then throws particles onto the
box's corners, where coincident particles make the SPH sums undefined).

The neighbour list has fixed capacity inside `jit`: it is allocated once with `extra_capacity`
spare slots and rebuilt at each r0 inside the loss (`neighbors.update`); if a rollout overflows it
(at r0 or during the steps), the result is discarded, the list re-allocated with more room and the
evaluation redone, so an overflow never produces a wrong loss or gradient.

As a study of the protocol (lab.experiment) each (case, start, optimizer) is a run (`<case>-<start>-<optimizer>`)
whose work is `compute`, cached by the harness under the run's key in <results>/inverse/<run>/:
  result.json   the iteration rows: case, start, optimizer, iteration, loss, rmse_final, rmse_initial, wall_s, ...
                (iteration k: the loss at the positions after k updates; rmse_final = sqrt(loss)), dt, steps, timings
  paths.npz     the target's initial / final state, every iterate r0_k and its final positions, walls
and the table <results>/inverse/summary.csv (`metrics`): one row per run, final errors, mean wall time per
iteration. plot_fig2.py draws Fig. 2 and writes the iteration rows of every run as metrics.csv beside it.

The scene (a square block ("cube") of water falling in a closed box under gravity): box interior
[0, L] x [0, L] (L = 1 in the paper), framed by `layers` layers of no-slip wall particles (Adami 2012)
built with `sph.lattice.wall_layers`, as `sph.cases.tank` does; the whole scene is shifted by
`layers * dx` so that the walls lie inside the simulation box [0, L + 2 layers dx). The block fills
[origin, origin + size]^2 of the interior with a cell-centred lattice (size 0.3 at dx = 0.05: 6 x 6 = 36
particles) and starts with a uniform velocity u0 (the paper: (0, -0.5)). Positions handed to or returned by
the scene functions are in *scene* coordinates (walls included); `offset(dx, layers)` converts interior
coordinates (the paper's) to scene coordinates.

    python -m lab.experiment inverse --profile smoke [--results results/smoke]
"""
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Optional

import jax
import jax.numpy as jnp
import numpy as np
import optax
import pandas as pd

import sph
from lab.configtools import require, require_agree, require_finite, to_mapping
from lab.keys import digest
from lab.protocol import Table
from sph.config import Effects, Material
from sph.domain import Domain
from sph.errors import SimulationError
from sph.lattice import cartesian, wall_layers
from sph.rollout import scan_rollout
from sph.scene import Scene
from sph.state import FLUID, WALL

START_KINDS = ("cube", "random")
OPTIMIZER_KINDS = ("sgd", "adam")
LOSSES = ("mse", "rmse")
PATHS = "paths.npz"
OUT = {"metadata": {"key": False}}
"""A field out of a run's key: it only judges or reports a result."""
ROW_COLUMNS = ["case", "start", "optimizer", "iteration", "loss", "rmse_final", "rmse_initial", "wall_s",
               "n_reallocations", "optimizer_kind", "objective", "learning_rate", "n_steps", "dt", "compile_s"]
"""The columns of an iteration row (fig2/metrics.csv)."""


@dataclass(frozen=True)
class Case:
    """A target simulation: the block's lower-left corner `origin` in interior coordinates ([0, L]^2)."""

    name: str
    origin: tuple[float, ...]

    def __post_init__(self):
        require(len(self.origin) == 2, "origin", f"expected 2 entries (x, y), got {len(self.origin)}")


@dataclass(frozen=True)
class Start:
    """Where the optimizer starts.

    kind    "cube": the block at `origin` (interior coordinates), same particle order as the target;
            "random": every particle uniform in [margin, L - margin]^2, seeded by `seed`
    """

    name: str
    kind: str
    origin: Optional[tuple[float, ...]] = None
    seed: int = 0
    margin: float = 0.15

    def __post_init__(self):
        require(self.kind in START_KINDS, "kind", f"{self.kind!r} is not one of {START_KINDS}")
        require(self.kind != "cube" or self.origin is not None, "origin",
                f"start {self.name!r} of kind 'cube' needs an origin")
        require(self.origin is None or len(self.origin) == 2, "origin",
                f"expected 2 entries (x, y), got {len(self.origin or ())}")
        require(self.margin >= 0, "margin", f"must be >= 0, got {self.margin}")


@dataclass(frozen=True)
class Optimizer:
    """An optax optimizer: kind "sgd" (plain gradient descent) or "adam", constant learning rate.

    loss      the objective it descends: "mse" (mean squared error of the final positions, the
              default) or "rmse" (its square root, as JAX-SPH's notebook does; gradient
              dRMSE = dMSE / (2 RMSE)). The recorded loss is the MSE either way.
    max_step  clip every coordinate of an update to [-max_step, max_step] (optax.clip; a trust region
              against the large gradients of rollouts in which particles hit a wall); null = none
    """

    name: str
    kind: str
    learning_rate: float
    b1: float = 0.9
    b2: float = 0.999
    loss: str = "mse"
    max_step: Optional[float] = None

    def __post_init__(self):
        require(self.kind in OPTIMIZER_KINDS, "kind", f"{self.kind!r} is not one of {OPTIMIZER_KINDS}")
        require(self.learning_rate > 0, "learning_rate", f"must be positive, got {self.learning_rate}")
        require(0 <= self.b1 < 1 and 0 <= self.b2 < 1, "b1", "b1 and b2 must lie in [0, 1)")
        require(self.loss in LOSSES, "loss", f"{self.loss!r} is not one of {LOSSES}")
        require(self.max_step is None or self.max_step > 0, "max_step", f"must be positive or null, got {self.max_step}")


@dataclass(frozen=True)
class Settings:
    """One profile (see config.yaml for the meaning of each key)."""

    cases: tuple[Case, ...]
    starts: tuple[Start, ...]
    optimizers: tuple[Optimizer, ...]
    t_end: float
    iterations: int
    dx: float = 0.05
    box_size: float = 1.0
    layers: int = 3
    cube_size: float = 0.3
    u0: tuple[float, ...] = (0.0, -0.5)
    material: sph.Material = field(default_factory=sph.Material)
    effects: sph.Effects = field(default_factory=sph.Effects)
    numerics: sph.Numerics = field(default_factory=sph.Numerics)
    segments: int = 0
    clip_margin: float = 0.025
    extra_capacity: int = 16
    max_reallocations: int = 5
    path_optimizer: str = "gd"
    rmse_targets: tuple[float, ...] = ()

    def __post_init__(self):
        require_finite(self)
        require(self.dx > 0, "dx", f"must be positive, got {self.dx}")
        require(len(self.u0) == 2, "u0", f"expected 2 entries (x, y), got {len(self.u0)}")
        n_side = self.cube_size / self.dx
        require_agree(self.cube_size > 0 and abs(n_side - round(n_side)) < 1e-6, ("cube_size", "dx"),
                      f"must be a positive multiple of dx = {self.dx}, got {self.cube_size}")
        n_box = self.box_size / self.dx
        require_agree(abs(n_box - round(n_box)) < 1e-6, ("box_size", "dx"),
                      f"must be a multiple of dx = {self.dx}, got {self.box_size}")
        require(self.layers >= 1, "layers", f"must be >= 1, got {self.layers}")
        require(len(self.cases) > 0, "cases", "needs at least one case")
        require(len(self.starts) > 0, "starts", "needs at least one start")
        require(len(self.optimizers) > 0, "optimizers", "needs at least one optimizer")
        for what, items in (("cases", self.cases), ("starts", self.starts), ("optimizers", self.optimizers)):
            names = [x.name for x in items]
            for i, n in enumerate(names):
                require(names.index(n) == i, f"{what}[{i}].name", f"{n!r} appears twice")
        for i, c in enumerate(self.cases):
            self._check_block(c.origin, f"cases[{i}].origin")
        for i, s in enumerate(self.starts):
            if s.kind == "cube":
                self._check_block(s.origin, f"starts[{i}].origin")
            else:
                require(2 * s.margin < self.box_size, f"starts[{i}].margin",
                        f"leaves no room in a box of side {self.box_size}")
        require(self.t_end > 0, "t_end", f"must be positive, got {self.t_end}")
        require(self.iterations >= 1, "iterations", f"must be >= 1, got {self.iterations}")
        require(self.segments >= 0, "segments", f"must be >= 0 (0 = no checkpointing), got {self.segments}")
        require(0 <= self.clip_margin < self.box_size / 2, "clip_margin", f"must lie in [0, box_size / 2), got {self.clip_margin}")
        require(self.extra_capacity >= 0, "extra_capacity", f"must be >= 0, got {self.extra_capacity}")
        require(self.max_reallocations >= 1, "max_reallocations", f"must be >= 1, got {self.max_reallocations}")
        require(self.effects.walls is not None, "effects.walls", "the block falls in a walled box: declare walls")
        require(self.path_optimizer in [o.name for o in self.optimizers], "path_optimizer",
                f"{self.path_optimizer!r} is not one of the optimizers {[o.name for o in self.optimizers]}")
        require(len(self.rmse_targets) in (0, len(self.cases)), "rmse_targets",
                f"needs one value per case ({len(self.cases)}) or none")

    def _check_block(self, origin, key):
        o = np.asarray(origin, float)
        require_agree(np.all(o >= 0) and np.all(o + self.cube_size <= self.box_size + 1e-12),
                      (key, "cube_size", "box_size"),
                      f"the block at {list(origin)} of side cube_size = {self.cube_size} does not fit into the box "
                      f"[0, {self.box_size}]^2")

    @property
    def n_fluid(self) -> int:
        return int(round(self.cube_size / self.dx)) ** 2

    def case(self, name: str) -> Case:
        return next(c for c in self.cases if c.name == name)




# -- the runs -------------------------------------------------------------------------------------
PROBLEM_FIELDS = ("alloc_origin", "t_end", "dx", "box_size", "layers", "cube_size", "u0", "material", "effects",
                  "numerics", "segments", "clip_margin", "extra_capacity", "max_reallocations")
"""The fields of a run that make its Problem (the solver and the compiled loss): the same for every run of a profile."""


@dataclass(frozen=True)
class Run:
    """One optimization: `optimizer` from `start` towards the final positions of `case`'s target. The
    neighbour list is allocated at the block at `alloc_origin` (the first case's, for every run)."""

    name: str
    case: Case
    start: Start
    optimizer: Optimizer
    iterations: int
    alloc_origin: tuple[float, ...]
    t_end: float
    dx: float
    box_size: float
    layers: int
    cube_size: float
    u0: tuple[float, ...]
    material: sph.Material
    effects: sph.Effects
    numerics: sph.Numerics
    segments: int
    clip_margin: float
    extra_capacity: int
    max_reallocations: int
    paper_rmse_final: Optional[float] = field(default=None, **OUT)

    @property
    def n_fluid(self) -> int:
        return int(round(self.cube_size / self.dx)) ** 2


def runs(s: Settings) -> list:
    """Per case, per start, per optimizer (the order of config.yaml)."""
    targets = dict(zip([c.name for c in s.cases], s.rmse_targets))
    common = {k: getattr(s, k) for k in PROBLEM_FIELDS if k != "alloc_origin"}
    return [Run(name=f"{c.name}-{st.name}-{o.name}", case=c, start=st, optimizer=o, iterations=s.iterations,
                alloc_origin=s.cases[0].origin, paper_rmse_final=targets.get(c.name), **common)
            for c in s.cases for st in s.starts for o in s.optimizers]


TABLE = Table(rows="metrics", file=lambda run: "summary.csv")
"""summary.csv: one row per run (`metrics`)."""


# -- the scene ------------------------------------------------------------------------------------
def offset(dx: float, layers: int) -> float:
    """Shift between interior coordinates ([0, L]^2, the paper's) and scene coordinates."""
    return layers * dx


def block(origin, size: float, dx: float, layers: int) -> np.ndarray:
    """Cell-centred lattice of the block [origin, origin + size]^2 (interior coordinates), returned in
    scene coordinates: (n_side^2, 2), n_side = size / dx."""
    lo = np.asarray(origin, float) + offset(dx, layers)
    return cartesian(lo, lo + size, dx)


def box_scene(dx: float, material: Material, effects: Effects, fluid: np.ndarray, u0, box_size: float = 1.0,
          layers: int = 3, name: str = "cube_fall") -> Scene:
    """Fluid particles at `fluid` (scene coordinates, (n, 2)) with velocity `u0`, inside the walled box."""
    off = offset(dx, layers)
    lo, hi = np.array([off, off]), np.array([off + box_size, off + box_size])
    wall, normal = wall_layers(lo, hi, dx, layers)
    fluid = np.asarray(fluid, float)
    r = np.concatenate([fluid, wall])
    tag = np.concatenate([np.full(len(fluid), FLUID), np.full(len(wall), WALL)]).astype(np.int32)
    u = np.zeros_like(r)
    u[: len(fluid)] = np.asarray(u0, float)
    nrm = np.concatenate([np.zeros_like(fluid), normal])
    side = box_size + 2 * off
    return Scene(name=name, dx=dx, domain=Domain(box=(side, side), periodic=(False, False)), material=material,
                 effects=effects, r=r, u=u, tag=tag, normal=nrm)


def interior_bounds(dx: float, layers: int, box_size: float = 1.0, margin: float = 0.0):
    """(lo, hi) of the fluid region in scene coordinates, shrunk by `margin` on every side."""
    off = offset(dx, layers)
    return off + margin, off + box_size - margin


def scene(run: Run):
    """(Scene, Numerics) of the run's target: the block at the case's origin in the walled box."""
    fluid = block_positions(run, run.case.origin)
    return box_scene(run.dx, run.material, run.effects, fluid, run.u0, run.box_size, run.layers,
                     name="inverse"), run.numerics


# -- the differentiable rollout -------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class Problem:
    """The solver shared by every run of a profile (the runs differ only in the fluid positions, so one
    scene's masks and one compiled step serve all), and the jitted function of the fluid positions.

    value_and_grad(rf, target, nbrs)  -> ((loss, (overflowed, final fluid positions)), dL/drf)

    (the target rollouts use it too, with the gradient unused: one compiled function for the process)
    """

    solver: sph.Solver
    template: sph.ParticleState
    n_fluid: int
    n_steps: int
    lo: float
    hi: float
    extra_capacity: int
    max_reallocations: int
    value_and_grad: Callable
    compiled: dict = field(default_factory=dict)  # (list pytree, capacity) -> compiled value_and_grad

    def full_positions(self, rf):
        return self.template.r.at[: self.n_fluid].set(rf)


def block_positions(run: Run, origin) -> np.ndarray:
    return block(origin, run.cube_size, run.dx, run.layers)


def start_positions(run: Run, start: Start) -> np.ndarray:
    """Initial guess of the optimizer, scene coordinates (n_fluid, 2)."""
    if start.kind == "cube":
        return block_positions(run, start.origin)
    lo, hi = interior_bounds(run.dx, run.layers, run.box_size, start.margin)
    return np.random.default_rng(start.seed).uniform(lo, hi, size=(run.n_fluid, 2))


_PROBLEMS = {}


def problem(run: Run) -> Problem:
    """`build(run)`, cached per problem settings (PROBLEM_FIELDS), so that its compiled functions are reused."""
    key = digest({k: to_mapping(getattr(run, k)) for k in PROBLEM_FIELDS})
    if key not in _PROBLEMS:
        _PROBLEMS[key] = build(run)
    return _PROBLEMS[key]


def build(run: Run) -> Problem:
    fluid = block_positions(run, run.alloc_origin)
    sc = box_scene(run.dx, run.material, run.effects, fluid, run.u0, run.box_size, run.layers, name="inverse")
    solver = sph.build_solver(sc, run.numerics)
    template, _ = solver.init_fn()
    nf, n_steps = len(fluid), solver.n_steps(run.t_end)
    lo, hi = interior_bounds(run.dx, run.layers, run.box_size, run.clip_margin)
    segments = run.segments

    def rollout(rf, nbrs):
        """Final fluid positions after n_steps from fluid positions rf (walls and velocities fixed)."""
        r = template.r.at[:nf].set(rf)
        nbrs0 = solver.neighbors.update(r, nbrs)  # the list at r0 (same capacity; overflow is reported)
        state0 = solver.state_at(r, template.u, nbrs0)
        state, _, overflow = scan_rollout(solver.step_fn, state0, nbrs0, n_steps, segments=segments)
        return state.r[:nf], overflow | nbrs0.did_buffer_overflow.astype(bool)

    def loss(rf, target, nbrs):
        final, overflow = rollout(rf, nbrs)
        return jnp.mean((final - target) ** 2), (overflow, final)

    return Problem(solver=solver, template=template, n_fluid=nf, n_steps=n_steps, lo=lo, hi=hi,
                   extra_capacity=run.extra_capacity, max_reallocations=run.max_reallocations,
                   value_and_grad=jax.jit(jax.value_and_grad(loss, has_aux=True)))


class Evaluator:
    """Calls the jitted functions with a neighbour list that has room: compiles ahead (timed apart)
    for each list capacity, and on overflow re-allocates with twice the spare slots (+8) and redoes the call."""

    def __init__(self, prob: Problem, r_alloc):
        self.prob = prob
        self.extra = prob.extra_capacity
        self.nbrs = prob.solver.neighbors.allocate(prob.full_positions(jnp.asarray(r_alloc)), extra_capacity=self.extra)
        self.compile_s = 0.0
        self.n_reallocations = 0

    def _compiled(self, rf, target):
        # a re-allocated list is a new pytree (jax-md makes new cell-list functions): compile for it
        key = (jax.tree_util.tree_structure(self.nbrs), self.nbrs.idx.shape)
        if key not in self.prob.compiled:
            t0 = time.perf_counter()
            self.prob.compiled[key] = self.prob.value_and_grad.lower(rf, target, self.nbrs).compile()
            self.compile_s += time.perf_counter() - t0
        return self.prob.compiled[key]

    def value_and_grad(self, rf, target):
        """(loss, final fluid positions, dL/drf) at fluid positions `rf`, from a rollout that did not
        overflow its neighbour list (re-allocating and redoing it if it did)."""
        rf, target = jnp.asarray(rf), jnp.asarray(target)
        for _ in range(self.prob.max_reallocations + 1):
            (loss, (overflow, final)), grad = self._compiled(rf, target)(rf, target, self.nbrs)
            if not bool(overflow) or not bool(jnp.isfinite(loss)):
                # a non-finite rollout overflows any list (NaN positions fill no cell): the caller
                # records the optimization as diverged instead of re-allocating for ever
                return loss, final, grad
            self.n_reallocations += 1
            # geometric growth: an optimizer step can pile particles up (a random start falling onto the
            # floor), so the list may need many times its spare slots at once (+16 per try was not enough)
            self.extra = 2 * self.extra + 8
            self.nbrs = self.prob.solver.neighbors.allocate(self.prob.full_positions(rf), extra_capacity=self.extra)
        raise SimulationError(f"neighbour list still overflows after {self.prob.max_reallocations} re-allocations, "
                              f"the rollout finite (min. final spacing {_min_spacing(final):.3g}) "
                              f"(extra capacity {self.extra})")

    def rollout(self, rf):
        """Final fluid positions of the rollout from `rf`."""
        return self.value_and_grad(rf, jnp.zeros_like(jnp.asarray(rf)))[1]


def _min_spacing(r) -> float:
    """Smallest distance between two of the positions `r` (N, dim)."""
    r = np.asarray(r)
    d = np.linalg.norm(r[:, None] - r[None], axis=-1) + np.diag(np.full(len(r), np.inf))
    return float(d.min())


def make_optimizer(opt: Optimizer) -> optax.GradientTransformation:
    if opt.kind == "sgd":
        tx = optax.sgd(opt.learning_rate)
    else:
        tx = optax.adam(opt.learning_rate, b1=opt.b1, b2=opt.b2)
    return tx if opt.max_step is None else optax.chain(tx, optax.clip(opt.max_step))


def rms(a, b) -> float:
    return float(np.sqrt(np.mean((np.asarray(a) - np.asarray(b)) ** 2)))


def optimize(prob: Problem, ev: Evaluator, opt: Optimizer, iterations: int, r_start, target_initial, target_final):
    """`iterations` updates of optimizer `opt` from `r_start`: (rows, iterates (K+1, N, 2), finals)."""
    tx = make_optimizer(opt)
    x = jnp.asarray(r_start)
    opt_state = tx.init(x)
    target = jnp.asarray(target_final)
    rows, path, finals = [], [], []
    for k in range(iterations + 1):
        t0 = time.perf_counter()
        c0, n0 = ev.compile_s, ev.n_reallocations
        loss, final, grad = ev.value_and_grad(x, target)
        grad.block_until_ready()
        wall = time.perf_counter() - t0 - (ev.compile_s - c0)
        loss = float(loss)
        if not np.isfinite(loss) or not np.all(np.isfinite(np.asarray(grad))):
            # a diverged optimization is recorded as such (loss NaN from here on) and stopped
            print(f"warning: {opt.name}: loss or gradient not finite at iteration {k}; stopped", flush=True)
            rows.append({"iteration": k, "loss": np.nan, "rmse_final": np.nan,
                         "rmse_initial": rms(x, target_initial), "wall_s": wall,
                         "n_reallocations": ev.n_reallocations - n0})
            break
        rows.append({"iteration": k, "loss": loss, "rmse_final": float(np.sqrt(loss)),
                     "rmse_initial": rms(x, target_initial), "wall_s": wall,
                     "n_reallocations": ev.n_reallocations - n0})
        path.append(np.asarray(x))
        finals.append(np.asarray(final))
        if k < iterations:
            if opt.loss == "rmse":
                grad = grad / (2.0 * np.sqrt(loss))
            updates, opt_state = tx.update(grad, opt_state, x)
            x = jnp.clip(optax.apply_updates(x, updates), prob.lo, prob.hi)
    return rows, np.stack(path), np.stack(finals)


def compute(run: Run, folder: Path, progress: bool = True) -> dict:
    """The target's rollout, then `iterations` updates of the run's optimizer from its start: the
    arrays to folder/paths.npz; returns the iteration rows (ROW_COLUMNS) and the run's facts."""
    t_all = time.perf_counter()
    prob = problem(run)
    ev = Evaluator(prob, block_positions(run, run.alloc_origin))
    r_init = block_positions(run, run.case.origin)
    t0 = time.perf_counter()
    c0 = ev.compile_s
    r_final = np.asarray(ev.rollout(jnp.asarray(r_init)))
    target_s = time.perf_counter() - t0 - (ev.compile_s - c0)
    opt = run.optimizer
    c0 = ev.compile_s
    run_rows, path, finals = optimize(prob, ev, opt, run.iterations, start_positions(run, run.start), r_init, r_final)
    rows = [{"case": run.case.name, "start": run.start.name, "optimizer": opt.name, **row,
             "optimizer_kind": opt.kind, "objective": opt.loss, "learning_rate": opt.learning_rate,
             "n_steps": prob.n_steps, "dt": prob.solver.dt, "compile_s": ev.compile_s - c0} for row in run_rows]
    Path(folder).mkdir(parents=True, exist_ok=True)
    np.savez(Path(folder) / PATHS, walls=np.asarray(prob.template.r[prob.n_fluid:]), lo=prob.lo, hi=prob.hi,
             target_initial=r_init, target_final=r_final, path=path, finals=finals)
    last = run_rows[-1]
    print(f"case {run.case.name}, {run.start.name} start, {opt.name} (lr {opt.learning_rate:g}): "
          f"loss {run_rows[0]['loss']:.3e} -> {last['loss']:.3e}, RMSE final {last['rmse_final']:.4f}, "
          f"initial {last['rmse_initial']:.4f}, {np.mean([r['wall_s'] for r in run_rows]):.2f} s/iter",
          flush=True)
    return {"rows": [{k: r[k] for k in ROW_COLUMNS} for r in rows], "dt": float(prob.solver.dt),
            "n_steps": int(prob.n_steps), "t_end": float(prob.n_steps * prob.solver.dt),
            "dt_limits": {k: float(v) for k, v in prob.solver.dt_limits.items()}, "n_particles": int(prob.solver.scene.n),
            "n_fluid": int(prob.n_fluid), "neighbor_capacity": int(ev.nbrs.idx.shape[1]),
            "n_reallocations": int(ev.n_reallocations), "compile_s": float(ev.compile_s),
            "target_rollout_s": float(target_s), "total_s": time.perf_counter() - t_all}


def iteration_rows(traj: dict) -> pd.DataFrame:
    """The run's iteration rows (ROW_COLUMNS), from its result."""
    return pd.DataFrame(traj["result"]["rows"], columns=ROW_COLUMNS)


def paths(folder) -> dict:
    """The arrays of a run (its paths.npz)."""
    with np.load(Path(folder) / PATHS) as z:
        return {k: z[k] for k in z.files}


def metrics(run: Run, traj: dict) -> dict:
    """The run's row of summary.csv: errors after the last update, best loss, time per iteration, and the
    paper's final RMSE for the case where the profile gives one."""
    g = iteration_rows(traj).sort_values("iteration")
    last = g.iloc[-1]
    paper = np.nan if run.paper_rmse_final is None else run.paper_rmse_final
    return {"case": run.case.name, "start": run.start.name, "optimizer": run.optimizer.name,
            "learning_rate": last["learning_rate"], "iterations": int(last["iteration"]),
            "loss_initial": g["loss"].iloc[0], "loss_final": last["loss"], "rmse_final": last["rmse_final"],
            "rmse_initial": last["rmse_initial"], "best_rmse_final": g["rmse_final"].min(),
            "wall_s_per_iteration": g["wall_s"].mean(), "paper_rmse_final": paper,
            "diverged": bool(not np.isfinite(last["loss"])), "below_paper": bool(last["rmse_final"] < paper)}
