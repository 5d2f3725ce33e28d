"""One protocol for an experiment folder: the folder says what a run builds and measures, the harness
does the rest (loading, paths, cache keys, the sweep, the cached run, the record, the command line).

A folder <dir>/ (e.g. experiments/droplet) holds

  config.yaml     `profiles:`, each profile a mapping of the study's Settings (`inherit:` between them)
  study.py        Settings                  frozen dataclass of one profile, validated on construction
                  runs(settings) -> [run]   the runs the profile asks for; a run is a frozen dataclass
                                            with `name` (its folder), `t_end`, `frames` and every input
                                            that can change its numbers (with the code, its cache key)
                  scene(run) -> (Scene, Numerics)    what a run builds (a recipe of sph.cases)
                  metrics(run, traj) -> dict         what it measures; keys err_<name> are its errors
                  KEEP, METHOD (optional)   per-frame fields kept besides position (default velocity,
                                            pressure); the record's method (default the run's `method`
                                            attribute, else its name)
  plot_<name>.py  a figure of the table and trajectories (`plot_main`): <results>/<dir name>/<name>.png

    python -m lab.experiment <dir> --profile smoke [--results R] [--only RUN ...]

runs each run of the profile through `runs.run_cached` (skip when current, resume, set a stale or
damaged file aside), writes each run's record.json (`record`, what `make accuracy` gathers) and the
table metrics.csv of exactly the profile's finished runs. The key of a run is its dataclass and the
code of study.py with every sph module it imports (the recipe included, `keys.code_fingerprint`). A
copied folder is an experiment of its own: its name is its folder's.
"""
import importlib.util
from pathlib import Path

from sph.solver import build_solver
from .configtools import load_profile, require, require_name, to_mapping
from .io import MissingOutput, read_trajectory
from .keys import code_fingerprint, digest
from .record import record, save_record
from .runs import RunSpec, run_cached, stored_state
from .tables import read_table, write_table

DEFAULT_KEEP = ("velocity", "pressure")


def load_study(folder):
    """The study module of `folder` (its study.py), imported under a name of its own."""
    folder = Path(folder).resolve()
    spec = importlib.util.spec_from_file_location(f"experiment_{folder.name.replace('-', '_')}_study",
                                                  folder / "study.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


class Experiment:
    """An experiment folder at one profile: its study, settings, runs and paths."""

    def __init__(self, folder, profile: str, results, overrides=None):
        self.folder = Path(folder).resolve()
        self.name = self.folder.name
        self.profile, self.results = profile, Path(results)
        self.study = load_study(self.folder)
        self.settings = load_profile(self.study.Settings, self.folder / "config.yaml", profile, overrides)
        self.runs = tuple(self.study.runs(self.settings))
        names = [require_name(r.name, "run name") for r in self.runs]
        for i, n in enumerate(names):
            require(names.index(n) == i, "runs", f"two runs are named {n!r}: a value is listed twice")
        self.keep = tuple(getattr(self.study, "KEEP", DEFAULT_KEEP))

    @property
    def out_dir(self) -> Path:
        return self.results / self.name

    @property
    def metrics_path(self) -> Path:
        return self.out_dir / "metrics.csv"

    def run(self, name: str):
        return next(r for r in self.runs if r.name == name)

    def spec(self, run) -> RunSpec:
        key = digest({"run": to_mapping(run), "code": code_fingerprint([self.folder / "study.py"])})
        return RunSpec(folder=self.out_dir / run.name, case=self.name, method=self.method(run), fingerprint=key,
                       t_end=run.t_end, frames=run.frames, keep=self.keep, metadata={"run": to_mapping(run)})

    def method(self, run) -> str:
        return getattr(self.study, "METHOD", None) or getattr(run, "method", None) or run.name

    def trajectory(self, run) -> dict:
        """The trajectory of `run`, refused (naming the run and how to make it) unless it is current."""
        spec = self.spec(run)
        state = stored_state(spec)
        if state != "current":
            raise MissingOutput(f"{spec.traj}: run {run.name} of profile {self.profile} is {state}, not made from "
                                f"the current config and code; run `make {self.name} PROFILE={self.profile}`")
        return read_trajectory(spec.traj)

    def run_all(self, only=None, progress: bool = True):
        """Run (or skip, or resume) the runs (`only`: these names), then rebuild every record and the table."""
        for run in self.runs:
            if only is None or run.name in only:
                run_cached(self.spec(run), lambda run=run: build_solver(*self.study.scene(run)), progress=progress)
        rows = [self.record(run) for run in self.runs if stored_state(self.spec(run)) == "current"]
        return write_table(self.metrics_path, rows)

    def record(self, run) -> dict:
        """The run's record (RECORD_COLUMNS, err_<name>, the other metrics), written as record.json."""
        m = self.study.metrics(run, self.trajectory(run))
        errors = {k[4:]: v for k, v in m.items() if k.startswith("err_")}
        rec = record(self.out_dir / run.name, experiment=self.name, target=self.name, method=self.method(run),
                     errors=errors, run=run.name, **{k: v for k, v in m.items() if not k.startswith("err_")})
        save_record(self.out_dir / run.name, rec)
        return rec

    def table(self):
        """metrics.csv, refused unless it lists exactly the profile's runs, each current."""
        missing = [r.name for r in self.runs if stored_state(self.spec(r)) != "current"]
        if missing:
            raise MissingOutput(f"{self.name} ({self.profile}): runs {', '.join(missing)} are missing or were made from "
                                f"other inputs; run `make {self.name} PROFILE={self.profile}`")
        df = read_table(self.metrics_path)
        if sorted(df["run"]) != sorted(r.name for r in self.runs):
            raise MissingOutput(f"{self.metrics_path}: lists {sorted(df['run'])}, not the profile's runs; run "
                                f"`make {self.name} PROFILE={self.profile}`")
        return df


def plot_main(plot, script: str, doc=None, argv=None):
    """A plot script's command line: `plot(experiment, out_dir) -> png path` for the folder of
    `script` (its __file__), `--profile`, `--results`, `--out` (default <results>/<folder name>)."""
    from .cli import profile_main

    def options(ap):
        ap.add_argument("--out", default=None, help="figure folder (default <results>/<experiment>)")

    def main(args):
        exp = Experiment(Path(script).parent, args.profile, args.results)
        out = Path(args.out) if args.out else exp.out_dir
        out.mkdir(parents=True, exist_ok=True)
        print(f"{Path(script).stem} -> {plot(exp, out)}")

    return profile_main(main, doc, options, argv)


def main(argv=None):
    from .cli import profile_main

    def options(ap):
        ap.add_argument("folder", help="the experiment folder (config.yaml, study.py)")
        ap.add_argument("--only", nargs="*", default=None, help="run names to run (default: all)")
        ap.add_argument("--no-progress", action="store_true")

    def work(args):
        exp = Experiment(args.folder, args.profile, args.results)
        if args.only is not None:
            bad = [n for n in args.only if n not in [r.name for r in exp.runs]]
            require(not bad, "--only", f"{bad[:1]} is not one of the profile's runs {[r.name for r in exp.runs]}")
        df = exp.run_all(args.only, not args.no_progress)
        print(f"{exp.name}: {len(df)} runs -> {exp.metrics_path}")

    return profile_main(work, __doc__, options, argv)


if __name__ == "__main__":
    main()
