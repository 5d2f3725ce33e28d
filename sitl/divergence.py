"""Where the coarse rollouts break (issue 21's study, beyond the paper): the solver alone and SitL at
L substeps per frame (M = write_every / L), step by step on the study's test windows.

`make sitl-study` reports a coarse SitL run as "diverged" when any of its 20-step test rollouts turns
non-finite, while the solver alone at the same L may stay finite and still be far off. This script
tells the two apart, on the same windows and with the same LagrangeBench case and model as
sitl/evaluate.py, for the solver alone and for SitL's best checkpoint (the one evaluated) and its
last one (the most trained), and, when the study trained one at that L (study.pushforward, beyond
the paper), SitL trained with pushforward (best and last checkpoint):

- the position MSE at every rollout step (LagrangeBench's: the mean squared periodic displacement
  from the ground truth over particles and coordinates), beside particles frozen at the last input
  frame (sitl/baseline.py's scale);
- the first step whose prediction is non-finite, and its cause: an overflow of the model's in-model
  neighbour lists (sitl/model.py turns one into NaN; the overflow counter in the model state
  rises), an overflow of LagrangeBench's own graph list right after its re-allocation, or a
  non-finite state of the solver itself;
- the smallest periodic pair distance / dx of the last finite frame (particles that pile up are
  what overflows a list sized for the lattice).

    make sitl-divergence PROFILE=cpu          # every coarse L of study.substeps
    .venv-lb/bin/python sitl/divergence.py --profile cpu --substeps 2 [--windows 10]

Writes results/<profile>/sitl_study/divergence_L<L>.{csv,md,png,json}; the json keeps the summary and
the key of its inputs (the dataset, both runs' settings, SitL's training record, this code and the
model's), and a call whose key matches repeats nothing. Needs the study's solver_L<L> and sitl_L<L>
runs (`make sitl-study ONLY="solver_L2 sitl_L2"`); trains and evaluates nothing.
"""
import json
from pathlib import Path

from sitl import common as C  # first: it sets up LagrangeBench

import jax
import jax.numpy as jnp
import numpy as np
from lagrangebench.utils import load_haiku

from sitl import baseline
from sitl import model as M
from sitl import settings as S
from sitl import study
from lab.cli import profile_main
from lab.atomic import write_text
from lab.tables import write_table
from lab.configtools import to_mapping
from lab.keys import digest, files_digest

HERE = Path(__file__).resolve().parent
CODE = [HERE / f for f in ("divergence.py", "model.py", "common.py")]

CAUSES = ("finite", "in-model list overflow", "graph list overflow", "non-finite solver state")


class Roller:
    """One model (its LagrangeBench case, haiku model and weights) rolled out window by window."""

    def __init__(self, exp: S.Experiment, folder: Path, kind: str, ckp: Path = None):
        path = S.data_dir(folder)
        data_train, _, self.test = C.datasets(exp, path)
        self.case = C.case(exp, data_train, kind)
        self.model = C.model(exp, kind, data_train, self.case)
        self.isl, self.n = exp.model.input_seq_length, exp.eval.n_rollout_steps
        pos, ptype = self.test[0]
        sample = (jnp.asarray(pos[:, :self.isl]), jnp.asarray(ptype))
        features, self.nbrs = self.case.allocate_eval(sample)  # kept across windows, as LagrangeBench does
        if ckp is None:
            self.params, self.state = self.model.init(jax.random.PRNGKey(0), (features, sample[1]))
            self.step = 0
        else:
            self.params, self.state, _, self.step = load_haiku(str(ckp))
        self.apply = jax.jit(self.model.apply)
        self.preprocess = jax.jit(self.case.preprocess_eval)
        self.integrate = jax.jit(self.case.integrate)
        bounds = self.test.metadata["bounds"]
        self.box = np.array([b[1] - b[0] for b in bounds], dtype=np.float64)
        self.dx = float(self.test.metadata["dx"])

    def min_pair(self, r: np.ndarray) -> float:
        """Smallest periodic distance between two particles / dx."""
        d = baseline.wrap(r[:, None, :] - r[None, :, :], self.box)
        dist = np.sqrt((d**2).sum(-1))
        np.fill_diagonal(dist, np.inf)
        return float(dist.min() / self.dx)

    def window(self, i: int) -> dict:
        """{"mse": [per step, NaN after a non-finite prediction], "first_bad": step or None, "cause",
        "min_pair_dx": of the last finite frame}."""
        raw, ptype = self.test[i]
        pos = np.asarray(raw, np.float64)
        ptype = jnp.asarray(ptype)
        current = jnp.asarray(raw[:, :self.isl])  # as sitl/evaluate.py feeds it
        nbrs, state = self.nbrs, self.state
        mse, first_bad, cause = [], None, CAUSES[0]
        for k in range(self.n):
            features, new = self.preprocess((current, ptype), nbrs)
            if bool(new.did_buffer_overflow):
                _, nbrs = self.case.allocate_eval((current, ptype))
                self.nbrs = nbrs
                features, new = self.preprocess((current, ptype), nbrs)
                if bool(new.did_buffer_overflow):
                    first_bad, cause = k, CAUSES[2]
                    break
            nbrs = new
            before = M.overflowed(state)
            pred, state = self.apply(self.params, state, (features, ptype))
            nxt = self.integrate(pred, current)
            if not bool(jnp.all(jnp.isfinite(nxt))):
                first_bad, cause = k, CAUSES[1] if M.overflowed(state) > before else CAUSES[3]
                break
            current = jnp.concatenate([current[:, 1:], nxt[:, None]], axis=1)
            d = baseline.wrap(np.asarray(nxt, np.float64) - pos[:, self.isl + k], self.box)
            mse.append(float(np.mean(d**2)))
        mse += [float("nan")] * (self.n - len(mse))
        return {"mse": mse, "first_bad": first_bad, "cause": cause,
                "min_pair_dx": self.min_pair(np.asarray(current[:, -1], np.float64))}


def located(profile: str, exp: S.Experiment, results, substeps: int) -> dict:
    """{"solver": (experiment, folder), "sitl": (experiment, folder, its training record)} of the
    study's runs at `substeps`, plus "sitl_pushforward" (the same) when the study has a finished
    pushforward run there; an error naming the run when solver or SitL is not in the study or not
    trained."""
    by_name = {r.name: r for r in study.runs(exp)}
    out = {}
    for kind in ("solver", "sitl"):
        name = f"{kind}_L{substeps}"
        if name not in by_name:
            raise KeyError(f"--substeps {substeps}: the study of profile {profile} has no run {name} "
                           f"(its coarse runs: study.substeps {list(exp.study.substeps)}, "
                           f"not model.substeps {exp.model.substeps})")
        out[kind] = study.locate(profile, exp, results, by_name[name])
    out["sitl"] += (_finished(out["sitl"][1], f"sitl_L{substeps}", profile, required=True),)
    pf = by_name.get(f"sitl_L{substeps}_pushforward")
    if pf is not None:
        rexp, folder = study.locate(profile, exp, results, pf)
        rec = _finished(folder, pf.name, profile, required=False)
        if rec is not None:
            out["sitl_pushforward"] = (rexp, folder, rec)
    return out


def _finished(folder: Path, name: str, profile: str, required: bool):
    """The training record (text) of a finished SitL run, else an error (`required`) or None."""
    ckp = S.ckpt_dir(folder, "sitl")
    rec = (ckp / "train.json").read_text() if (ckp / "train.json").exists() else "{}"
    if json.loads(rec).get("complete"):
        return rec
    msg = f"{ckp}: no finished training of {name}; run `make sitl-study PROFILE={profile} ONLY={name}` first"
    if required:
        raise FileNotFoundError(msg)
    print(f"divergence: {msg} (diagnosed without it)", flush=True)
    return None


def inputs_key(runs: dict, results, windows) -> str:
    """What a diagnosis depends on: the dataset's record, both runs' settings, SitL's training
    record (its checkpoints), the window count and the code (module docstring)."""
    data = (S.data_dir(results) / "generate.json").read_text()
    key = {"data": data, "solver": to_mapping(runs["solver"][0]), "sitl": to_mapping(runs["sitl"][0]),
           "train": runs["sitl"][2], "windows": windows, "code": files_digest(CODE)}
    if "sitl_pushforward" in runs:
        key["pushforward"] = (to_mapping(runs["sitl_pushforward"][0]), runs["sitl_pushforward"][2])
    return digest(key)


def models(runs: dict) -> dict:
    """{label: Roller} for the solver alone and SitL's best and last checkpoints (and those of SitL
    with pushforward, when trained)."""
    sexp, sfolder = runs["solver"]
    out = {"solver alone": Roller(sexp, sfolder, "solver")}
    for key, name in (("sitl", "SitL"), ("sitl_pushforward", "SitL with pushforward")):
        if key in runs:
            rexp, folder, _ = runs[key]
            ckp = S.ckpt_dir(folder, "sitl")
            out[f"{name}, best checkpoint"] = Roller(rexp, folder, "sitl", ckp / "best")
            out[f"{name}, last checkpoint"] = Roller(rexp, folder, "sitl", ckp)
    return out


def diagnose(runs: dict, exp: S.Experiment, windows: int = None):
    """(one row per model and test window (module docstring), the number of windows)."""
    rollers = models(runs)
    any_roller = next(iter(rollers.values()))
    n_win = C.n_windows(exp, any_roller.test) if windows is None else min(windows, C.n_windows(exp, any_roller.test))
    rows = []
    for label, ro in rollers.items():
        for i in range(n_win):
            w = ro.window(i)
            rows.append({"model": label, "checkpoint_step": ro.step, "window": i, "seed": ro.test.seed_of(i), **w})
    return rows, n_win


def summary(rows: list, frozen: np.ndarray, steps=(1, 5, 10, 15, 20)) -> list:
    """Per model: windows, non-finite windows by cause, the median first non-finite step, the median
    MSE at `steps` over the windows finite there, and the windows above the frozen particles there."""
    out, n = [], frozen.shape[1]
    steps = sorted({s for s in steps if s <= n} | {n})
    for label in dict.fromkeys(r["model"] for r in rows):
        rs = [r for r in rows if r["model"] == label]
        mse = np.array([r["mse"] for r in rs])
        bad = [r["first_bad"] for r in rs if r["first_bad"] is not None]
        row = {"model": label, "checkpoint_step": rs[0]["checkpoint_step"], "windows": len(rs),
               "non_finite": len(bad), "median_first_bad_step": float(np.median(bad)) + 1 if bad else None,
               **{f"cause: {c}": sum(r["cause"] == c for r in rs) for c in CAUSES[1:]},
               "median_min_pair_dx": float(np.median([r["min_pair_dx"] for r in rs]))}
        for s in steps:
            col = mse[:, s - 1]
            ok = np.isfinite(col)
            row[f"mse step {s}"] = float(np.median(col[ok])) if ok.any() else None
            row[f"finite at step {s}"] = int(ok.sum())
            row[f"above frozen at step {s}"] = int((~ok | (col > frozen[:len(rs), s - 1])).sum())
        out.append(row)
    return out


def write(rows: list, summ: list, frozen: np.ndarray, substeps: int, out: Path, exp: S.Experiment):
    import pandas as pd
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out.mkdir(parents=True, exist_ok=True)
    stem = out / f"divergence_L{substeps}"
    long = [{"model": r["model"], "checkpoint_step": r["checkpoint_step"], "window": r["window"], "seed": r["seed"],
             "step": k + 1, "mse": m, "first_bad_step": None if r["first_bad"] is None else r["first_bad"] + 1,
             "cause": r["cause"], "min_pair_dx": r["min_pair_dx"]} for r in rows for k, m in enumerate(r["mse"])]
    write_table(stem.with_suffix(".csv"), long)
    t = pd.DataFrame(summ)
    m = exp.data.write_every / substeps
    head = (f"# Where the coarse rollouts break: L = {substeps} (M = {m:.3g}), {len(rows) // len(summ)} "
            "test windows\n\n`sitl/divergence.py`. Median over the windows still finite at that step; "
            "'above frozen': windows non-finite or with an MSE above particles frozen at the last input frame "
            "(sitl/baseline.py). A non-finite step is counted from 1.\n\n")
    steps = [int(c.rsplit(" ", 1)[-1]) for c in t.columns if c.startswith("mse step ")]
    write_text(
        stem.with_suffix(".md"), head + t.to_markdown(index=False, floatfmt=".3g") + "\n\nFrozen particles, median MSE at steps "
        + ", ".join(map(str, steps)) + ": " + ", ".join(f"{np.median(frozen[:, s - 1]):.3g}" for s in steps) + "\n")
    fig, ax = plt.subplots(figsize=(6.4, 4.2))
    steps = np.arange(1, frozen.shape[1] + 1)
    ax.plot(steps, np.median(frozen, 0), "k--", label="frozen particles")
    for label in dict.fromkeys(r["model"] for r in rows):
        mse = np.array([r["mse"] for r in rows if r["model"] == label])
        med = np.array([np.median(c[np.isfinite(c)]) if np.isfinite(c).any() else np.nan for c in mse.T])
        n_ok = np.isfinite(mse).sum(0)
        line, = ax.plot(steps, med, marker="o", ms=3, label=label)
        gone = np.nonzero(n_ok < len(mse))[0]
        if len(gone):
            ax.axvline(steps[gone[0]], color=line.get_color(), lw=0.8, ls=":")
    ax.set_yscale("log")
    ax.set_xlabel("rollout step (coarse frames)")
    ax.set_ylabel("position MSE (median over finite windows)")
    ax.set_title(f"RPF 2D, L = {substeps} (M = {m:.3g}); dotted: first non-finite window")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(stem.with_suffix(".png"), dpi=130)
    plt.close(fig)
    return stem


def diagnosis(profile: str, exp: S.Experiment, results, substeps: int, windows: int = None) -> dict:
    """The diagnosis at `substeps` (made, or read back when its inputs are unchanged)."""
    runs = located(profile, exp, results, substeps)
    key = inputs_key(runs, results, windows)
    side = study.study_dir(results) / f"divergence_L{substeps}.json"
    stem = side.with_suffix("")
    try:
        done = json.loads(side.read_text())
    except (OSError, ValueError):
        done = {}
    if done.get("key") == key and all(stem.with_suffix(x).exists() for x in (".csv", ".md", ".png")):
        print(f"divergence L={substeps}: up to date ({side})", flush=True)
        return done
    rexp = runs["sitl"][0]  # the study's settings of the run (its test windows)
    rows, n_win = diagnose(runs, rexp, windows)
    frozen = baseline.frozen_steps(rexp, S.data_dir(results), n_win)
    summ = summary(rows, frozen)
    write(rows, summ, frozen, substeps, side.parent, rexp)
    out = {"substeps": substeps, "windows": n_win, "summary": summ, "key": key}
    write_text(side, json.dumps(out, indent=2) + "\n")  # last: a killed diagnosis is made again
    print(stem.with_suffix(".md").read_text(), flush=True)
    return out


def options(ap):
    ap.add_argument("--substeps", type=int, nargs="*", default=None,
                    help="L of the study's coarse runs (default: every study.substeps but model.substeps)")
    ap.add_argument("--windows", type=int, default=None, help="the first N test windows (default: all)")


def main(args):
    exp = S.load(args.profile)
    subs = args.substeps or [n for n in exp.study.substeps if n != exp.model.substeps]
    return [diagnosis(args.profile, exp, args.results, n, args.windows) for n in subs]


if __name__ == "__main__":
    profile_main(main, __doc__, options)
