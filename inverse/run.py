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

Writes results/<profile>/inverse/
  metrics.csv   long format: case, start, optimizer, iteration, loss, rmse_final, rmse_initial, wall_s, ...
                (iteration k: the loss at the positions after k updates; rmse_final = sqrt(loss))
  summary.csv   one row per (case, start, optimizer): final errors, mean wall time per iteration
  paths.npz     target initial / final states, every iterate r0_k and its final positions, walls
  run.json      fingerprint, dt, steps, timings

    python inverse/run.py --profile smoke [--results results/smoke]
"""
import json
import time
from dataclasses import dataclass, field
from typing import Callable

import jax
import jax.numpy as jnp
import numpy as np
import optax
import pandas as pd

import sph
from lab.configtools import to_mapping
from lab.keys import digest
from sph.diagnostics import SimulationError
from sph.rollout import scan_rollout
try:
    from . import scene as cube
    from . import settings as S
except ImportError:  # run as a script: its folder comes first on the import path (a copied folder works unchanged)
    import scene as cube
    import settings as S


@dataclass(frozen=True, eq=False)
class Problem:
    """The solver shared by every case (the cases differ only in the fluid positions, so one scene's
    masks and one compiled step serve all), and the two jitted functions of the fluid positions.

    value_and_grad(rf, target, nbrs)  -> ((loss, (overflowed, final fluid positions)), dL/drf)

    (the target rollouts use it too, with the gradient unused: one compiled function for the run)
    """

    exp: S.Experiment
    solver: sph.Solver
    template: sph.ParticleState
    n_fluid: int
    n_steps: int
    lo: float
    hi: float
    value_and_grad: Callable
    compiled: dict = field(default_factory=dict)  # (list pytree, capacity) -> compiled value_and_grad

    def full_positions(self, rf):
        return self.template.r.at[: self.n_fluid].set(rf)


def block_positions(exp: S.Experiment, origin) -> np.ndarray:
    return cube.block(origin, exp.cube_size, exp.dx, exp.layers)


def start_positions(exp: S.Experiment, start: S.Start) -> np.ndarray:
    """Initial guess of the optimizer, scene coordinates (n_fluid, 2)."""
    if start.kind == "cube":
        return block_positions(exp, start.origin)
    lo, hi = cube.interior_bounds(exp.dx, exp.layers, exp.box_size, start.margin)
    return np.random.default_rng(start.seed).uniform(lo, hi, size=(exp.n_fluid, 2))


_PROBLEMS = {}


def problem(exp: S.Experiment) -> Problem:
    """`build(exp)`, cached per profile settings, so that its compiled functions are reused."""
    key = digest(to_mapping(exp))
    if key not in _PROBLEMS:
        _PROBLEMS[key] = build(exp)
    return _PROBLEMS[key]


def build(exp: S.Experiment) -> Problem:
    fluid = block_positions(exp, exp.cases[0].origin)
    scene = cube.scene(exp.dx, exp.material, exp.effects, fluid, exp.u0, exp.box_size, exp.layers, name="inverse")
    solver = sph.build_solver(scene, exp.numerics)
    template, _ = solver.init_fn()
    nf, n_steps = len(fluid), solver.n_steps(exp.t_end)
    lo, hi = cube.interior_bounds(exp.dx, exp.layers, exp.box_size, exp.clip_margin)

    def rollout(rf, nbrs):
        """Final fluid positions after n_steps from fluid positions rf (walls and velocities fixed)."""
        r = template.r.at[:nf].set(rf)
        nbrs0 = solver.neighbors.update(r, nbrs)  # the list at r0 (same capacity; overflow is reported)
        state0 = solver.state_at(r, template.u, nbrs0)
        state, _, overflow = scan_rollout(solver.step_fn, state0, nbrs0, n_steps, segments=exp.segments)
        return state.r[:nf], overflow | nbrs0.did_buffer_overflow.astype(bool)

    def loss(rf, target, nbrs):
        final, overflow = rollout(rf, nbrs)
        return jnp.mean((final - target) ** 2), (overflow, final)

    return Problem(exp=exp, solver=solver, template=template, n_fluid=nf, n_steps=n_steps, lo=lo, hi=hi,
                   value_and_grad=jax.jit(jax.value_and_grad(loss, has_aux=True)))


class Evaluator:
    """Calls the jitted functions with a neighbour list that has room: compiles ahead (timed apart)
    for each list capacity, and on overflow re-allocates with twice the spare slots (+8) and redoes the call."""

    def __init__(self, prob: Problem, r_alloc):
        self.prob = prob
        self.extra = prob.exp.extra_capacity
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
        for _ in range(self.prob.exp.max_reallocations + 1):
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
        raise SimulationError(f"neighbour list still overflows after {self.prob.exp.max_reallocations} re-allocations, "
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


def make_optimizer(opt: S.Optimizer) -> optax.GradientTransformation:
    if opt.kind == "sgd":
        tx = optax.sgd(opt.learning_rate)
    else:
        tx = optax.adam(opt.learning_rate, b1=opt.b1, b2=opt.b2)
    return tx if opt.max_step is None else optax.chain(tx, optax.clip(opt.max_step))


def rms(a, b) -> float:
    return float(np.sqrt(np.mean((np.asarray(a) - np.asarray(b)) ** 2)))


def optimize(prob: Problem, ev: Evaluator, opt: S.Optimizer, r_start, target_initial, target_final):
    """`iterations` updates of optimizer `opt` from `r_start`: (rows, iterates (K+1, N, 2), finals)."""
    tx = make_optimizer(opt)
    x = jnp.asarray(r_start)
    opt_state = tx.init(x)
    target = jnp.asarray(target_final)
    rows, path, finals = [], [], []
    for k in range(prob.exp.iterations + 1):
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
        if k < prob.exp.iterations:
            if opt.loss == "rmse":
                grad = grad / (2.0 * np.sqrt(loss))
            updates, opt_state = tx.update(grad, opt_state, x)
            x = jnp.clip(optax.apply_updates(x, updates), prob.lo, prob.hi)
    return rows, np.stack(path), np.stack(finals)


def run_all(exp: S.Experiment, results, verbose: bool = True) -> pd.DataFrame:
    """Every (case, start, optimizer) of the profile; writes the outputs and returns the metrics."""
    out = S.out_dir(results)
    fp = S.fingerprint(exp)
    info = S.info_path(results)
    if info.exists() and S.metrics_path(results).exists() and S.paths_path(results).exists():
        if json.loads(info.read_text()).get("fingerprint") == fp:
            if verbose:
                print(f"inverse: complete with the same inputs, skipped ({S.metrics_path(results)})", flush=True)
            return pd.read_csv(S.metrics_path(results))
    t_all = time.perf_counter()
    prob = problem(exp)
    arrays = {"walls": np.asarray(prob.template.r[prob.n_fluid:]), "lo": prob.lo, "hi": prob.hi}
    ev = Evaluator(prob, block_positions(exp, exp.cases[0].origin))
    rows, target_s = [], {}
    for case in exp.cases:
        r_init = block_positions(exp, case.origin)
        t0 = time.perf_counter()
        c0 = ev.compile_s
        r_final = np.asarray(ev.rollout(jnp.asarray(r_init)))
        target_s[case.name] = time.perf_counter() - t0 - (ev.compile_s - c0)
        arrays[f"target_initial__{case.name}"], arrays[f"target_final__{case.name}"] = r_init, r_final
        for start in exp.starts:
            r_start = start_positions(exp, start)
            for opt in exp.optimizers:
                c0 = ev.compile_s
                run_rows, path, finals = optimize(prob, ev, opt, r_start, r_init, r_final)
                key = f"{case.name}__{start.name}__{opt.name}"
                arrays[f"path__{key}"], arrays[f"finals__{key}"] = path, finals
                for row in run_rows:
                    rows.append({"case": case.name, "start": start.name, "optimizer": opt.name, **row,
                                 "optimizer_kind": opt.kind, "objective": opt.loss,
                                 "learning_rate": opt.learning_rate, "n_steps": prob.n_steps,
                                 "dt": prob.solver.dt, "compile_s": ev.compile_s - c0})
                last = run_rows[-1]
                if verbose:
                    print(f"case {case.name}, {start.name} start, {opt.name} (lr {opt.learning_rate:g}): "
                          f"loss {run_rows[0]['loss']:.3e} -> {last['loss']:.3e}, RMSE final {last['rmse_final']:.4f}, "
                          f"initial {last['rmse_initial']:.4f}, {np.mean([r['wall_s'] for r in run_rows]):.2f} s/iter",
                          flush=True)
    table = pd.DataFrame(rows)
    out.mkdir(parents=True, exist_ok=True)
    table.to_csv(S.metrics_path(results), index=False)
    summarize(exp, table).to_csv(out / "summary.csv", index=False)
    np.savez(S.paths_path(results), **arrays)
    info.write_text(json.dumps({
        "fingerprint": fp, "dt": prob.solver.dt, "n_steps": prob.n_steps, "t_end": prob.n_steps * prob.solver.dt,
        "dt_limits": {k: float(v) for k, v in prob.solver.dt_limits.items()}, "n_particles": prob.solver.scene.n,
        "n_fluid": prob.n_fluid, "neighbor_capacity": int(ev.nbrs.idx.shape[1]),
        "n_reallocations": ev.n_reallocations, "compile_s": ev.compile_s, "target_rollout_s": target_s,
        "total_s": time.perf_counter() - t_all, "experiment": to_mapping(exp)}, indent=1, default=float))
    if verbose:
        print(f"inverse: {len(exp.cases) * len(exp.starts) * len(exp.optimizers)} optimizations of "
              f"{exp.iterations} steps ({prob.n_steps} SPH steps of dt {prob.solver.dt:.4g} each) in "
              f"{time.perf_counter() - t_all:.1f} s (compile {ev.compile_s:.1f} s) -> {S.metrics_path(results)}",
              flush=True)
    return table


def summarize(exp: S.Experiment, table: pd.DataFrame) -> pd.DataFrame:
    """One row per (case, start, optimizer): errors after the last update, best loss, time per iteration,
    and the paper's final RMSE for the case where the profile gives one."""
    targets = dict(zip([c.name for c in exp.cases], exp.rmse_targets))
    rows = []
    for (case, start, opt), g in table.groupby(["case", "start", "optimizer"], sort=False):
        g = g.sort_values("iteration")
        last = g.iloc[-1]
        rows.append({"case": case, "start": start, "optimizer": opt, "learning_rate": last["learning_rate"],
                     "iterations": int(last["iteration"]), "loss_initial": g["loss"].iloc[0],
                     "loss_final": last["loss"], "rmse_final": last["rmse_final"],
                     "rmse_initial": last["rmse_initial"], "best_rmse_final": g["rmse_final"].min(),
                     "wall_s_per_iteration": g["wall_s"].mean(), "paper_rmse_final": targets.get(case, np.nan),
                     "diverged": bool(not np.isfinite(last["loss"]))})
    out = pd.DataFrame(rows)
    out["below_paper"] = out["rmse_final"] < out["paper_rmse_final"]
    return out


if __name__ == "__main__":
    from lab.cli import experiment_main

    experiment_main(run_all, S.load, __doc__)
