"""Settings of the Solver-in-the-Loop experiment (Toshev et al. 2024, Sec. 5 / App. B, Fig. 3,
Table 1): experiments/sitl/config.yaml (linked here as sitl/config.yaml) -> frozen, validated dataclasses, paths and fingerprints.

Sections of a profile: `data` (the RPF 2D dataset our solver generates), `model` (GNS / SitL
architecture), `train` (LagrangeBench Trainer settings), `eval` (test-set inference), `fig3` and
`cost` (the accuracy-cost comparison, sitl/cost.py).
An unknown or mistyped key fails with a message naming it (e.g. ``profiles.smoke.train.stpes``).
"""
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Optional

from lab.configtools import from_mapping, load_profile, merge, require, to_mapping
from lab.keys import code_fingerprint, digest, files_digest
from sitl.rpf_data import Data  # noqa: F401  (S.Data: the dataset's settings)

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
CONFIG = HERE / "config.yaml"
MODELS = ("solver", "gns", "sitl")
"""Table 1's columns: the SPH solver alone at the coarse step, LagrangeBench's GNS, and SitL."""


SOLVER_FORCES = ("per_particle", "uniform")
EXTRA_INPUTS = ("solver_acc", "substep")
STARTS = ("frame_average", "consistent")


@dataclass(frozen=True)
class Model:
    """GNS (LagrangeBench) and the SitL corrector share this architecture (paper App. B).

    latent_dim, num_mlp_layers, num_mp_steps   GNS width, MLP depth, message-passing layers
    substeps           SitL: SPH substeps L of dt_frame / L per coarse step (paper Listing 1: 3)
    input_seq_length   positions per input (2 = one velocity)
    capacity_multiplier  SitL's in-model neighbour lists (SPH and graph), relative to the training
                       data's maximum; an overflow is never silent (NaN output, state['overflow'])
    solver_force       the body force of SitL's in-loop solver (and of the solver alone):
                       "per_particle", the data's own RPF force (paper Sec. 5), or "uniform", the
                       authors' (+g, 0) for every particle (sitl/authors_force.py): a known bias the
                       corrector can learn, since it always sees the data's per-particle force
    extra_inputs       SitL's corrector inputs besides LagrangeBench's (velocity, the data's force,
                       the graph): any of "solver_acc" (the solver's acceleration at this substep, in
                       the output's normalised units) and "substep" (the substep index, one-hot)
    start              the solver's first velocity from the two input frames: "frame_average"
                       (u = d(r^0, r^-1) / Delta t, LagrangeBench's, the paper's) or "consistent"
                       (u + (Delta t / 2)(1 - 1 / W) a(r^0), as sitl/cost.py's fine solver)
    """

    latent_dim: int = 64
    num_mlp_layers: int = 2
    num_mp_steps: int = 10
    substeps: int = 3
    input_seq_length: int = 2
    capacity_multiplier: float = 1.5
    solver_force: str = "per_particle"
    extra_inputs: tuple[str, ...] = ()
    start: str = "frame_average"

    def __post_init__(self):
        require(self.latent_dim >= 1, "model.latent_dim", "must be >= 1")
        require(self.num_mlp_layers >= 1, "model.num_mlp_layers", "must be >= 1")
        require(self.num_mp_steps >= 1, "model.num_mp_steps", "must be >= 1")
        require(self.substeps >= 1, "model.substeps", f"must be >= 1, got {self.substeps}")
        require(self.input_seq_length >= 2, "model.input_seq_length",
                f"needs at least 2 positions (one velocity), got {self.input_seq_length}")
        require(self.capacity_multiplier >= 1, "model.capacity_multiplier", "must be >= 1")
        require(self.solver_force in SOLVER_FORCES, "model.solver_force",
                f"{self.solver_force!r} is not one of {', '.join(SOLVER_FORCES)}")
        for i, name in enumerate(self.extra_inputs):
            require(name in EXTRA_INPUTS, f"model.extra_inputs[{i}]", f"{name!r} is not one of {', '.join(EXTRA_INPUTS)}")
        require(len(set(self.extra_inputs)) == len(self.extra_inputs), "model.extra_inputs",
                f"lists an input twice: {list(self.extra_inputs)}")
        require(self.start in STARTS, "model.start", f"{self.start!r} is not one of {', '.join(STARTS)}")


def check_pushforward(steps, unrolls, probs, prefix: str):
    """LagrangeBench's pushforward schedule (train/strats.py): one entry per stage in each list; the
    first stage holds from step 0 (steps[0] < 0), stages start at increasing steps, unrolls >= 0, the
    weights >= 0 and the first one > 0. `prefix` names the keys in the message (e.g. "train.pushforward_")."""
    n = len(steps)
    require(n >= 1 and len(unrolls) == n and len(probs) == n, f"{prefix}steps",
            f"{prefix}steps, unrolls and probs need one entry each per stage, got {len(steps)}, {len(unrolls)}, "
            f"{len(probs)}")
    require(steps[0] < 0 and list(steps) == sorted(set(steps)), f"{prefix}steps",
            f"must start below 0 (the first stage holds from step 0) and increase, got {list(steps)}")
    require(all(u >= 0 for u in unrolls), f"{prefix}unrolls", f"must be >= 0, got {list(unrolls)}")
    require(all(q >= 0 for q in probs) and probs[0] > 0, f"{prefix}probs",
            f"must be >= 0, the first > 0, got {list(probs)}")


@dataclass(frozen=True)
class Train:
    """LagrangeBench Trainer settings (no pushforward by default, as in the paper).

    step_max           training steps per model
    lr_start, lr_final, lr_decay_steps, lr_decay_rate   exponential decay (LagrangeBench's optax);
                       paper App. B.2 and the authors' last yaml: lr_start 1e-3
    noise_std          GNS's random-walk input noise (paper App. B.2: 1e-3)
    sitl_noise_std     SitL's (paper App. B.2 and the authors' final SitL script: 1e-5); "solver" is
                       evaluated with SitL's case (its normalisation cancels in its output)
    eval_steps         validate (20-step MSE on `eval_n_trajs` valid rollouts) and checkpoint
    eval_n_trajs       validation windows, taken round-robin over the seeds (sitl/common.py)
    log_steps          print the training loss
    seed               model init, noise and data-loader seed
    dtype              precision of the networks and the in-model solver
    pushforward_steps, pushforward_unrolls, pushforward_probs
                       LagrangeBench's pushforward schedule (Brandstetter et al. 2022): from training
                       step steps[i] on, a sample is first rolled out by one of unrolls[:i+1] model
                       steps without gradient, drawn with weights probs[:i+1]. The paper trains without
                       (App. B.2: steps [-1], unrolls [0], probs [1], the default); the study's
                       pushforward runs use LagrangeBench's own schedule scaled to step_max
    """

    step_max: int = 1000
    lr_start: float = 1e-3
    lr_final: float = 1e-6
    lr_decay_steps: float = 1e5
    lr_decay_rate: float = 0.1
    noise_std: float = 1e-3
    sitl_noise_std: float = 1e-5
    eval_steps: int = 500
    log_steps: int = 100
    eval_n_trajs: int = 25
    seed: int = 0
    dtype: str = "float32"
    num_workers: int = 0
    pushforward_steps: tuple[int, ...] = (-1,)
    pushforward_unrolls: tuple[int, ...] = (0,)
    pushforward_probs: tuple[float, ...] = (1.0,)

    def __post_init__(self):
        require(self.step_max >= 1, "train.step_max", "must be >= 1")
        check_pushforward(self.pushforward_steps, self.pushforward_unrolls, self.pushforward_probs,
                          "train.pushforward_")
        require(0 < self.lr_final <= self.lr_start, "train.lr_final", "must be in (0, lr_start]")
        require(self.noise_std >= 0, "train.noise_std", "must be >= 0")
        require(self.sitl_noise_std >= 0, "train.sitl_noise_std", "must be >= 0")
        require(1 <= self.eval_steps <= self.step_max, "train.eval_steps", "must be in [1, step_max]")
        require(self.log_steps >= 1, "train.log_steps", "must be >= 1")
        require(self.eval_n_trajs >= 1, "train.eval_n_trajs", "must be >= 1")
        require(self.dtype in ("float32", "float64"), "train.dtype", f"{self.dtype!r} is not float32 or float64")

    def noise(self, kind: str) -> float:
        """The training noise of model `kind` (GNS: noise_std; SitL and the solver: sitl_noise_std)."""
        return self.noise_std if kind == "gns" else self.sitl_noise_std

    @property
    def max_unroll(self) -> int:
        """The longest pushforward unroll: a training sample needs this many frames more."""
        return max(self.pushforward_unrolls)


@dataclass(frozen=True)
class Eval:
    """Test-set inference (LagrangeBench `infer`): `n_rollout_steps` = 20 gives MSE_20.

    n_trajs            test rollouts (-1: all 20-step windows of the test split, of every seed;
                       otherwise the first n_trajs taken round-robin over the seeds)
    metrics_stride     stride of e_kin and sinkhorn along the rollout
    batch_size         rollouts evaluated together
    bootstrap          resamples (over test windows) of the 95 % interval of each mean (sitl/stats.py)
    """

    n_rollout_steps: int = 20
    n_trajs: int = -1
    metrics_stride: int = 1
    batch_size: int = 1
    bootstrap: int = 2000

    def __post_init__(self):
        require(self.n_rollout_steps >= 5, "eval.n_rollout_steps", "must be >= 5 (MSE_5 is reported)")
        require(self.n_trajs == -1 or self.n_trajs >= 1, "eval.n_trajs", "must be -1 or >= 1")
        require(self.metrics_stride >= 1, "eval.metrics_stride", "must be >= 1")
        require(self.batch_size >= 1, "eval.batch_size", "must be >= 1")
        require(self.bootstrap >= 100, "eval.bootstrap", f"must be >= 100, got {self.bootstrap}")


@dataclass(frozen=True)
class Fig3:
    """Fig. 3: velocity magnitude of the test rollout `rollout` at these coarse steps, from rollouts
    of `steps` coarse steps (the paper's stamps reach 500) from every test window that long
    (sitl/fig3_rollouts.py), with the MSE against the rollout step beside it."""

    stamps: tuple[int, ...] = (0, 5, 10, 20)
    rollout: int = 0
    steps: int = 20

    def __post_init__(self):
        require(len(self.stamps) >= 1 and all(s >= 0 for s in self.stamps), "fig3.stamps",
                "needs non-negative coarse-step indices")
        require(self.steps >= 1, "fig3.steps", f"must be >= 1, got {self.steps}")
        require(max(self.stamps) <= self.steps, "fig3.stamps",
                f"stamp {max(self.stamps)} lies beyond the rollout's fig3.steps = {self.steps}")


@dataclass(frozen=True)
class Cost:
    """The accuracy-cost comparison (sitl/cost.py): MSE_20 on the test split against inference time
    per coarse step Delta t = dt * write_every (one stored frame).

    coarsening   temporal coarsening factors M of the solver-only points: the solver module
                 (model.py, correction off) advances each Delta t in L = write_every / M substeps of
                 M dt, from LagrangeBench's two input frames; M must divide data.write_every (M >
                 write_every would be a step longer than a frame). M = 1 is that module at the data's
                 own dt; the fine solver (the data's integrator, started consistently) is always
                 evaluated besides
    repeats      timed calls of one jitted coarse step per point, after compilation (median)
    """

    coarsening: tuple[int, ...] = (1, 2, 5, 10, 20)
    repeats: int = 30

    def __post_init__(self):
        require(len(self.coarsening) >= 1, "cost.coarsening", "needs at least one factor M")
        for i, m in enumerate(self.coarsening):
            require(m >= 1, f"cost.coarsening[{i}]", f"must be >= 1, got {m}")
        require(len(set(self.coarsening)) == len(self.coarsening), "cost.coarsening",
                f"has repeated factors: {list(self.coarsening)}")
        require(self.repeats >= 3, "cost.repeats", f"must be >= 3, got {self.repeats}")


@dataclass(frozen=True)
class Study:
    """`make sitl-study` (sitl/study.py): when does SitL beat the solver alone? Every run is a
    training (or an evaluation) of its own, cached and resumable like Table 1's.

    noise            SitL's training noise sweep (paper: 1e-5); test MSE_20 against solver only's
    substeps         coarse SitL (and the solver alone) at L substeps per frame, M = write_every / L,
                     where the solver alone fails; trained at the paper's noise
    train_seeds      further training seeds of SitL (paper settings): the spread between trainings
    gns_equal_cost   GNS trained for as many steps as cost what SitL's training costs (both timed side
                     by side, sitl/train_cost.py), the comparison at equal training cost
    authors_force_data  keys over `data` for the dataset of the authors' force bug (their uniform
                     force against the per-particle one, solver only, no training): the paper's
                     resolution and frame interval on cpu / paper; {} = the profile's own dataset
    pushforward      beyond the paper: {substeps: [L, ...], steps, unrolls, probs}: SitL at these L
                     trained also with this pushforward schedule (train.pushforward_*), at the paper's
                     noise; does training on its own rolled-out states keep the coarse solver stable?
                     None: no such runs
    overrides        keys over the whole profile for every study run (smoke: tiny sizes); a run whose
                     settings equal the profile's (e.g. SitL at the paper's noise) is Table 1's own
    authors_table1   Table 1 as its authors ran it: the solver alone and SitL with the authors'
                     uniform force in the in-loop solver (model.solver_force), GNS as before. The
                     SitL run is the positive control: a known, learnable bias (the corrector sees the
                     data's per-particle force), which it must remove (MSE_20 >= 10x below its solver's)
    extra_inputs     is the correct-force residual learnable? SitL whose corrector also sees these
                     (model.extra_inputs, e.g. [solver_acc, substep]); () = no such run
    consistent_start the solver alone started with the velocity at t0 (model.start "consistent"):
                     how much of its error is the start-up lag of the frame-averaged velocity
    gns_noise        GNS's training noise sweep besides train.noise_std (LagrangeBench's RPF: 3e-4)
    gns_input_seq    GNS with these input lengths besides model.input_seq_length (LagrangeBench's
                     default: 6 positions, 5 velocities); its test windows are longer, so it is
                     compared with the solver alone unpaired
    long_steps       the reference GNS and SitL (`long_models`) trained again for this many steps, the
                     learning-rate decay stretched over them (train.lr_decay_steps = long_steps, as the
                     cpu profile sets it to step_max): are their curves still moving at step_max?
                     0 = no such runs
    long_models      the models of the long trainings (gns, sitl)
    """

    noise: tuple[float, ...] = (0.0, 1e-5, 3e-5, 3e-4)
    substeps: tuple[int, ...] = (2, 1)
    train_seeds: tuple[int, ...] = (1,)
    gns_equal_cost: bool = True
    authors_force_data: Any = None
    pushforward: Any = None
    overrides: Any = None
    authors_table1: bool = True
    extra_inputs: tuple[str, ...] = ("solver_acc", "substep")
    consistent_start: bool = True
    gns_noise: tuple[float, ...] = (3e-4, 1e-4)
    gns_input_seq: tuple[int, ...] = (6,)
    long_steps: int = 0
    long_models: tuple[str, ...] = ("gns", "sitl")

    def __post_init__(self):
        require(isinstance(self.long_steps, int) and self.long_steps >= 0, "study.long_steps",
                f"must be an integer >= 0 (0: no long trainings), got {self.long_steps!r}")
        for i, m in enumerate(self.long_models):
            require(m in ("gns", "sitl"), f"study.long_models[{i}]", f"{m!r} is not gns or sitl (the trained models)")
        for i, n in enumerate(self.noise):
            require(n >= 0, f"study.noise[{i}]", f"must be >= 0, got {n}")
        for i, n in enumerate(self.gns_noise):
            require(n >= 0, f"study.gns_noise[{i}]", f"must be >= 0, got {n}")
        for i, n in enumerate(self.gns_input_seq):
            require(isinstance(n, int) and n >= 2, f"study.gns_input_seq[{i}]", f"must be an integer >= 2, got {n!r}")
        for i, name in enumerate(self.extra_inputs):
            require(name in EXTRA_INPUTS, f"study.extra_inputs[{i}]", f"{name!r} is not one of {', '.join(EXTRA_INPUTS)}")
        for i, n in enumerate(self.substeps):
            require(n >= 1, f"study.substeps[{i}]", f"must be >= 1, got {n}")
        for key in ("authors_force_data", "pushforward", "overrides"):
            v = getattr(self, key)
            require(v is None or isinstance(v, dict), f"study.{key}", f"must be a mapping, got {v!r}")
        if self.pushforward is not None:
            keys = {"substeps", "steps", "unrolls", "probs"}
            require(set(self.pushforward) == keys, "study.pushforward",
                    f"needs exactly the keys {sorted(keys)}, got {sorted(self.pushforward)}")
            pf = self.pushforward
            check_pushforward(pf["steps"], pf["unrolls"], pf["probs"], "study.pushforward.")
            for i, n in enumerate(self.pushforward["substeps"]):
                require(isinstance(n, int) and n >= 1, f"study.pushforward.substeps[{i}]", f"must be >= 1, got {n}")


@dataclass(frozen=True)
class Experiment:
    data: Data
    model: Model = field(default_factory=Model)
    train: Train = field(default_factory=Train)
    eval: Eval = field(default_factory=Eval)
    fig3: Fig3 = field(default_factory=Fig3)
    cost: Cost = field(default_factory=Cost)
    study: Study = field(default_factory=Study)
    models: tuple[str, ...] = MODELS

    def __post_init__(self):
        for i, m in enumerate(self.models):
            require(m in MODELS, f"models[{i}]", f"{m!r} is not one of {list(MODELS)}")
        loop = [m for m in self.models if m != "gns"]
        require(self.model.input_seq_length == 2 or not loop, "model.input_seq_length",
                f"{self.model.input_seq_length} positions, but {' and '.join(loop)} start(s) from one velocity: only 2 "
                "is supported there (a GNS with a longer history: models: [gns])")
        windows = self.data.frames[2] // (self.model.input_seq_length + self.eval.n_rollout_steps)
        require(windows >= 1, "data.frames[2]", f"the test split needs at least input_seq_length + "
                f"eval.n_rollout_steps = {self.model.input_seq_length + self.eval.n_rollout_steps} frames")
        valid = self.data.frames[1] // (self.model.input_seq_length + self.eval.n_rollout_steps) * self.data.seeds
        require(valid >= self.train.eval_n_trajs, "train.eval_n_trajs",
                f"{self.train.eval_n_trajs} exceeds the {valid} windows of the valid split (raise data.frames[1])")
        require(self.data.frames[2] >= self.model.input_seq_length + self.fig3.steps, "fig3.steps",
                f"{self.fig3.steps} coarse steps need input_seq_length + fig3.steps = "
                f"{self.model.input_seq_length + self.fig3.steps} test frames per seed, data.frames[2] is "
                f"{self.data.frames[2]}")
        w = self.data.write_every
        for i, m in enumerate(self.cost.coarsening):
            require(w % m == 0, f"cost.coarsening[{i}]",
                    f"M = {m} does not divide data.write_every = {w}: the solver at coarsening M takes "
                    f"write_every / M substeps of M dt per stored frame; possible M: "
                    f"{[k for k in range(1, w + 1) if w % k == 0]}")
        for i, n in enumerate(self.study.substeps):
            require(w % n == 0, f"study.substeps[{i}]", f"L = {n} does not divide data.write_every = {w}")
        for i, n in enumerate((self.study.pushforward or {}).get("substeps", ())):
            require(n == self.model.substeps or n in self.study.substeps, f"study.pushforward.substeps[{i}]",
                    f"L = {n} has no solver-alone run to compare with: use model.substeps "
                    f"({self.model.substeps}) or one of study.substeps {list(self.study.substeps)}")
        if self.study.authors_force_data:
            from_mapping(Data, merge(to_mapping(self.data), self.study.authors_force_data), "study.authors_force_data")


def load(profile: str, path=CONFIG, overrides: Optional[dict] = None) -> Experiment:
    return load_profile(Experiment, path, profile, overrides)


# -- paths and fingerprints -------------------------------------------------------------------------
def out_dir(results) -> Path:
    return Path(results) / "sitl"


def data_dir(results) -> Path:
    """LagrangeBench-style name: 2D_RPF_<N>_<frames>every<write_every> is set in metadata; the folder
    itself is fixed so that make rules can name it."""
    return out_dir(results) / "data" / "2D_RPF"


def ckpt_dir(results, model: str) -> Path:
    return out_dir(results) / "ckp" / model


def metrics_path(results, model: str) -> Path:
    return out_dir(results) / "metrics" / f"{model}.json"


def rollout_dir(results, model: str) -> Path:
    return out_dir(results) / "rollouts" / model


def cost_dir(results) -> Path:
    """sitl/cost.py's run records, one folder per point (gathered by experiments/accuracy/atlas.py)."""
    return out_dir(results) / "cost"


def data_config_digest(exp: Experiment) -> str:
    """The dataset's configuration alone (no code)."""
    return digest({"data": to_mapping(exp.data)})


def data_fingerprint(exp: Experiment) -> str:
    """Configuration + generator + the code that can change the data: generate.py, the dataset's
    settings (rpf_data.py, not this file: a study or training setting does not re-key the data) and
    the sph modules of the solver and of those two (`lab.keys.code_fingerprint`; sitl/rules.mk lists
    the same files as the dataset's prerequisites): a dataset is regenerated when this changes."""
    return digest({"data": to_mapping(exp.data),
                   "code": code_fingerprint([HERE / "generate.py", HERE / "rpf_data.py"])})


def train_fingerprint(exp: Experiment, model: str, metadata_text: str) -> str:
    """A training run is continued / reused while this matches: the dataset (its configuration and
    its metadata.json, i.e. its statistics), the model and training settings and the SitL code
    (model.py, train.py, common.py, each without docstrings and comments: `files_digest`). The
    core's source is deliberately not part of it, so that a core edit that leaves the data unchanged
    does not throw away hours of training."""
    code = files_digest([HERE / f for f in ("model.py", "train.py", "common.py")])
    train = to_mapping(exp.train)
    # only the model's own training noise (GNS: noise_std, SitL: sitl_noise_std)
    train.pop("sitl_noise_std" if model == "gns" else "noise_std")
    return digest({"data": data_config_digest(exp), "metadata": metadata_text, "model": to_mapping(exp.model),
                   "train": train, "name": model, "code": code})


def authors_force_experiment(exp: Experiment) -> Experiment:
    """The experiment of the study's authors'-force dataset: `data` overridden by
    study.authors_force_data (the paper's resolution and frame interval on cpu), no training."""
    extra = exp.study.authors_force_data or {}
    data = from_mapping(Data, merge(to_mapping(exp.data), extra), "study.authors_force_data")
    train = exp.train
    windows = data.frames[1] // (exp.model.input_seq_length + exp.eval.n_rollout_steps) * data.seeds
    if train.eval_n_trajs > windows:  # never trained: only its validation check must pass
        from dataclasses import replace
        train = replace(train, eval_n_trajs=max(1, windows))
    return Experiment(data=data, model=exp.model, train=train, eval=exp.eval, fig3=exp.fig3, cost=exp.cost,
                      study=exp.study, models=("solver",))
