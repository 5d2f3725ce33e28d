"""Solver-in-the-Loop on the 2D reverse Poiseuille flow (Toshev et al. 2024, Sec. 5 and App. B):
Table 1's models and Fig. 3's long rollouts, as a study of the protocol (lab.experiment).

What a run builds and measures; the machinery is the library sitl/ (sitl/README.md):

  fit run      one of Table 1's columns (`solver`, `gns`, `sitl`): LagrangeBench's Trainer trains the
               model (resumed from its checkpoint, reused while its training key holds: sitl/train.py;
               the solver alone is never trained), then it is rolled out on every test window
               (sitl/evaluate.py). Its row: MSE_5, MSE_20, MSE_Ekin, Sinkhorn with the bootstrap
               interval of MSE_20, the training's steps and wall time, the time per coarse step.
  fig3 run     the model's rollouts over Fig. 3's horizon (fig3.steps coarse steps, paper: 500) from
               every test window that long (sitl/fig3_rollouts.py): the MSE at every step.

Every run is computed on every run step (COMPUTE = "always"): the library's own keys decide what is
current (the dataset's, a training's, an evaluation's, the rollouts'), so a training that took hours is
never redone for an edit that cannot change it. The runs need LagrangeBench: the folder's rules.mk runs
its steps in .venv-lb. Table 1 (sitl/table1.py) and the study of when SitL helps (sitl/study.py, `make
sitl-study`) read the fit runs' metrics files.
"""
import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

import sph
from sph.cases import rpf
from sph.errors import require
from sitl import settings as S
from lab.protocol import Table

Settings = S.Experiment
"""A profile of config.yaml: data, model, train, eval, fig3, cost, study (sitl/settings.py)."""

COMPUTE = "always"
KINDS = ("fit", "fig3")
NOT_KEYED = {"key": False}


@dataclass(frozen=True)
class Run:
    """One model's training and evaluation (`kind` "fit", named after the model) or its Fig. 3 rollouts
    (`kind` "fig3", named fig3_<model>). `settings` is the profile the library reads (its own keys cover
    what of it each step uses)."""

    name: str
    model: str
    kind: str
    settings: Settings = field(metadata=NOT_KEYED, repr=False)
    groups: tuple = ()

    def __post_init__(self):
        require(self.model in S.MODELS, "model", f"must be one of {list(S.MODELS)}, got {self.model!r}")
        require(self.kind in KINDS, "kind", f"must be one of {list(KINDS)}, got {self.kind!r}")


def runs(s: Settings) -> list:
    """Each model of the profile fitted (groups table1 and fig3: Fig. 3 rolls out the trained models),
    then its Fig. 3 rollouts (group fig3)."""
    fits = [Run(m, m, "fit", s, ("table1", "fig3")) for m in s.models]
    return fits + [Run(f"fig3_{m}", m, "fig3", s, ("fig3",)) for m in s.models]


TABLE = Table(rows="metrics", file=lambda run: "metrics.csv" if run.kind == "fit" else "fig3_runs.csv")


def scene(run):
    """(Scene, Numerics) of the flow every model learns: the RPF scene on the dataset's lattice (before
    its relaxation, sitl/generate.py) with the per-particle body force, and the data run's numerics.
    The solver alone and SitL's in-loop solver step this scene at the coarse step."""
    data = run.settings.data
    return rpf.scene(data.dx, data.material, sph.Effects(), g=data.g), data.numerics()


def compute(run, folder: Path, progress: bool = True) -> dict:
    """Train and evaluate the model (a fit run) or roll it out over Fig. 3's horizon (a fig3 run), each
    step skipped by the library when current; the run's result: what its table row shows."""
    from sitl import common  # noqa: F401  (first: it sets up LagrangeBench)
    from sitl import evaluate, fig3_rollouts, train

    results, exp = Path(folder).parents[1], run.settings
    if run.kind == "fig3":
        rec = fig3_rollouts.make(exp, results, run.model)
        last = [m[-1] for m in rec["mse_steps"]]
        return {"model": run.model, "steps": rec["steps"], "n_windows": rec["n_windows"], "mse_last": last,
                "inputs": rec["inputs"]}
    train.train(exp, results, run.model)
    evaluate.evaluate(exp, results, run.model)
    m = json.loads(S.metrics_path(results, run.model).read_text())
    keep = ("mse5", "mse20", "ci_mse20", "e_kin", "sinkhorn", "n_rollouts", "finite", "train_steps", "train_wall_s",
            "s_per_coarse_step", "inputs")
    return {"model": run.model, **{k: m.get(k) for k in keep}}


def metrics(run, traj) -> dict:
    """The run's row: a fit run's test-set errors (err_*, LagrangeBench's metrics, mean over the test
    windows) with MSE_20's bootstrap interval; a fig3 run's MSE at the last step (mean of the finite windows)."""
    r = traj["result"]
    if run.kind == "fig3":
        last = np.asarray(r["mse_last"], float)
        ok = np.isfinite(last)
        return {"run": run.name, "model": run.model, "steps": r["steps"], "n_windows": r["n_windows"],
                "diverged": int((~ok).sum()), "err_mse_last": float(last[ok].mean()) if ok.any() else float("nan")}
    lo, hi = r["ci_mse20"] or (None, None)
    return {"run": run.name, "model": run.model, "err_mse5": r["mse5"], "err_mse20": r["mse20"], "mse20_lo": lo,
            "mse20_hi": hi, "err_e_kin": r["e_kin"], "err_sinkhorn": r["sinkhorn"], "n_windows": r["n_rollouts"],
            "finite": r["finite"], "train_steps": r["train_steps"], "train_wall_s": r["train_wall_s"],
            "s_per_coarse_step": r["s_per_coarse_step"]}
