"""Accuracy against cost on RPF 2D (issue 12, beyond the paper): MSE_20 of 20-step test rollouts
(LagrangeBench's metrics, as sitl/evaluate.py) against the inference time of one coarse step, for
the fine solver, the solver alone at several temporal coarsenings, GNS and SitL.

Definitions. The dataset stores every W-th step (W = data.write_every) of our SPH run at dt
(data.dt), so one coarse step, a stored frame and LagrangeBench's step, is Delta t = W dt.

  temporal coarsening M   the number of fine steps dt one solver substep stands for: the solver
                          alone at coarsening M advances each Delta t in L = W / M substeps of
                          M dt (model.py's module, correction off, substeps = L). M must divide W
                          (settings.Cost): M > W would be a step longer than a frame.
  solver M                the points of cost.coarsening, plus M = W / model.substeps (Table 1's
                          "solver only": the substep SitL corrects) if not among them. Like every
                          model here it starts from LagrangeBench's two input frames with the
                          frame-averaged velocity u = d(r^0, r^-1) / Delta t.
  fine solver             the data's own integrator (sph step_fn: standard SPH, symplectic Euler)
                          at the data's dt, W steps per frame, in float32, started consistently:
                          u(t0) = d(r^0, r^-1) / Delta t + (Delta t / 2)(1 - 1 / W) a(r^0), exact
                          for the data's symplectic Euler when the acceleration a is constant over
                          a frame. Its MSE_20 is the floor: what two stored frames cannot tell about
                          the state (the acceleration's variation within a frame), float32 round-off
                          and chaotic growth. The solver at M = 1 is the same integrator started
                          with the frame-averaged velocity, which lags by (Delta t / 2) a: the gap
                          between the two is that start-up error alone.
  SitL                    L = model.substeps corrected substeps: M = W / L.
  GNS                     one network step per frame, standing for W fine steps: M = W.

Accuracy: 20-step rollouts from the first eval.n_trajs windows of test.h5, as LagrangeBench's
`infer` makes them (case.preprocess_eval: features and the graph neighbour list, re-allocated on
overflow; the model; case.integrate; kinematic particles from the data), scored by its
MetricsComputer and averaged by its `averaged_metrics`: MSE_5, MSE_20 (its `loss`), MSE_Ekin. The
rollout loop is this script's, so that the one jitted step that makes the rollouts is also the one
timed; it reproduces evaluate.py's numbers (`infer`'s) to float32 round-off: the L = model.substeps
solver point matches metrics/solver.json to 1e-5 relative.

Cost: inference time per coarse step, that jitted step (features, graph list, model, integration)
from a test input, after compilation; every point is timed in each of cost.repeats interleaved
rounds, so that the load of a shared machine falls on all alike; the median over rounds (the
minimum is kept as ms_min). evaluate.py's Table-1 number times the model call alone, without
GNS's graph construction.

Trained models are never trained here: GNS / SitL appear when evaluate.py's metrics/<kind>.json
exists and belongs to the current checkpoint (train.json complete, with the fingerprint train.py
would compute now; the metrics' training steps and best step equal to its). Their MSE values are
read from it, their time is measured here from ckp/<kind>/best. Otherwise they are left out, with
the reason printed.

Writes results/<profile>/sitl/cost.csv, cost.md (the same points as a table, which the READMEs
show), cost.png (log-log MSE_20 against ms per coarse step) and a run record per point,
sitl/cost/<name>/record.json (lab.record's schema: experiment "sitl", err_mse20, err_mse5,
err_e_kin; wall_s is one 20-step rollout, 20 x the time per coarse step, ms_per_step the time per
coarse step), which `make accuracy` gathers. cost.json keeps the inputs' key: a call with
the same inputs (data, config, code, trained models' metrics) does nothing.

    .venv-lb/bin/python sitl/cost.py --profile smoke [--results results/smoke] [--force]
"""
import dataclasses
import json
import math
import os
import shutil
import time
from pathlib import Path
from typing import Optional

import haiku as hk
import jax
import jax.numpy as jnp
import numpy as np

# LagrangeBench (sitl.common, then lagrangebench.*) is imported only when something is measured:
# its import takes ~10 s, the up-to-date check of an unchanged call none
from sitl import generate
from sitl import integrity
from sitl import model as M
from sitl import settings as S
from lab import keys, runs, stamp
from lab.atomic import write_text
from lab.tables import write_table
from lab.cli import profile_main
from lab.configtools import to_mapping
from lab.deliver import note_input
from lab.keys import digest
from lab.other_load import OtherLoad
from lab.record import RECORD_COLUMNS, save_record

HERE = Path(__file__).resolve().parent
CODE = [HERE / f for f in ("cost.py", "model.py", "common.py", "evaluate.py", "settings.py")]
"""The code the plane's numbers come from. Not study.py: the plane reads of the study only its points
(their names, M and L, in the key) and the trained models' records (in the key too), so editing the
study's table or adding a study run of another kind measures nothing again."""
TRAINED = ("gns", "sitl")
KEYS = {"mse5": "val/mse5", "mse20": "val/loss", "e_kin": "val/e_kin"}
STYLE = {"fine": ("*", "C3"), "solver": ("o", "C0"), "gns": ("^", "C2"), "sitl": ("D", "C1")}
COLUMNS = ["name", "kind", "method", "M", "substeps", "substep_dt", "substep_over_cfl", "mse5", "mse20", "e_kin",
           "std_mse20", "finite", "ms_per_coarse_step", "ms_min", "other_load", "compile_s", "n_rollouts", "source"]


@dataclasses.dataclass(frozen=True)
class Point:
    """One point of the plane: `name` is its folder under sitl/cost/, M its temporal coarsening,
    substeps the SPH substeps per coarse step (None for GNS)."""

    name: str
    kind: str
    method: str
    M: float
    substeps: Optional[int]
    study_run: Optional[str] = None   # a trained model of `make sitl-study` (sitl/study.py's run name)


def _m(x: float) -> str:
    return f"{x:.3g}"


def points(exp: S.Experiment) -> list:
    """The fine solver, the solver alone at each configured M (and at SitL's substep), GNS, SitL, and
    the study's coarse SitL (study.substeps: L substeps per frame, M = W / L) and SitL with
    pushforward (study.pushforward.substeps)."""
    w, lsitl = exp.data.write_every, exp.model.substeps
    out = [Point("fine", "fine", "fine solver", 1.0, w)]
    for m in sorted(exp.cost.coarsening):
        out.append(Point(f"solver_M{m}", "solver", f"solver M={m}", float(m), w // m))
    if lsitl not in [p.substeps for p in out if p.kind == "solver"]:
        out.append(Point(f"solver_L{lsitl}", "solver", f"solver M={_m(w / lsitl)} (L={lsitl}, as SitL)",
                         w / lsitl, lsitl))
    out.append(Point("gns", "gns", "GNS", float(w), None))
    out.append(Point("sitl", "sitl", f"SitL (L={lsitl})", w / lsitl, lsitl))
    from sitl import study

    for r in study.runs(exp):  # the study's own names: its coarse SitL, then SitL with pushforward
        if r.kind == "sitl" and r.group in ("coarse", "pushforward"):
            n = r.overrides["model"]["substeps"]
            tag = ", pushforward" if r.group == "pushforward" else ""
            out.append(Point(r.name, "sitl", f"SitL (L={n}{tag}, study)", w / n, n, study_run=r.name))
    return out


def trained_run(exp: S.Experiment, profile: str, results, p: Point):
    """(experiment, results folder) of a trained point: Table 1's, or the study's run `p.study_run`."""
    if p.study_run is None:
        return exp, Path(results)
    from sitl import study

    run = {r.name: r for r in study.runs(exp)}[p.study_run]
    rexp = study.run_experiment(profile, exp, run)
    return rexp, study.study_dir(results) / "runs" / run.name


def trained_status(exp: S.Experiment, results, kind: str, metadata_text: str):
    """(metrics dict, None) when evaluate.py's metrics of `kind` belong to its current checkpoint,
    else (None, why not)."""
    mpath, ckp = S.metrics_path(results, kind), S.ckpt_dir(results, kind)
    side = ckp / "train.json"
    note_input(mpath, side)
    if not mpath.exists():
        return None, f"no {mpath} (make table1 / make sitl-study trains and evaluates it)"
    if not side.exists() or not (ckp / "best" / "params_tree.pkl").exists():
        return None, f"no trained checkpoint in {ckp}"
    bad = integrity.unreadable_checkpoint(ckp / "best")
    rec, met = (_json_or_none(q) for q in (side, mpath))
    bad = bad or next(((q, "not readable as JSON") for q, v in ((side, rec), (mpath, met)) if v is None), None)
    if bad is not None:
        return None, f"{bad[0]} is damaged ({bad[1]}; make table1 / make sitl-study redoes it)"
    if not rec.get("complete") or rec.get("fingerprint") != S.train_fingerprint(exp, kind, metadata_text):
        return None, f"{ckp} was trained on other inputs or is unfinished (make table1 retrains it)"
    if (met.get("train_steps"), met.get("best_step")) != (rec.get("step_max"), rec.get("best_step")):
        return None, f"{mpath} was made from another checkpoint (run sitl/evaluate.py --model {kind})"
    if met.get("n_rollout_steps") != exp.eval.n_rollout_steps or met.get("n_rollouts") != n_rollouts(exp):
        return None, f"{mpath} was evaluated with other eval settings (run sitl/evaluate.py --model {kind})"
    return met, None


def _json_or_none(p: Path):
    try:
        return json.loads(p.read_text())
    except ValueError:
        return None


def n_rollouts(exp: S.Experiment) -> int:
    """Test rollouts of evaluate.py (and here): every (input_seq_length + n_rollout_steps)-frame window
    of the test split per trajectory (LagrangeBench's H5Dataset), or eval.n_trajs of them."""
    windows = exp.data.frames[2] // (exp.model.input_seq_length + exp.eval.n_rollout_steps) * exp.data.seeds
    return windows if exp.eval.n_trajs == -1 else min(exp.eval.n_trajs, windows)


def inputs_key(exp: S.Experiment, results, path: Path, plan: list, trained: dict) -> str:
    """Everything the outputs depend on: the dataset, the settings used, the points (`plan`), the code
    (with the sph modules it imports), and the metrics and training record of each trained model shown."""
    gen = json.loads((path / "generate.json").read_text())
    return digest({"data": [gen.get("fingerprint"), gen.get("config"), (path / "metadata.json").read_text()],
                   "cost": to_mapping(exp.cost), "eval": to_mapping(exp.eval), "model": to_mapping(exp.model),
                   "dtype": exp.train.dtype, "seed": exp.train.seed, "code": keys.code_fingerprint(CODE),
                   "points": [dataclasses.astuple(p) for p in plan],
                   "trained": {name: [S.metrics_path(folder, name.split("_")[0]).read_text(),
                                      (S.ckpt_dir(folder, name.split("_")[0]) / "train.json").read_text()]
                               for name, (met, _, folder) in trained.items() if met is not None}})


def solver_model(exp: S.Experiment, data_train, case, substeps: int):
    """The solver alone (model.py, correction off) with `substeps` substeps per coarse step."""
    cfg = dataclasses.replace(exp.model, substeps=substeps)
    return M.build("solver", data_train.metadata, case.normalization_stats, data_train[0][0][:, 0], cfg,
                   exp.train.dtype)


def fine_model(exp: S.Experiment, data_train, case):
    """The fine solver (module docstring) as a haiku model LagrangeBench's `infer` runs: W steps of
    our solver's step_fn at the data's dt from a consistent start; output in LagrangeBench's
    normalised acceleration like model.py's (NaN if a neighbour list overflowed)."""
    meta = data_train.metadata
    w = int(meta["write_every"])
    setup = M.make_setup(meta, case.normalization_stats, data_train[0][0][:, 0], w, exp.train.dtype,
                         exp.model.capacity_multiplier)
    solver = setup.solver
    disp = solver.scene.domain.make_displacement(solver.neighbors.cutoff + solver.neighbors.skin)
    lag = 0.5 * setup.frame_dt * (1.0 - 1.0 / w)

    def fn(sample):
        features, _ = sample
        pos = jnp.asarray(features["abs_pos"], setup.dtype)
        r0 = pos[:, -1]
        v0 = disp(r0, pos[:, -2])                        # per-frame displacement
        u = v0 / setup.frame_dt
        nbrs = solver.neighbors.update(r0, setup.sph_nbrs)
        state = solver.state_at(r0, u + lag * solver.state_at(r0, u, nbrs).dudt, nbrs)

        def body(k, carry):
            st, nb, over = carry
            st, nb = solver.step_fn(st, nb, k + 1)
            return st, nb, over | nb.did_buffer_overflow.astype(bool)

        state, _, over = jax.lax.fori_loop(0, w, body, (state, nbrs, nbrs.did_buffer_overflow.astype(bool)))
        acc = (disp(state.r, r0) - v0 - setup.acc_mean) / setup.acc_std
        return {"acc": jnp.where(over, jnp.nan, acc)}

    return hk.without_apply_rng(hk.transform_with_state(fn))


class Stepper:
    """One jitted coarse step of a rollout, as LagrangeBench's eval loop makes it: features and graph
    list (case.preprocess_eval), the model, case.integrate, kinematic particles set from the target."""

    def __init__(self, model, params, state, case, sample):
        from lagrangebench.utils import get_kinematic_mask

        self.params, self.state, self.case, self.ptype = params, state, case, sample[1]
        self.nbrs = case.allocate_eval(sample)[1]
        kinematic = get_kinematic_mask(self.ptype)

        def step(params, state, pos, nbrs, target):
            features, nbrs = case.preprocess_eval((pos, self.ptype), nbrs)
            pred, state = model.apply(params, state, (features, self.ptype))
            nxt = jnp.where(kinematic[:, None], target, case.integrate(pred, pos))
            return jnp.concatenate([pos[:, 1:], nxt[:, None]], axis=1), state, nbrs

        self.step = jax.jit(step)
        self.sample = sample
        t0 = time.perf_counter()
        jax.block_until_ready(self(sample[0], sample[0][:, -1]))
        self.compile_s = time.perf_counter() - t0

    def __call__(self, pos, target, state=None):
        return self.step(self.params, self.state if state is None else state, pos, self.nbrs, target)

    def rollout(self, traj, n_steps: int, isl: int):
        """(n_steps, N, dim) predicted positions from the first isl frames of traj (N, T, dim)."""
        pos, state, preds = traj[:, :isl], self.state, []
        for k in range(n_steps):
            nxt, new_state, nbrs = self.step(self.params, state, pos, self.nbrs, traj[:, isl + k])
            if bool(nbrs.did_buffer_overflow):       # as LagrangeBench: re-allocate and redo the step
                self.nbrs = self.case.allocate_eval((pos, self.ptype))[1]
                nxt, new_state, nbrs = self.step(self.params, state, pos, self.nbrs, traj[:, isl + k])
            pos, state, self.nbrs = nxt, new_state, nbrs
            preds.append(pos[:, -1])
            if not bool(jnp.isfinite(preds[-1]).all()):  # blown up (or an in-model list overflowed):
                preds += [preds[-1]] * (n_steps - k - 1)  # NaN to the end, no list built from NaN
                break
        return jnp.stack(preds)

    def time_once(self) -> float:
        t0 = time.perf_counter()
        jax.block_until_ready(self(self.sample[0], self.sample[0][:, -1]))
        return time.perf_counter() - t0


def accuracy(exp: S.Experiment, stepper: Stepper, data_test, computer) -> dict:
    """MSE_5, MSE_20 (LagrangeBench's `loss`) and MSE_Ekin over the first eval.n_trajs test windows,
    LagrangeBench's MetricsComputer `computer` per rollout and its averaged_metrics over them."""
    from lagrangebench.evaluate import averaged_metrics

    ev, isl = exp.eval, data_test.input_seq_length
    n = data_test.num_samples if ev.n_trajs == -1 else min(ev.n_trajs, data_test.num_samples)
    metrics = {}
    for i in range(n):
        traj = jnp.asarray(data_test[i][0])
        pred = stepper.rollout(traj, ev.n_rollout_steps, isl)
        target = traj[:, isl:isl + ev.n_rollout_steps].transpose(1, 0, 2)
        metrics[f"rollout_{i}"] = computer(pred, target)
    avg = averaged_metrics(metrics)
    return {"n_rollouts": n, **{k: avg[v] for k, v in KEYS.items()}, "std_mse20": avg["val/stdloss"]}


def interleaved_times(steppers: dict, repeats: int) -> dict:
    """{name: (median s, min s)} over `repeats` rounds, each calling every stepper once."""
    times = {k: [] for k in steppers}
    for _ in range(repeats):
        for k, st in steppers.items():
            times[k].append(st.time_once())
    return {k: (float(np.median(v)), float(np.min(v))) for k, v in times.items()}


def record(exp: S.Experiment, p: Point, row: dict) -> dict:
    """The run record of one point (lab.record.RECORD_COLUMNS, then err_<name>, then extras): a "run"
    is one 20-step test rollout, so wall_s = n_rollout_steps x the time per coarse step."""
    d, n = exp.data, exp.eval.n_rollout_steps
    s = row["ms_per_coarse_step"] / 1e3
    frame_dt = d.dt * d.write_every
    fixed = {"experiment": "sitl", "target": "sitl-cost", "method": p.method,
             "effects": "standard" if p.kind != "gns" else "", "kernel": "quintic" if p.kind != "gns" else "",
             "h_factor": 1.0 if p.kind != "gns" else float("nan"), "dx": d.dx, "dim": 2, "dtype": exp.train.dtype, "n_particles": d.n_particles, "n_steps": n,
             "dt": frame_dt, "t_end": n * frame_dt, "wall_s": n * s, "compile_s": row["compile_s"],
             "ms_per_step": 1e3 * s, "peak_rss_mb": runs.peak_rss_mb(), "other_load": row["other_load"],
             "devices": 1, "processes": 1}
    rec = {c: fixed[c] for c in RECORD_COLUMNS}
    rec.update({f"err_{k}": row[k] for k in ("mse20", "mse5", "e_kin")})
    rec.update({k: row[k] for k in ("kind", "M", "substeps", "substep_dt", "substep_over_cfl", "finite",
                                    "n_rollouts", "source")})
    return rec


def plot(rows: list, path: Path, title: str):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.4, 4.6), constrained_layout=True)
    ok = [r for r in rows if r["finite"] and r["mse20"] > 0]
    top = max([r["mse20"] for r in ok], default=1.0) * 10
    family = sorted([r for r in rows if r["kind"] == "solver" and r in ok], key=lambda r: r["M"])
    if len(family) > 1:
        ax.plot([r["ms_per_coarse_step"] for r in family], [r["mse20"] for r in family], "-", color="C0",
                lw=1, alpha=0.5)
    shown = set()
    # the diverged points all sit on one line (y = top): their labels are stacked downwards by time
    # so that points close in cost do not print over each other
    diverged = sorted((r for r in rows if r not in ok), key=lambda r: r["ms_per_coarse_step"])
    stack = {id(r): i for i, r in enumerate(diverged)}
    for r in rows:
        marker, color = STYLE[r["kind"]]
        y = r["mse20"] if r in ok else top
        label = {"fine": "fine solver (dt, consistent start)", "solver": "solver only (M)", "gns": "GNS",
                 "sitl": "SitL"}[r["kind"]]
        ax.loglog(r["ms_per_coarse_step"], y, marker if r in ok else "x", color=color, ms=9 if marker == "*" else 7,
                  ls="none", label=None if label in shown else label)
        shown.add(label)
        note = (("fine" if r["kind"] == "fine" else f"M={_m(r['M'])}")
                + (" pushforward" if "pushforward" in r["method"] else "") + ("" if r in ok else " diverged"))
        # the solver point SitL corrects sits next to M = 5: its label goes below the point
        dy = -11 if "as SitL" in r["method"] else 4 - 11 * stack.get(id(r), 0)
        ax.annotate(note, (r["ms_per_coarse_step"], y), textcoords="offset points", xytext=(5, dy), fontsize=7)
    ax.set(xlabel="inference time per coarse step [ms]", ylabel="MSE$_{20}$ (test rollouts)", title=title)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    fig.savefig(path, dpi=130)
    plt.close(fig)


def markdown(rows: list, exp: S.Experiment, profile: str) -> str:
    """cost.md: the plane as a table, one row per point in cost.csv's order (what the README shows)."""
    d = exp.data
    n = sorted({int(r["n_rollouts"]) for r in rows if r.get("n_rollouts")})
    load = max((r.get("other_load") or 0.0) for r in rows) if rows else 0.0

    def num(r, k):
        v = r.get(k)
        return "diverged" if v is None or not math.isfinite(v) else f"{v:.3g}"

    lines = [f"# Accuracy against cost, RPF 2D ({profile}): {d.n_particles} particles, coarse step = "
             f"{d.write_every} dt", "",
             f"MSE of 20-step rollouts, mean over {'/'.join(map(str, n))} test windows (std over the windows); "
             f"time: one jitted coarse step (features, graph list, model, integration), median / minimum "
             f"over {exp.cost.repeats} interleaved rounds, beside {load:.2f} cores of other work. GNS and "
             f"SitL: MSE from their evaluation (metrics/<model>.json), time measured here. M: fine steps "
             f"dt per solver substep; L: substeps per coarse step.", "",
             "| point | M | L | substep dt / CFL dt | MSE_5 | MSE_20 (std) | MSE_Ekin | ms per coarse step "
             "(median / min) |",
             "|---|---|---|---|---|---|---|---|"]
    for r in rows:
        mse20 = num(r, "mse20") + (f" ({r['std_mse20']:.2g})" if r["finite"] and r.get("std_mse20") is not None
                                   and math.isfinite(r["std_mse20"]) else "")
        cfl = "" if r.get("substep_over_cfl") is None else f"{r['substep_over_cfl']:.3g}"
        lines.append(f"| {r['method']} | {_m(r['M'])} | {r.get('substeps') or ''} | {cfl} | {num(r, 'mse5')} | "
                     f"{mse20} | {num(r, 'e_kin')} | {r['ms_per_coarse_step']:.3g} / {r['ms_min']:.3g} |")
    return "\n".join(lines) + "\n"


def outputs(results) -> list:
    out = S.out_dir(results)
    return [out / "cost.csv", out / "cost.png", out / "cost.json", out / "cost.md"]


def run(exp: S.Experiment, results, profile: str = "", force: bool = False) -> list:
    path = generate.ready(exp, results)
    meta_text = (path / "metadata.json").read_text()
    plan = points(exp)
    where = {p.name: trained_run(exp, profile, results, p) for p in plan if p.kind in TRAINED}
    trained = {name: (*trained_status(rexp, folder, next(q.kind for q in plan if q.name == name), meta_text),
                      folder) for name, (rexp, folder) in where.items()}
    key = inputs_key(exp, results, path, plan, trained)
    out = S.out_dir(results)
    side = out / "cost.json"
    if not force and all(p.exists() for p in outputs(results)):
        try:
            stored = json.loads(side.read_text())
        except ValueError:  # damaged: measured again
            stored = {}
        names = [p.name for p in plan if p.kind not in TRAINED or trained[p.name][0] is not None]
        if stored.get("key") == key and all((S.cost_dir(results) / n / "record.json").exists() for n in names):
            bad = integrity.damaged(out, stored.get("outputs"))
            if bad is None:
                stamp_points(results, stored["rows"])
                print(f"cost: up to date ({out / 'cost.csv'})", flush=True)
            else:  # the measurements are intact in cost.json: write the table and the figure again
                print(f"cost: {bad[0]} {bad[1]}; written again from {side.name}", flush=True)
                write_outputs(stored["rows"], exp, results, profile, key)
            return stored["rows"]

    from sitl import common as C  # sets up LagrangeBench first
    from lagrangebench.evaluate import MetricsComputer
    from lagrangebench.utils import load_haiku

    data_train, _, data_test = C.datasets(exp, path)
    case = C.case(exp, data_train, "solver")
    computer = MetricsComputer(["mse", "e_kin"], dist_fn=case.displacement, metadata=data_test.metadata,
                               input_seq_length=data_test.input_seq_length, stride=exp.eval.metrics_stride)
    pos, ptype = data_test[0]
    sample = (jnp.asarray(pos[:, :exp.model.input_seq_length]), jnp.asarray(ptype))  # the timed input
    features, _ = case.allocate_eval(sample)
    gen = json.loads((path / "generate.json").read_text())
    cfl = (gen.get("dt_limits") or {}).get("dt")
    d = exp.data
    rows, steppers = [], {}
    for p in plan:
        if p.kind in TRAINED:
            met, why, folder = trained[p.name]
            if met is None:
                print(f"cost: {p.method} left out: {why}", flush=True)
                continue
            rexp = where[p.name][0]
            kcase = C.case(rexp, data_train, p.kind)  # its training noise is in its normalisation
            model = C.model(rexp, p.kind, data_train, kcase)
            params, state, _, _ = load_haiku(str(S.ckpt_dir(folder, p.kind) / "best"))
            steppers[p.name] = Stepper(model, params, state, kcase, sample)
            acc = {"n_rollouts": met["n_rollouts"], **{k: met[k] for k in KEYS}, "std_mse20": met["std_mse20"]}
            source = str(Path(os.path.relpath(S.metrics_path(folder, p.kind), results)))
        else:
            model = fine_model(exp, data_train, case) if p.kind == "fine" else \
                solver_model(exp, data_train, case, p.substeps)
            # no weights: the initial (params, state) from the abstract init, never running the module
            # eagerly op by op (seconds for W substeps); the solver's only state is its zero overflow count
            shapes = jax.eval_shape(model.init, jax.random.PRNGKey(0), (features, sample[1]))
            params, state = jax.tree_util.tree_map(lambda x: jnp.zeros(x.shape, x.dtype), shapes)
            steppers[p.name] = Stepper(model, params, state, case, sample)
            acc = accuracy(exp, steppers[p.name], data_test, computer)
            source = "measured"
        sub = None if p.substeps is None else d.dt * d.write_every / p.substeps
        rows.append({"name": p.name, "kind": p.kind, "method": p.method, "M": p.M, "substeps": p.substeps,
                     "substep_dt": sub, "substep_over_cfl": sub / cfl if sub and cfl else None, **acc,
                     "finite": bool(all(math.isfinite(acc[k]) for k in KEYS)),
                     "compile_s": steppers[p.name].compile_s, "source": source})
        print(f"cost: {p.method:32s} MSE_5 {acc['mse5']:.3g}  MSE_20 {acc['mse20']:.3g}  "
              f"(compile {steppers[p.name].compile_s:.1f} s)", flush=True)
    with OtherLoad() as load:
        times = interleaved_times(steppers, exp.cost.repeats)
    for r in rows:
        med, fastest = times[r["name"]]
        r.update(ms_per_coarse_step=1e3 * med, ms_min=1e3 * fastest, other_load=load.cores)
        print(f"cost: {r['method']:32s} {r['ms_per_coarse_step']:.3g} ms per coarse step "
              f"(min {r['ms_min']:.3g})", flush=True)

    out.mkdir(parents=True, exist_ok=True)
    cdir = S.cost_dir(results)
    names = {r["name"] for r in rows}
    if cdir.exists():  # a point no longer configured (or a model now stale) must not reach the atlas
        for old in cdir.iterdir():
            if old.is_dir() and old.name not in names:
                shutil.rmtree(old)
    by_name = {p.name: p for p in plan}
    for r in rows:
        folder = cdir / r["name"]
        folder.mkdir(parents=True, exist_ok=True)
        save_record(folder, record(exp, by_name[r["name"]], r))
    write_outputs(rows, exp, results, profile, key)
    print(f"cost: {len(rows)} points -> {out / 'cost.csv'}, cost.png, {cdir}/*/record.json", flush=True)
    return rows


def write_outputs(rows: list, exp: S.Experiment, results, profile: str, key: str) -> None:
    """cost.csv, cost.md, cost.png, then cost.json (the rows, the key of their inputs and the digests of the
    two, checked on the next run) and the stamp `cost.done` listing the current points' record
    folders (the atlas reads exactly those: `lab.stamp.current_folders`)."""
    out = S.out_dir(results)
    write_table(out / "cost.csv", rows, columns=COLUMNS)
    write_text(out / "cost.md", markdown(rows, exp, profile or Path(results).name))
    plot(rows, out / "cost.png", f"RPF 2D, {exp.data.n_particles} particles ({profile or Path(results).name}): "
                                  f"coarse step = {exp.data.write_every} dt")
    made = integrity.digests(out, ["cost.csv", "cost.md", "cost.png"])
    # the dataset's fingerprint: a reader of the rows (sitl/study.py's fine-solver floor) checks it
    data_fp = json.loads((S.data_dir(results) / "generate.json").read_text()).get("fingerprint")
    write_text(out / "cost.json", json.dumps({"key": key, "data_fingerprint": data_fp, "rows": rows, "outputs": made},
                                             indent=2) + "\n")
    stamp_points(results, rows)


def stamp_points(results, rows: list) -> None:
    """The stamp cost.done: the record folders of exactly the points in `rows` (lab.stamp)."""
    cdir = S.cost_dir(results)
    stamp.update(S.out_dir(results) / "cost.done", cdir, noted=[cdir / r["name"] for r in rows])


def options(ap):
    ap.add_argument("--force", action="store_true", help="measure again even if the inputs are unchanged")


def main(args):
    run(S.load(args.profile), args.results, args.profile, args.force)


if __name__ == "__main__":
    profile_main(main, __doc__, options)
