"""When does SitL beat the solver alone? (issue 21) The decisive runs, each trained / evaluated once,
cached and resumable like Table 1's, gathered into one table and one figure:

  reference      the solver alone at SitL's L = model.substeps, GNS and SitL at the paper's settings
                 (App. B.2: lr 1e-3; noise 1e-3 GNS, 1e-5 SitL); with no study.overrides these are
                 Table 1's own runs (same folder, trained once)
  noise          SitL trained at each study.noise (paper 1e-5; 3e-4 was LagrangeBench's default)
  seed           SitL at the paper's settings with another training seed: spread between trainings
  coarse         where the solver alone fails: the solver and SitL at L = study.substeps substeps per
                 frame (M = write_every / L), SitL at the paper's noise
  pushforward    beyond the paper: SitL at L = study.pushforward.substeps trained with LagrangeBench's
                 pushforward (its schedule scaled to the step budget): first rolled out by its own
                 model for up to a few steps without gradient, so it sees the states its rollout
                 drifts into
  equal_cost     GNS trained for as many steps as cost what the reference SitL's training costs, both
                 models' seconds per step and per validation window timed side by side
                 (sitl/train_cost.py), validations included
  authors_force  the solver alone (L = model.substeps) with the authors' uniform force beside the
                 per-particle one, at study.authors_force_data's resolution and frame interval (cpu:
                 the paper's dx 0.025, frames every 0.01), no training
  long           the reference GNS and SitL trained for study.long_steps steps, the learning-rate
                 decay stretched over them: are the curves still moving at train.step_max?
  frozen         not a run: particles frozen at the last input frame on the same test windows
                 (sitl/baseline.py), the scale from the data alone (a model above it does worse
                 than not moving)

Every number is a mean over the test windows of every seed with a 95 % bootstrap interval over the
windows; each model is also compared with the solver alone at its own L (GNS: at model.substeps) on
the same windows, as a paired ratio of MSE_20 with its interval (sitl/stats.py).

A run whose settings equal the profile's lives in the profile's own folder (results/<profile>/sitl,
Table 1's); any other in results/<profile>/sitl_study/runs/<name>/sitl with the profile's dataset
linked in. Training resumes from its checkpoint, a finished training or a current evaluation is not
repeated (sitl/train.py, sitl/evaluate.py), so `make sitl-study` can be killed and re-run, and
`--only` runs a subset. Writes results/<profile>/sitl_study/study.{csv,md,png,json}.

    .venv-lb/bin/python sitl/study.py --profile smoke [--only sitl_L2 solver_L2]
"""
import dataclasses
import json
import math
import os
import subprocess
import sys
from pathlib import Path
from typing import Optional

from sitl import settings as S
from sitl import stats
from sitl.fmt import ratio_digits
from sitl.table1 import chain_verdict
from lab.cli import profile_main, select
from lab.atomic import write_text
from lab.tables import write_table
from lab.configtools import merge
from lab.lock import folder_lock

HERE = Path(__file__).resolve().parent
PAPER_SOLVER = {"mse5": 1.7e-7, "mse20": 7.9e-6, "e_kin": 0.13, "sinkhorn": 3.4e-7}  # paper Table 1


@dataclasses.dataclass(frozen=True)
class Run:
    """One run: `name` is its folder / row, `overrides` its keys over the study's base profile."""

    name: str
    kind: str
    group: str
    label: str
    overrides: dict = dataclasses.field(default_factory=dict)


def _g(x: float) -> str:
    return f"{x:.3g}"


def runs(exp: S.Experiment) -> list:
    """The study's runs in the order they are made (most informative first)."""
    st, t = exp.study, exp.train
    l0, w = exp.model.substeps, exp.data.write_every
    out = [Run(f"solver_L{l0}", "solver", "reference", f"solver only, L={l0} (M={_g(w / l0)})"),
           Run("gns", "gns", "reference", f"GNS, noise {_g(t.noise_std)}"),
           Run("sitl", "sitl", "reference", f"SitL, L={l0}, noise {_g(t.sitl_noise_std)}")]
    for n in st.substeps:
        if n == l0:
            continue
        sub = {"model": {"substeps": n}}
        out.append(Run(f"solver_L{n}", "solver", "coarse", f"solver only, L={n} (M={_g(w / n)})", sub))
        out.append(Run(f"sitl_L{n}", "sitl", "coarse", f"SitL, L={n} (M={_g(w / n)}), noise {_g(t.sitl_noise_std)}",
                       sub))
    pf = st.pushforward or {}
    for n in pf.get("substeps", ()):
        sub = {"model": {"substeps": n}, "train": {"pushforward_steps": pf["steps"], "pushforward_unrolls": pf["unrolls"],
                                                   "pushforward_probs": pf["probs"]}}
        out.append(Run(f"sitl_L{n}_pushforward", "sitl", "pushforward",
                       f"SitL, L={n} (M={_g(w / n)}), noise {_g(t.sitl_noise_std)}, pushforward up to "
                       f"{max(pf['unrolls'])} unrolls (beyond the paper)", sub))
    if st.gns_equal_cost:
        out.append(Run("gns_equal_cost", "gns", "equal_cost", "GNS at SitL's training cost"))
    for n in st.noise:
        if n != t.sitl_noise_std:
            out.append(Run(f"sitl_noise{_g(n)}", "sitl", "noise", f"SitL, L={l0}, noise {_g(n)}",
                           {"train": {"sitl_noise_std": n}}))
    for seed in st.train_seeds:
        if seed != t.seed:
            out.append(Run(f"sitl_seed{seed}", "sitl", "seed", f"SitL, L={l0}, noise {_g(t.sitl_noise_std)}, "
                                                                f"training seed {seed}", {"train": {"seed": seed}}))
    out.append(Run("authors_force", "solver", "authors_force", f"solver only, L={l0}: per-particle vs authors' "
                                                                "uniform force"))
    if st.authors_table1:
        uni = {"model": {"solver_force": "uniform"}}
        out.append(Run(f"solver_L{l0}_uniform", "solver", "authors", f"solver only, L={l0}, authors' uniform force", uni))
        out.append(Run("sitl_uniform", "sitl", "authors", f"SitL, L={l0}, noise {_g(t.sitl_noise_std)}, authors' "
                                                          "uniform force in the loop (positive control)", uni))
    if st.extra_inputs:
        out.append(Run("sitl_extra_inputs", "sitl", "learnability",
                       f"SitL, L={l0}, noise {_g(t.sitl_noise_std)}, corrector also sees {', '.join(st.extra_inputs)}",
                       {"model": {"extra_inputs": list(st.extra_inputs)}}))
    if st.consistent_start:
        out.append(Run(f"solver_L{l0}_consistent", "solver", "learnability",
                       f"solver only, L={l0}, consistent start (velocity at t0)", {"model": {"start": "consistent"}}))
    for n in st.gns_noise:
        if n != t.noise_std:
            out.append(Run(f"gns_noise{_g(n)}", "gns", "fair_gns", f"GNS, noise {_g(n)}", {"train": {"noise_std": n}}))
    for n in st.gns_input_seq:
        if n != exp.model.input_seq_length:
            out.append(Run(f"gns_seq{n}", "gns", "fair_gns", f"GNS, noise {_g(t.noise_std)}, {n} input positions "
                                                             f"({n - 1} velocities; other test windows: unpaired)",
                           {"model": {"input_seq_length": n}, "models": ["gns"]}))
    for kind in st.long_models if st.long_steps else ():
        ref = next(r for r in out if r.group == "reference" and r.kind == kind)
        out.append(Run(f"{kind}_long{st.long_steps}", kind, "long", f"{ref.label}, {st.long_steps} training steps",
                       {"train": {"step_max": st.long_steps, "lr_decay_steps": st.long_steps}}))
    return out


def study_dir(results) -> Path:
    return Path(results) / "sitl_study"


def run_experiment(profile: str, exp: S.Experiment, run: Run, extra: dict = None) -> S.Experiment:
    """The profile with study.overrides, then the run's own keys (and `extra`, e.g. a step budget)."""
    over = merge(merge(exp.study.overrides or {}, run.overrides), extra or {})
    return S.load(profile, overrides=over) if over else exp


def run_results(results, profile_exp: S.Experiment, run_exp: S.Experiment, run: Run, own_data: bool = False) -> Path:
    """Table 1's folder when the run's settings are the profile's own, else its own folder with the
    profile's dataset linked in (`own_data`: a folder for a dataset of its own)."""
    if run_exp is not None and run_exp == profile_exp and not own_data:
        return Path(results)
    own = study_dir(results) / "runs" / run.name
    if own_data:
        return own
    link = S.data_dir(own)
    if not link.is_symlink():
        link.parent.mkdir(parents=True, exist_ok=True)
        if link.exists():
            raise FileExistsError(f"{link}: expected a link to the profile's dataset, found a folder")
        link.symlink_to(os.path.relpath(S.data_dir(results).resolve(), link.parent.resolve()),
                        target_is_directory=True)
    return own


def equal_cost_budget(profile: str, exp: S.Experiment, results) -> dict:
    """GNS's step budget at the reference SitL's training cost: both models' seconds per training
    step and per validation window measured side by side in this process (sitl/train_cost.py), then
    the GNS training, validating as often (eval_steps scaled with its steps), that costs what the
    reference SitL's does. Measured once, then kept in budget.json so that the run's key is stable.
    The two reference trainings' own wall times are recorded beside it, for comparison only: they
    depend on what else the machine ran meanwhile."""
    from sitl import train, train_cost
    from lab.other_load import OtherLoad

    side = study_dir(results) / "runs" / "gns_equal_cost" / "budget.json"
    if side.exists():
        return json.loads(side.read_text())
    refs = {r.kind: locate(profile, exp, results, r) for r in runs(exp) if r.group == "reference" and r.kind != "solver"}
    base, folder = refs["sitl"]
    t = base.train
    print("study: timing GNS and SitL training side by side for the equal-cost budget (sitl/train_cost.py)",
          flush=True)
    with OtherLoad() as load:  # both models are timed in the same conditions; this says which
        cost = train_cost.measure(base, folder)
    sitl_s = train_cost.training_s(cost["sitl"], t.step_max, t.eval_steps, t.eval_n_trajs)
    n_evals = t.step_max // t.eval_steps
    steps = max(1, int(round((sitl_s - n_evals * t.eval_n_trajs * cost["gns"]["s_per_window"])
                             / cost["gns"]["s_per_step"])))
    recorded = {}
    for kind, (_, rfolder) in refs.items():
        rec = train.read_record(S.ckpt_dir(rfolder, kind) / "train.json") or {}
        recorded[kind] = {k: rec.get(k) for k in ("wall_s", "s_per_step", "complete")}
    budget = {"cost": cost, "other_load": load.fields()["other_load"], "sitl_training_s": sitl_s,
              "sitl_step_max": t.step_max, "step_max": steps, "recorded_trainings": recorded,
              "overrides": {"train": {"step_max": steps,
                                      "lr_decay_steps": float(t.lr_decay_steps) * steps / t.step_max,
                                      # as many validations as SitL's (steps // eval_steps of them)
                                      "eval_steps": max(1, steps // max(1, n_evals)),
                                      "log_steps": max(1, int(round(t.log_steps * steps / t.step_max)))}}}
    write_text(side, json.dumps(budget, indent=2) + "\n")
    return budget


def authors_force(profile: str, exp: S.Experiment, results, run: Run) -> dict:
    """The authors' force bug (sitl/authors_force.py) on the study's authors'-force dataset, which is
    generated in a subprocess (the data run is float64, which must not switch this process)."""
    from sitl import authors_force as AF

    base = run_experiment(profile, exp, run)
    afexp = S.authors_force_experiment(base)
    if exp.study.authors_force_data:
        own = run_results(results, exp, afexp, run, own_data=True)
        cmd = [sys.executable, str(HERE / "generate.py"), "--profile", profile, "--results", str(own),
               "--authors-force", "--no-progress"]
        print(f"study: the authors'-force dataset: {' '.join(cmd[1:])}", flush=True)
        subprocess.run(cmd, check=True)
    else:  # the profile's own dataset
        own = study_dir(results) / "runs" / run.name
        run_results(results, exp, None, run)
    side = own / "authors_force.json"
    key = authors_force_key(afexp, own)
    if side.exists():
        done = json.loads(side.read_text())
        if done.get("key") == key:
            print(f"study: authors_force up to date ({side})", flush=True)
            return done
    out = {"key": key, "dx": afexp.data.dx, "frame_dt": afexp.data.dt * afexp.data.write_every,
           "n_particles": afexp.data.n_particles,
           "per_particle": AF.evaluate(afexp, own, "per_particle"), "uniform": AF.evaluate(afexp, own, "uniform")}
    write_text(side, json.dumps(out, indent=2) + "\n")
    return out


def authors_force_key(afexp: S.Experiment, own: Path) -> str:
    """What authors_force.json in `own` is made from: its dataset, model and eval settings, the code."""
    from lab.keys import digest, files_digest

    return digest({"data": (S.data_dir(own) / "generate.json").read_text(), "model": dataclasses.asdict(afexp.model),
                   "eval": dataclasses.asdict(afexp.eval),
                   "code": files_digest([HERE / f for f in ("authors_force.py", "model.py", "common.py", "evaluate.py")])})


def locate(profile: str, exp: S.Experiment, results, run: Run, extra: dict = None):
    """(the run's experiment, its results folder); `extra`: the equal-cost run's step budget."""
    rexp = run_experiment(profile, exp, run, extra)
    return rexp, run_results(results, exp, rexp, run)


def stored_row(profile: str, exp: S.Experiment, results, run: Run):
    """The row of a run when it is finished and current (nothing is trained, evaluated or generated
    here), else None: the table always shows every current run, and a current run is not made again.
    Its records suffice (train.json, the metrics json, the dataset's generate.json / metadata.json):
    a run restored from the committed snapshot (`make restore`, without checkpoints) is current."""
    from sitl import evaluate, train

    own = study_dir(results) / "runs" / run.name
    if run.group == "authors_force":
        side = own / "authors_force.json"
        try:
            done = json.loads(side.read_text())
            afexp = S.authors_force_experiment(run_experiment(profile, exp, run))
            return {"run": run, "authors_force": done, "stored": True} \
                if done.get("key") == authors_force_key(afexp, own) else None
        except (OSError, ValueError):
            return None
    budget = own / "budget.json"
    if run.group == "equal_cost" and not budget.exists():
        return None
    rexp, folder = locate(profile, exp, results, run,
                          json.loads(budget.read_text())["overrides"] if run.group == "equal_cost" else None)
    rec = {"model": run.kind, "trained": False}
    if run.kind != "solver":
        rec = train.read_record(S.ckpt_dir(folder, run.kind) / "train.json") or {}
        meta = (S.data_dir(folder) / "metadata.json").read_text()
        if not rec.get("complete") or rec.get("fingerprint") != S.train_fingerprint(rexp, run.kind, meta):
            return None
    met = evaluate.current(rexp, folder, run.kind)
    if met is None:
        return None
    return {"run": run, "exp": rexp, "folder": str(folder), "shared": folder == Path(results), "train": rec,
            "metrics": met, "stored": True}


def make_run(profile: str, exp: S.Experiment, results, run: Run) -> dict:
    """Train (if a network) and evaluate one run; returns its row."""
    from sitl import evaluate, train

    if run.group == "authors_force":
        return {"run": run, "authors_force": authors_force(profile, exp, results, run)}
    rexp, folder = locate(profile, exp, results, run,
                          equal_cost_budget(profile, exp, results)["overrides"] if run.group == "equal_cost" else None)
    shared = folder == Path(results)
    print(f"study: {run.name} ({run.label}) in {folder}", flush=True)
    rec = train.train(rexp, folder, run.kind)
    met = evaluate.evaluate(rexp, folder, run.kind, rollouts=shared, sinkhorn=shared, timing=shared)
    return {"run": run, "exp": rexp, "folder": str(folder), "shared": shared, "train": rec, "metrics": met}


def reference_of(run: Run, exp: S.Experiment, rows: dict):
    """The solver-only row a run is compared with: the solver at the run's own L (GNS: model.substeps)."""
    if run.kind == "solver":
        return None
    model = run.overrides.get("model", {})
    subs = model.get("substeps", exp.model.substeps) if run.kind == "sitl" else exp.model.substeps
    uniform = run.kind == "sitl" and model.get("solver_force") == "uniform"
    return rows.get(f"solver_L{subs}" + ("_uniform" if uniform else ""))


def table(exp: S.Experiment, rows: dict, frozen_e_kin: float = None) -> list:
    """Flat rows of study.csv; `frozen_e_kin`: the frozen particles' MSE_Ekin, above which a finite
    rollout counts as blown up (`blew_up`)."""
    w, n_boot = exp.data.write_every, exp.eval.bootstrap
    out = []
    for name, r in rows.items():
        run = r["run"]
        if run.group == "authors_force":
            af = r["authors_force"]
            for force in ("per_particle", "uniform"):
                m = af[force]
                out.append({"name": f"authors_force_{force}", "group": run.group, "kind": "solver",
                            "label": f"solver only, {force.replace('_', '-')} force, dx {af['dx']:g}, frames every "
                                     f"{af['frame_dt']:g} ({af['n_particles']} particles)",
                            **{k: m.get(k) for k in ("mse5", "mse20", "e_kin", "sinkhorn")},
                            "mse20_lo": m["ci_mse20"][0], "mse20_hi": m["ci_mse20"][1],
                            "n_windows": m["n_rollouts"], "finite": m["finite"]})
            continue
        m, rexp, tr = r["metrics"], r["exp"], r["train"]
        subs = rexp.model.substeps if run.kind != "gns" else None
        row = {"name": name, "group": run.group, "kind": run.kind, "label": run.label,
               "L": subs, "M": w / subs if subs else w,
               "noise_std": rexp.train.noise(run.kind) if run.kind != "solver" else None,
               "lr_start": rexp.train.lr_start if run.kind != "solver" else None,
               "seed": rexp.train.seed if run.kind != "solver" else None,
               "train_steps": tr.get("step_max"), "train_wall_s": tr.get("wall_s"),
               "train_timed_from_step": timed_from_step(tr), "s_per_step": tr.get("s_per_step"),
               "best_step": tr.get("best_step"),
               **{k: m.get(k) for k in ("mse5", "mse20", "e_kin", "sinkhorn")},
               "mse20_lo": m["ci_mse20"][0], "mse20_hi": m["ci_mse20"][1], "n_windows": m["n_rollouts"],
               "finite": m["finite"], "blew_up": blew_up(m.get("e_kin"), frozen_e_kin),
               "shared_with_table1": r["shared"], "folder": r["folder"]}
        ref = reference_of(run, exp, rows)
        if ref is not None:
            # the same test windows: paired; a longer input history cuts the test data into other windows
            paired = rexp.model.input_seq_length == ref["exp"].model.input_seq_length
            a, b = m["per_window"]["mse20"], ref["metrics"]["per_window"]["mse20"]
            ratio, lo, hi = stats.paired_ratio(a, b, n_boot) if paired else stats.unpaired_ratio(a, b, n_boot)
            row.update(vs=ref["run"].name, ratio_mse20=ratio, ratio_lo=lo, ratio_hi=hi, paired=paired,
                       verdict=stats.verdict(lo, hi, min(m["n_rollouts"], ref["metrics"]["n_rollouts"])))
            if paired and "mse1" in m["per_window"] and "mse1" in ref["metrics"]["per_window"]:  # one step, before compounding
                r1, lo1, hi1 = stats.paired_ratio(m["per_window"]["mse1"], ref["metrics"]["per_window"]["mse1"], n_boot)
                row.update(ratio_mse1=r1, ratio_mse1_lo=lo1, ratio_mse1_hi=hi1)
            row.update(diverged_verdict(m["finite"], ref["metrics"]["finite"], row["blew_up"],
                                        blew_up(ref["metrics"].get("e_kin"), frozen_e_kin)))
        out.append(row)
    order = [rows.get(n) for n in ("sitl_uniform", "gns", f"solver_L{exp.model.substeps}_uniform")]
    if all(r is not None and "metrics" in r for r in order):
        windows = [r["metrics"]["per_window"]["mse20"] for r in order]
        if len({len(w) for w in windows}) == 1:  # the same test windows (GNS with 2 input positions)
            next(o for o in out if o["name"] == "sitl_uniform")["paper_ordering"] = paper_ordering(*windows, n_boot)
    return out


def frozen_row(profile: str, exp: S.Experiment, results, plan: list) -> dict:
    """The scale row: particles frozen at the last input frame on the runs' test windows
    (sitl/baseline.py), from the profile's dataset alone."""
    from sitl import baseline, generate

    base = run_experiment(profile, exp, [r for r in plan if r.group == "reference"][0])
    b = baseline.frozen(base, generate.ready(exp, results), base.eval.bootstrap)
    return {"name": "frozen", "group": "baseline", "kind": "data",
            "label": "particles frozen at the last input frame (the test data alone)",
            "mse5": b["mse5"], "mse20": b["mse20"], "mse20_lo": b["ci_mse20"][0], "mse20_hi": b["ci_mse20"][1],
            "e_kin": b["e_kin"], "n_windows": b["n_windows"], "finite": True}


def constant_velocity_row(profile: str, exp: S.Experiment, results, plan: list) -> dict:
    """The floor of sense: particles moving on with their last velocity (sitl/baseline.py), no learning."""
    from sitl import baseline, generate

    base = run_experiment(profile, exp, [r for r in plan if r.group == "reference"][0])
    b = baseline.constant_velocity(base, generate.ready(exp, results), base.eval.bootstrap)
    return {"name": "constant_velocity", "group": "baseline", "kind": "data",
            "label": "particles moving on at their last velocity (no learning)",
            "mse5": b["mse5"], "mse20": b["mse20"], "mse20_lo": b["ci_mse20"][0], "mse20_hi": b["ci_mse20"][1],
            "n_windows": b["n_windows"], "finite": True}


POSITIVE_CONTROL_FACTOR = 10.0
"""The positive control passes when SitL with the authors' uniform force in the loop has an MSE_20 at
least this many times below its biased solver's (issue 39)."""


def fine_floor(results) -> Optional[float]:
    """The fine solver's test MSE_20 (sitl/cost.py's cost.json, `make sitl-cost`): the floor of what
    two stored frames cannot tell, when cost.json was made on the dataset there now; else None."""
    try:
        cost = json.loads((S.out_dir(results) / "cost.json").read_text())
        data = json.loads((S.data_dir(results) / "generate.json").read_text())
    except (OSError, ValueError):
        return None
    if cost.get("data_fingerprint") != data.get("fingerprint"):
        return None
    return next((float(r["mse20"]) for r in cost.get("rows", []) if r.get("kind") == "fine"), None)


LEARNABILITY = ("sitl", "sitl_extra_inputs", "solver_L{l0}_consistent")
"""The rows of the learnability table (issue 39 item 3): does each close the gap between the solver
alone and the fine solver? ({l0}: model.substeps)"""


def learnability(exp: S.Experiment, flat: list, floor: Optional[float]) -> list:
    """Markdown lines: each learnability row's MSE_20 and the share of the gap between the solver alone
    (at model.substeps, the same test windows) and the fine-solver floor that it closes,
    (MSE_solver - MSE_row) / (MSE_solver - MSE_fine): 0 = the solver alone, 1 = the fine solver."""
    l0 = exp.model.substeps
    by = {r["name"]: r for r in flat}
    solver = by.get(f"solver_L{l0}")
    rows = [by[n.format(l0=l0)] for n in LEARNABILITY if n.format(l0=l0) in by]
    if solver is None or len(rows) < 2 or not solver.get("finite"):
        return []
    lines = ["", f"Is the correct-force residual learnable? The gap between the solver alone (L = {l0}, MSE_20 "
                 f"{_f(solver['mse20'])}) and the fine solver (its own integrator at the data's dt, started with "
                 f"the velocity at t0: {_f(floor) if floor else 'not measured on this dataset: make sitl-cost'}) "
                 "and the share of it each row closes, (MSE_solver - MSE_row) / (MSE_solver - MSE_fine):", "",
             "| run | MSE_20 | vs solver | step 1 vs solver | gap closed |", "|---|---|---|---|---|"]
    for r in rows:
        closed = "" if not floor or not r.get("finite") or solver["mse20"] <= floor else \
            f"{(solver['mse20'] - r['mse20']) / (solver['mse20'] - floor):.0%}"
        vs = "" if r.get("ratio_mse20") is None else _vs_cell(r)
        lines.append(f"| {r['label']} | {_f(r['mse20'])}{_ci(r['mse20'], r['mse20_lo'], r['mse20_hi'])} | {vs} | "
                     f"{_ratio_cell(r, 'ratio_mse1')} | {closed} |")
    return lines


def authors_table1(flat: list) -> list:
    """Table 1 as its authors ran it (markdown lines): the solver alone and SitL with the uniform
    force in the loop, GNS as before, and the positive control's factor."""
    by = {r["name"]: r for r in flat}
    pc = by.get("sitl_uniform")
    rows = [r for r in flat if r["group"] == "authors"]
    if not rows:
        return []
    lines = ["", "Table 1 as its authors ran it (the uniform force in the solver alone and in SitL's loop; GNS as "
                 "before), and the positive control:", "",
             "| run | MSE_5 | MSE_20 | MSE_Ekin |", "|---|---|---|---|"]
    for r in [by[n] for n in ("gns",) if n in by] + rows:
        lines.append(f"| {r['label']} | {_f(r['mse5'])} | {_f(r['mse20'])}{_ci(r['mse20'], r['mse20_lo'], r['mse20_hi'])} | "
                     f"{_f(r.get('e_kin'))} |")
    if pc is not None and pc.get("paper_ordering"):
        lines += ["", f"The paper's ordering (SitL < GNS < solver only) on MSE_20 here, by paired intervals on the "
                      f"same test windows: {pc['paper_ordering']}."]
    if pc is not None and pc.get("ratio_mse20"):
        factor = 1.0 / pc["ratio_mse20"]
        ok = factor >= POSITIVE_CONTROL_FACTOR and pc["finite"]
        lines += ["", f"Positive control: SitL's MSE_20 is {_f(factor)}x below its biased solver's "
                      f"(paired interval of the ratio [{_f(pc['ratio_lo'])}, {_f(pc['ratio_hi'])}]): "
                      f"{'passes' if ok else 'FAILS'} (needs >= {POSITIVE_CONTROL_FACTOR:g}x)."]
    return lines


def paper_ordering(sitl, gns, solver, n_boot: int = 2000) -> str:
    """Whether MSE_20 orders SitL < GNS < solver only, from the three models' per-window MSE_20 on the
    same test windows: the paired verdicts of SitL vs GNS and of GNS vs the solver alone
    (stats.verdict), joined by table1.chain_verdict, the rule of Table 1's own verdict.
    A diverged model (a non-finite window) leaves its step undecided."""
    steps = [stats.verdict(*stats.paired_ratio(a, b, n_boot)[1:], n=len(a)) for a, b in ((sitl, gns), (gns, solver))]
    return f"{chain_verdict(steps)} (SitL vs GNS {steps[0]}, GNS vs solver only {steps[1]})"


def diverged_verdict(finite: bool, ref_finite: bool, blown: bool = False, ref_blown: bool = False) -> dict:
    """The comparison with the solver alone when either side diverged: its rollouts went non-finite
    (NaN / inf positions), or stayed finite but blew up (`blown`: a kinetic-energy error above the
    frozen particles', `blew_up` below). {} when neither did. A non-finite side sets the ratio
    (inf, 0 or NaN); a finite one that blew up keeps its measured ratio."""
    fails, ref_fails = blown or not finite, ref_blown or not ref_finite
    if not (fails or ref_fails):
        return {}
    out = {}
    if not (finite and ref_finite):
        r = 0.0 if finite else math.inf if ref_finite else math.nan
        out = {"ratio_mse20": r, "ratio_lo": r, "ratio_hi": r}
    out["verdict"] = "both diverged" if fails and ref_fails else "higher (diverged)" if fails \
        else "lower (solver diverged)"
    return out


def blew_up(e_kin, frozen_e_kin) -> bool:
    """A finite rollout that blew up: its MSE_Ekin is above the particles frozen at the last input
    frame's, i.e. its kinetic energy is further from the truth than no motion at all (sitl/baseline.py)."""
    return e_kin is not None and math.isfinite(e_kin) and frozen_e_kin is not None and e_kin > frozen_e_kin


COLUMNS = ["name", "group", "kind", "label", "L", "M", "noise_std", "lr_start", "seed", "train_steps",
           "train_wall_s", "train_timed_from_step", "s_per_step", "best_step", "mse5", "mse20", "mse20_lo",
           "mse20_hi", "e_kin", "sinkhorn", "n_windows", "finite", "blew_up", "vs", "ratio_mse20", "ratio_lo",
           "ratio_hi", "paired", "verdict", "ratio_mse1", "ratio_mse1_lo", "ratio_mse1_hi", "shared_with_table1", "folder"]


def timed_from_step(train: dict):
    """The first training step that train.json's wall time covers: 0 when every segment was timed; a
    later step when a killed segment left no time behind (train.py times a segment when it ends), so
    the wall time is of the steps from there on only. None for a run that was never trained."""
    segments = train.get("segments") or []
    return min(s["from_step"] for s in segments) if segments else None


def _train_cell(r: dict) -> str:
    """'steps (wall s)', with the steps the wall time covers when it is not all of them."""
    if r["kind"] not in ("gns", "sitl"):
        return ""
    first = r.get("train_timed_from_step")
    part = f" for steps {first}-{r['train_steps']}" if first else ""
    return f"{r['train_steps']} ({_f(r['train_wall_s'])}{part})"


def _f(x, digits: int = 3) -> str:
    if x is None or x == "":
        return ""
    if isinstance(x, bool):
        return str(x)
    if isinstance(x, int):
        return str(x)
    if isinstance(x, float) and not math.isfinite(x):
        return "diverged" if math.isnan(x) or x > 0 else str(x)
    return f"{x:.{digits}g}"


def _ci(value, lo, hi, digits: int = 3) -> str:
    """" [lo, hi]" of the interval of a finite `value`; " (one window: no interval)" when the interval
    is NaN (stats: no spread from one window); "" for a non-finite value (it reads "diverged" itself)."""
    if not (isinstance(value, (int, float)) and math.isfinite(value)):
        return ""
    nan = lo is None or hi is None or any(isinstance(x, float) and math.isnan(x) for x in (lo, hi))
    return " (one window: no interval)" if nan else f" [{_f(lo, digits)}, {_f(hi, digits)}]"


def _other_work(cores) -> str:
    """', beside x cores of other work' when the budget's timing measured it (lab.other_load)."""
    return "" if cores is None else f", beside {cores:.2g} cores of other work"


def sigma_a(results) -> float:
    """The dataset's acceleration scale sigma_a (the rms of metadata.json's per-axis acc_std, per-frame
    units): a training noise is stated against it, since the same noise_std is a different regime
    at another resolution (cpu: 1e-5 is about 0.1 sigma_a; at the paper's dx about 7 sigma_a)."""
    meta = json.loads((S.data_dir(results) / "metadata.json").read_text())
    return math.sqrt(sum(x * x for x in meta["acc_std"]) / len(meta["acc_std"]))


def _vs_cell(r: dict) -> str:
    """The row's MSE_20 / its solver's with the paired interval, digits enough to tell its ends apart."""
    d = ratio_digits(r["ratio_mse20"], r.get("ratio_lo"), r.get("ratio_hi"))
    return f"{_f(r['ratio_mse20'], d)}{_ci(r['ratio_mse20'], r['ratio_lo'], r['ratio_hi'], d)}"


def _ratio_cell(r: dict, key: str) -> str:
    """A paired ratio with its interval, digits enough to tell its ends apart ('' when absent)."""
    if r.get(key) is None:
        return ""
    lo, hi = r.get(f"{key}_lo"), r.get(f"{key}_hi")
    d = ratio_digits(r[key], lo, hi)
    return f"{_f(r[key], d)}{_ci(r[key], lo, hi, d)}"


def _noise_cell(noise, sig) -> str:
    if noise is None:
        return ""
    return _f(noise) if not sig else f"{_f(noise)} ({noise / sig:.2g} σ_a)"


def markdown(exp: S.Experiment, flat: list, profile: str, budget: dict, sig: float = None,
             floor: float = None, missing: tuple = ()) -> str:
    """study.md: the table of `flat` and the tables beside it; `missing` names the study's runs that
    are not in it (not made, or not current on this dataset and code)."""
    d = exp.data
    lines = [f"# SitL study, RPF 2D, profile {profile} ({d.n_particles} particles, frames every "
             f"{d.dt * d.write_every:g}, W = {d.write_every})", "",
             "MSE_20: mean over the test windows of every seed [95 % bootstrap interval over the windows]; "
             "vs solver: MSE_20 / the solver alone's at the same L on the same windows [95 % paired interval]. "
             "Diverged: a rollout that went non-finite, or stayed finite but blew up (MSE_Ekin above the frozen "
             "particles', i.e. a kinetic energy further from the truth than no motion at all; marked *)."
             + (f" Training noise also in units of the dataset's σ_a = {sig:.3g} (its acceleration scale)." if sig else ""),
             "",
             "| run | M | noise | training steps (wall s) | MSE_5 | MSE_20 | MSE_Ekin | vs solver | | step 1 vs solver |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    for r in flat:
        if r["group"] in ("authors_force", "authors"):
            continue
        tr = _train_cell(r)
        vs = "" if r.get("vs") is None else _vs_cell(r) + ("" if r.get("paired", True) else " (unpaired)")
        mse20 = _f(r["mse20"]) if not r["finite"] else f"{_f(r['mse20'])}{_ci(r['mse20'], r['mse20_lo'], r['mse20_hi'])}"
        lines.append(f"| {r['label']} | {_f(r.get('M'))} | {_noise_cell(r.get('noise_std'), sig)} | {tr} | {_f(r['mse5'])} | {mse20} | "
                     f"{_f(r.get('e_kin'))}{' *' if r.get('blew_up') else ''} | {vs} | {r.get('verdict', '')} | "
                     f"{_ratio_cell(r, 'ratio_mse1')} |")
    if missing:
        lines += ["", f"Not in the table: {len(missing)} of the study's runs are not made on the current dataset and "
                      f"code ({', '.join(missing)}). `make sitl-study PROFILE={profile}` makes them (resumable); "
                      f"`ONLY=\"...\"` a subset."]
    if budget:
        c = budget["cost"]
        lines += ["", f"Equal cost: GNS trained {budget['step_max']} steps, the cost of the reference SitL's "
                      f"{budget['sitl_step_max']} steps with their validations ({budget['sitl_training_s']:.0f} s "
                      f"predicted), from both models timed side by side in one process "
                      f"(sitl/train_cost.py): SitL {c['sitl']['s_per_step']:.3g} s / step and "
                      f"{c['sitl']['s_per_window']:.3g} s / validation window, GNS {c['gns']['s_per_step']:.3g} s / "
                      f"step and {c['gns']['s_per_window']:.3g} s / window"
                      f"{_other_work(budget.get('other_load'))}."]
    lines += authors_table1(flat)
    lines += learnability(exp, flat, floor)
    af = [r for r in flat if r["group"] == "authors_force"]
    if af:
        lines += ["", "The authors' force bug (solver only, no training):", "",
                  "| force | MSE_5 | MSE_20 | MSE_Ekin |", "|---|---|---|---|"]
        lines += [f"| {r['label']} | {_f(r['mse5'])} | {_f(r['mse20'])}{_ci(r['mse20'], r['mse20_lo'], r['mse20_hi'])} | "
                  f"{_f(r['e_kin'])} |" for r in af]
        lines.append("| paper's solver only (Table 1) | " + " | ".join(_f(PAPER_SOLVER[k]) for k in
                                                                      ("mse5", "mse20", "e_kin")) + " |")
    return "\n".join(lines) + "\n"


def plot(exp: S.Experiment, flat: list, path: Path, title: str):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    by = {r["name"]: r for r in flat}
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(11, 4.4), constrained_layout=True)
    ok = [r["mse20"] for r in flat if r["finite"] and r["mse20"] > 0]
    top = max(ok, default=1.0) * 10

    def err(r):
        return np.array([[r["mse20"] - r["mse20_lo"]], [r["mse20_hi"] - r["mse20"]]])

    # (a) SitL's training noise against the solver alone (and GNS), at SitL's L
    l0 = exp.model.substeps
    noise = sorted([r for r in flat if r["kind"] == "sitl" and r["L"] == l0 and r["group"] in ("reference", "noise")],
                   key=lambda r: r["noise_std"])
    floor = min([r["noise_std"] for r in noise if r["noise_std"] > 0], default=1e-5) / 10
    for i, r in enumerate(noise):
        x = r["noise_std"] if r["noise_std"] > 0 else floor
        y = r["mse20"] if r["finite"] else top
        ax1.errorbar([x], [y], yerr=err(r) if r["finite"] else None, fmt="D" if r["finite"] else "x", color="C1",
                     label="SitL" if i == 0 else None, capsize=3)
    for r in flat:
        if r["group"] == "seed":
            ax1.errorbar([r["noise_std"] * 1.15], [r["mse20"]], yerr=err(r) if r["finite"] else None, fmt="s",
                         color="C4", capsize=3, label=f"SitL, training seed {r['seed']}")
    for name, color, lab in ((f"solver_L{l0}", "C0", f"solver only (L={l0})"), ("gns", "C2", "GNS"),
                             ("gns_equal_cost", "C2", "GNS at SitL's training cost")):
        r = by.get(name)
        if r and r["finite"]:
            ax1.axhline(r["mse20"], color=color, ls="-" if name != "gns_equal_cost" else "--", lw=1, label=lab)
            ax1.axhspan(r["mse20_lo"], r["mse20_hi"], color=color, alpha=0.15)
    for ax in (ax1, ax2):
        for r in flat:
            if r["group"] == "baseline":
                frozen = r["name"] == "frozen"
                ax.axhline(r["mse20"], color="0.4", ls=":" if frozen else "-.", lw=1,
                           label="particles frozen (data alone)" if frozen else "constant velocity (no learning)")
    ax1.set_xscale("log")
    ax1.set_yscale("log")
    ax1.set(xlabel=f"SitL training noise std (0 plotted at {floor:g})", ylabel="test MSE$_{20}$",
            title="SitL's training noise")
    ax1.grid(True, which="both", alpha=0.3)
    ax1.legend(fontsize=7)
    # (b) temporal coarsening: the solver alone and SitL against M (and SitL with pushforward); the
    # series are shifted slightly in M so that markers at the same point (e.g. two diverged runs) both show
    diverged = {}
    for shift, (kind, groups, marker, color, lab) in zip((1.0, 1.0, 1.05), (
            ("solver", ("reference", "coarse"), "o", "C0", "solver only"),
            ("sitl", ("reference", "coarse"), "D", "C1", "SitL"),
            ("sitl", ("pushforward",), "^", "C3", "SitL with pushforward"))):
        pts = sorted([r for r in flat if r["kind"] == kind and r["group"] in groups], key=lambda r: r["M"])
        if not pts:
            continue
        ax2.plot([r["M"] * shift for r in pts], [r["mse20"] if r["finite"] else top for r in pts], "-", color=color,
                 alpha=0.4)
        for i, r in enumerate(pts):
            ax2.errorbar([r["M"] * shift], [r["mse20"] if r["finite"] else top], yerr=err(r) if r["finite"] else None,
                         fmt=marker if r["finite"] else "x", color=color, capsize=3, label=lab if i == 0 else None)
            if not r["finite"]:
                diverged.setdefault(r["M"], []).append(lab)
            elif r.get("blew_up"):
                ax2.annotate("blew up (MSE_Ekin above frozen)", (r["M"], r["mse20"]), textcoords="offset points",
                             xytext=(-4, 6), ha="right", fontsize=7)
    for m, labs in sorted(diverged.items()):  # x markers at the top; named in the legend, not over the data
        ax2.plot([], [], "x", color="0.3", label=f"diverged at M = {_g(m)}: {', '.join(labs)}")
    ax2.set_xscale("log")
    ax2.set_yscale("log")
    ax2.set(xlabel="temporal coarsening M (fine steps per substep; L = W / M substeps)",
            ylabel="test MSE$_{20}$", title="coarser solver steps")
    ax2.grid(True, which="both", alpha=0.3)
    ax2.legend(fontsize=7)
    fig.suptitle(title, fontsize=9)
    fig.savefig(path, dpi=130)
    plt.close(fig)


def run(profile: str, results, only=None) -> list:
    from sitl import generate

    exp = S.load(profile)
    generate.ready(exp, results)  # the profile's dataset (make sitl-data) must exist
    plan = runs(exp)
    names = select("--only", only, [r.name for r in plan])
    rows = {}
    for r in plan:
        if names is None or r.name in names:
            # one process per run: `make sitl-study ONLY=a` and `ONLY=b` may run at once (a second
            # process wanting the same run waits, then finds it done)
            with folder_lock(study_dir(results) / "runs" / r.name):
                rows[r.name] = stored_row(profile, exp, results, r) or make_run(profile, exp, results, r)
                if rows[r.name].get("stored"):
                    print(f"study: {r.name}: up to date (its training and evaluation records)", flush=True)
    out = study_dir(results)
    with folder_lock(out):  # the table of one process at a time, from every run finished by then
        return write_outputs(profile, exp, results, plan, rows, out)


def write_outputs(profile: str, exp: S.Experiment, results, plan: list, rows: dict, out: Path) -> list:
    """study.{csv,md,png,json} from `rows` (the runs made now) and the finished, current rows of the
    others (made earlier, or by another process meanwhile): the table always shows every current run."""
    for r in plan:
        if r.name not in rows:
            row = stored_row(profile, exp, results, r)
            if row is not None:
                rows[r.name] = row
    rows = {r.name: rows[r.name] for r in plan if r.name in rows}  # the study's order
    frozen = frozen_row(profile, exp, results, plan)
    flat = table(exp, rows, frozen["e_kin"]) + [frozen, constant_velocity_row(profile, exp, results, plan)]
    budget_path = out / "runs" / "gns_equal_cost" / "budget.json"
    budget = json.loads(budget_path.read_text()) if budget_path.exists() and "gns_equal_cost" in rows else None
    write_table(out / "study.csv", flat, columns=COLUMNS)
    missing = [r.name for r in plan if r.name not in rows]
    md = markdown(exp, flat, profile, budget, sigma_a(results), fine_floor(results), missing)
    write_text(out / "study.md", md)
    d = exp.data
    plot(exp, flat, out / "study.png", f"SitL study, RPF 2D, {profile}: {d.n_particles} particles, "
                                       f"W = {d.write_every}; mean over test windows, 95 % bootstrap intervals")
    write_text(out / "study.json", json.dumps({"profile": profile, "runs": [r for r in flat],
                                                "budget": budget}, indent=2, default=str) + "\n")
    from sitl import plot_curves

    solvers = {n: r for n, r in rows.items() if r["run"].kind == "solver" and "metrics" in r
               and n in (f"solver_L{exp.model.substeps}", f"solver_L{exp.model.substeps}_uniform")}
    plot_curves.from_study(results, rows, solvers, f"SitL study, {profile}: learning curves")
    print(md, flush=True)
    print(f"study: {len(flat)} rows -> {out / 'study.csv'}, study.md, study.png, curves.png", flush=True)
    return flat


def options(ap):
    ap.add_argument("--only", nargs="*", default=None, help="run only these runs (names of sitl/study.py's runs)")


def main(args):
    run(args.profile, args.results, args.only)


if __name__ == "__main__":
    profile_main(main, __doc__, options)
