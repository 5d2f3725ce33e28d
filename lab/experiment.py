"""One protocol for an experiment folder: the folder says what a run builds and measures, the harness
does the rest (loading, paths, cache keys, the sweep, the cached run, the record, the command line).

A folder <dir>/ (e.g. experiments/droplet) holds

  config.yaml     `profiles:`, each profile a mapping of the study's Settings (`inherit:` between them)
  study.py        Settings                  frozen dataclass of one profile, validated on construction
                  runs(settings) -> [run]   the runs the profile asks for; a run is a frozen dataclass
                                            with `name` (its folder), `t_end`, `frames` and every input
                                            that can change its numbers (with the code, its cache key;
                                            a field declared `field(metadata={"key": False})`, read
                                            only by `metrics`, e.g. evaluation times, stays out of it)
                  scene(run) -> (Scene, Numerics)    what a run builds (a recipe of sph.cases)
                  metrics(run, traj) -> dict         what it measures (traj: lab.io.read_trajectory of
                                            the run, its metadata.json as traj["metadata"]); keys
                                            err_<name> are its errors
  plot_<name>.py  a figure of the table and trajectories (`plot_main`): <results>/<dir name>/<name>.png,
                  or the folder its rules.mk names (the Makefile's protocol rules: FIGDIR, EXTRA, GIF)
  analysis.py     (optional) what a run measures when it is more than study.py should hold: `metrics`,
                  `record`, TABLE, TARGET and `read_trajectory(path) -> dict` (what metrics read of a
                  trajectory, default lab.io.read_trajectory: every dataset, e.g. only the per-frame
                  series of a large 3D run) are then this module's, reading what they need from the
                  run (a field declared out of the key can carry the settings). Its code stays out of
                  the runs' keys: editing it re-evaluates the runs, never re-runs them

and optionally, in study.py, where a folder needs more:

  KEEP, METHOD    per-frame fields kept besides position (default velocity, pressure); the record's
                  method (default the run's `method` attribute, else its name)
  TARGET          the record's target (default the folder's name), e.g. the paper figure
  TABLE           a `lab.protocol.Table`: the rows of metrics.csv (default each run's record), their
                  order, and one table per kind of run where a folder's runs are of several kinds
  start(run) -> Start      (lab.protocol) a cached initial state shared by runs (a relaxed lattice):
                  <results>/<dir name>/relaxed_<tag>.npy; `scene(run, positions)` then receives it
  run_options(run) -> dict  RunSpec entries besides folder and key (case, method (of the
                  metadata, default the record's), keep, frame_dt, connectivity_radius_factor, u_limit, metadata)
  initial_state(run, solver) -> (state, nbrs)   a fresh run's start (default solver.init_fn())
  record(run, metrics) -> dict  the record's `errors` mapping, its `target` (default TARGET) and
                  extra columns (default: the err_<name> metrics as errors, the run's name and the
                  other metrics as columns)
  preflight(runs)          refusals made before any of `runs` (those about to run) is built (memory)
  FAILURES        "record": a run that raises (the driver's blow-up stop, a scene that cannot be built)
                  is an outcome, not an error (experiments/stability): the exception goes to the run's
                  failure.json under the run's key, the run counts as done (re-run only when its key
                  changes) and `metrics(run, traj)` receives traj["failure"] (error, kinds, message,
                  traceback) with whatever the run wrote (its frames up to the last good one and their
                  checkpoint; traj["metadata"] None when it failed before writing any)
  parts(exp) -> Experiments    the folder runs other folders' studies (experiments/accuracy: tgv2d per
                  kernel and dtype, each under a results root of its own): `run_all` runs theirs (their
                  runs, records and tables), one after the other, in place of its own runs
  compute(run, folder, progress) -> dict   the run's work when it is not a simulation with a trajectory
                  (gradcheck: a gradient check; inverse: an optimisation): it replaces `scene` and the
                  simulation, may write files (arrays) into `folder` (the run's folder, <results>/<dir
                  name>/<run name>) and returns the run's result, a JSON mapping, cached in folder/result.json
                  under the run's key (its keyed fields and the code of study.py with the sph modules it
                  imports; a run needs no `t_end` or `frames`): a run whose result.json holds its current
                  key is skipped, any other is computed again. `metrics(run, traj)` then receives traj =
                  {"result": that mapping, "folder": the run's folder, "key": its key}; such a run writes
                  no record.json (it has no metadata.json): its row of the table is its metrics
  COMPUTE         "always": the study's `compute` keeps caches of its own (experiments/sitl: a training's
                  checkpoints and key, an evaluation's key, in the library sitl/) and is called on every
                  run step, whatever result.json holds: it answers "up to date" itself, and its result
                  is written again (the same bytes when nothing changed, so the stamp stays)

A run may name the `groups` it belongs to (e.g. the figures that show it): `--group G` runs only those
and writes only the tables they go to, and the Makefile's protocol rules give each group of a folder's
rules.mk (GROUPS.<dir>) a stamp of its own.

    python -m lab.experiment <dir> --profile smoke [--results R] [--only RUN ...] [--group G] [--method M ...]
                             [--no-progress] [--log-every N]

runs each run of the profile through `runs.run_cached` (skip when current, resume, set a stale or
damaged file aside), writes each run's record.json (`record`, what `make accuracy` gathers) and the
table metrics.csv of exactly the profile's finished runs. The key of a run is its dataclass (its keyed
fields), its start's key and the code of study.py with every sph module it imports (the recipe
included, `keys.code_fingerprint`). A copied folder is an experiment of its own: its name is its folder's.
"""
import importlib.util
import re
import traceback
from dataclasses import fields
from pathlib import Path
from typing import Callable, Optional

from sph.precision import resolve
from sph.solver import build_solver
from .cli import profile_main
from .configtools import harness_options, load_profile, require, to_mapping
from .io import MissingOutput, read_metadata, read_trajectory, write_metadata
from .keys import code_fingerprint, digest
from .lock import folder_lock
from .protocol import Start, Table
from .record import record, save_record
from .runs import RunOutcome, RunSpec, cached_positions, run_cached, stored_state
from .stamp import note_current
from .tables import read_table, write_table

DEFAULT_KEEP = ("velocity", "pressure")
RUN_NAME = re.compile(r"[A-Za-z_](?:[A-Za-z0-9_-]|\.(?!\.))*")
"""A run's name, its folder: a name (configtools.NAME) that may hold single dots (tvf_dx0.02)."""
FAILURE = "failure.json"
"""A failed run's record (a study with FAILURES = "record"), in its folder."""
RESULT = "result.json"
"""A computed run's result under its key (a study with `compute`), in its folder."""
RUN_OPTIONS = ("case", "method", "keep", "frame_dt", "connectivity_radius_factor", "u_limit", "metadata")
"""What a study's `run_options(run)` may set of a run's RunSpec (lab.runs)."""


def require_file_name(value, key: str) -> str:
    """`value` if it is a run's file or folder name (RUN_NAME), else a ConfigError naming `key`."""
    require(isinstance(value, str) and bool(RUN_NAME.fullmatch(value)), key,
            f"{value!r} is not a folder name: letters, digits, _, - and single dots, starting with a letter or _")
    return value


def load_study(folder, module: str = "study"):
    """The study module of `folder` (its study.py; `module`: another of its modules), imported under a
    name of its own."""
    folder = Path(folder).resolve()
    spec = importlib.util.spec_from_file_location(f"experiment_{folder.name.replace('-', '_')}_{module}",
                                                  folder / f"{module}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def load_settings(folder, profile: str, overrides: Optional[dict] = None):
    """The study's Settings of profile `profile` of `folder`'s config.yaml (`overrides` merged last):
    errors name the file, the profile and the key."""
    folder = Path(folder)
    return load_profile(load_study(folder).Settings, folder / "config.yaml", profile, overrides)


def run_key(run) -> dict:
    """The inputs of `run` that enter its cache key: its fields but those declared
    `field(metadata={"key": False})` (what only its metrics read)."""
    m = to_mapping(run)
    return {f.name: m[f.name] for f in fields(run) if f.metadata.get("key", True)}


class Experiment:
    """An experiment folder at one profile: its study, settings, runs and paths (`overrides`, a mapping,
    is merged over the profile last)."""

    def __init__(self, folder, profile: str, results, overrides: Optional[dict] = None, devices: Optional[int] = None):
        self.folder = Path(folder).resolve()
        self.name = self.folder.name
        self.profile, self.results = profile, Path(results)
        self.study = load_study(self.folder)
        self.analysis = load_study(self.folder, "analysis") if (self.folder / "analysis.py").exists() else self.study
        self.settings = load_profile(self.study.Settings, self.folder / "config.yaml", profile, overrides)
        self.devices = devices or harness_options(self.folder / "config.yaml", profile, overrides)["devices"]
        """How many devices each run's steps use: `devices` (the command line's --devices), else the
        profile's `devices:` (default 1); not part of a run's key (lab.runs.RunSpec.devices)."""
        self.runs = tuple(self.study.runs(self.settings))
        names = [require_file_name(r.name, "run name") for r in self.runs]
        for i, n in enumerate(names):
            require(names.index(n) == i, "runs", f"two runs are named {n!r}: a value is listed twice")
        self.keep = tuple(getattr(self.study, "KEEP", DEFAULT_KEEP))
        self.target = getattr(self.analysis, "TARGET", self.name)
        self.table_spec = getattr(self.analysis, "TABLE", Table())
        compute = getattr(self.study, "COMPUTE", None)
        require(compute in (None, "always"), "COMPUTE", f"must be 'always' (or absent), got {compute!r}")
        require(compute is None or hasattr(self.study, "compute"), "COMPUTE", "is set but study.py defines no compute")

    @property
    def out_dir(self) -> Path:
        return self.results / self.name

    @property
    def metrics_path(self) -> Path:
        return self.out_dir / "metrics.csv"

    def table_path(self, run) -> Path:
        """The table `run`'s row goes to (TABLE.file; metrics.csv by default)."""
        name = self.table_spec.file(run) if self.table_spec.file else "metrics.csv"
        return self.out_dir / require_file_name(name, f"TABLE.file({run.name})")

    def run(self, name: str):
        """The run named `name`, refused (listing the profile's runs) when there is none."""
        names = [r.name for r in self.runs]
        require(name in names, "run", f"{name!r} is not one of the runs of profile {self.profile}: {names}")
        return self.runs[names.index(name)]

    # -- keys and paths ---------------------------------------------------------------------------------
    def _code(self, modules=()) -> str:
        return code_fingerprint([self.folder / "study.py"], tuple(modules))

    def start(self, run) -> Optional[Start]:
        return self.study.start(run) if hasattr(self.study, "start") else None

    def start_key(self, start: Start) -> str:
        return digest({"tag": start.tag, "inputs": start.inputs, "code": self._code(start.modules)})

    def start_path(self, start: Start) -> Path:
        return self.out_dir / f"relaxed_{require_file_name(start.tag, 'start tag')}.npy"

    def spec(self, run) -> RunSpec:
        opts = dict(self.study.run_options(run)) if hasattr(self.study, "run_options") else {}
        for k in opts:
            require(k in RUN_OPTIONS, f"run_options({run.name}).{k}", f"is not one of {list(RUN_OPTIONS)}")
        st = self.start(run)
        key = digest({"run": run_key(run), "start": self.start_key(st) if st else None, "code": self._code()})
        metadata = {"run": to_mapping(run), **opts.pop("metadata", {})}
        frames = {} if "frame_dt" in opts else {"frames": run.frames}
        return RunSpec(**{"case": self.name, "method": self.method(run), "keep": self.keep, **opts, **frames},
                       folder=self.out_dir / run.name, fingerprint=key, t_end=run.t_end, metadata=metadata,
                       devices=self.devices)

    def method(self, run) -> str:
        return getattr(self.study, "METHOD", None) or getattr(run, "method", None) or run.name

    # -- running ------------------------------------------------------------------------------------------
    def positions(self, start: Start, progress: bool = True):
        """The start's positions, cached (computed when missing or made from other inputs)."""
        return cached_positions(self.start_path(start), self.start_key(start), lambda: start.compute(progress),
                                f"relaxed {start.tag}", **start.meta)

    def solver(self, run, progress: bool = True):
        st = self.start(run)
        args = (run,) if st is None else (run, self.positions(st, progress))
        return build_solver(*self.study.scene(*args))

    def run_one(self, run, progress: bool = True, callback=None):
        """Run (or skip, or resume) `run`; its lab.runs.RunOutcome."""
        if self.computes:
            return self._compute(run, progress)
        start = getattr(self.study, "initial_state", None)

        def go():
            return run_cached(self.spec(run), lambda: self.solver(run, progress), progress=progress, callback=callback,
                              initial_state=None if start is None else lambda solver: start(run, solver))
        return self._recording_failure(run, go) if self.records_failures else go()

    # -- runs that compute instead of simulating (a study's `compute`) ------------------------------------
    @property
    def computes(self) -> bool:
        return hasattr(self.study, "compute")

    @property
    def computes_always(self) -> bool:
        """The study's compute decides itself what is current (COMPUTE = "always")."""
        return getattr(self.study, "COMPUTE", None) == "always"

    def compute_key(self, run) -> str:
        """The key of a computed run: its keyed fields and the code of study.py with the sph modules it imports."""
        return digest({"run": run_key(run), "code": self._code()})

    def result(self, run) -> Optional[dict]:
        """The result of a computed run (its result.json) when made from its current key, else None."""
        stored = read_metadata(self.out_dir / run.name / RESULT)
        if stored is None or stored.get("key") != self.compute_key(run) or not isinstance(stored.get("result"), dict):
            return None
        return stored["result"]

    def _compute(self, run, progress: bool = True) -> RunOutcome:
        """`compute(run, folder, progress)` of the study, skipped when its result is current; the result is
        written (last, after whatever files the study wrote) to the run's result.json under its key."""
        folder = self.out_dir / run.name
        label = f"{self.name}/{run.name}"
        with folder_lock(folder):  # one writer at a time (make -j2)
            if not self.computes_always and self.result(run) is not None:
                note_current(folder)
                print(f"{label}: current (same inputs), skipped", flush=True)
                return RunOutcome("skipped", folder)
            (folder / RESULT).unlink(missing_ok=True)
            key = self.compute_key(run)
            result = self.study.compute(run, folder, progress)
            write_metadata(folder / RESULT, {"key": key, "result": result})
            note_current(folder)
        return RunOutcome("run", folder)

    # -- failed runs as outcomes (FAILURES = "record") ----------------------------------------------------
    @property
    def records_failures(self) -> bool:
        return getattr(self.study, "FAILURES", None) == "record"

    def failure(self, run) -> Optional[dict]:
        """The failure.json of `run` when the study records failures and it was made from the run's
        current inputs (its key), else None."""
        if not self.records_failures:
            return None
        spec = self.spec(run)
        rec = read_metadata(Path(spec.folder) / FAILURE)
        return rec if rec is not None and rec.get("fingerprint") == spec.fingerprint else None

    def state(self, run) -> str:
        """lab.runs.stored_state of the run's trajectory, or "current" for a failure recorded under its key;
        of a computed run: "current" when its result is, else "stale" (made from other inputs) or "missing"."""
        if self.computes:
            return "current" if self.result(run) is not None else \
                "stale" if (self.out_dir / run.name / RESULT).exists() else "missing"
        return "current" if self.failure(run) is not None else stored_state(self.spec(run))

    def _recording_failure(self, run, go):
        """`go()` (the cached run), its exception written to failure.json instead of raised; a run whose
        failure is recorded under its current key is skipped."""
        spec = self.spec(run)
        path = Path(spec.folder) / FAILURE
        if self.failure(run) is not None:
            note_current(spec.folder)
            print(f"{spec.label}: failed before with the same inputs ({path.name}), skipped", flush=True)
            return RunOutcome("skipped", Path(spec.folder))
        path.unlink(missing_ok=True)
        try:
            return go()
        except Exception as e:  # noqa: BLE001 (the study asked for every failure as an outcome)
            write_metadata(path, {"fingerprint": spec.fingerprint, "error": type(e).__name__,
                                  "kinds": [c.__name__ for c in type(e).__mro__], "message": str(e),
                                  "traceback": traceback.format_exc()})
            note_current(spec.folder)
            print(f"{spec.label}: failed, recorded in {path}: {type(e).__name__}: {' '.join(str(e).split())[:300]}",
                  flush=True)
            return RunOutcome("failed", Path(spec.folder))

    def run_all(self, only=None, progress: bool = True, callback=None):
        """Run (or skip, or resume) the runs (`only`: these names), then rebuild every record and the table."""
        if hasattr(self.study, "parts"):
            self.part_tables = []
            for part in self.study.parts(self):
                part.run_all(None, progress, callback)
                self.part_tables += sorted({part.table_path(r) for r in part.runs})
            return None
        chosen = [r for r in self.runs if only is None or r.name in only]
        if hasattr(self.study, "preflight"):
            self.study.preflight(chosen)
        for run in chosen:
            self.run_one(run, progress, callback)
        return self.write_table(None if only is None else [r.name for r in chosen])

    # -- what a run measures ------------------------------------------------------------------------
    def current(self, run) -> RunSpec:
        """The spec of `run`, refused (naming the run and how to make it) unless its output is current (a
        computed run: its result.json, refused likewise)."""
        if self.computes:
            if self.result(run) is None:
                raise MissingOutput(f"{self.out_dir / run.name / RESULT}: run {run.name} of profile {self.profile} is "
                                    f"{self.state(run)}, not made from the current config and code; run "
                                    f"`make {self.name} PROFILE={self.profile}`")
            return None
        spec = self.spec(run)
        state = self.state(run)
        if state != "current":
            raise MissingOutput(f"{spec.traj}: run {run.name} of profile {self.profile} is {state}, not made from "
                                f"the current config and code; run `make {self.name} PROFILE={self.profile}`")
        return spec

    def trajectory(self, run) -> dict:
        """The trajectory of `run` with its metadata.json as ["metadata"], refused unless it is current; JAX
        then computes in the run's precision (x64 on for a float64 run: a metric evaluated with JAX gives
        the same numbers in the process that made the run as in a plot script's). A computed run's: its
        result, folder and key (`compute`)."""
        if self.computes:
            self.current(run)
            return {"result": self.result(run), "folder": self.out_dir / run.name, "key": self.compute_key(run)}
        spec = self.current(run)
        failure = self.failure(run)
        read = getattr(self.analysis, "read_trajectory", read_trajectory)
        traj = read(spec.traj) if failure is None or stored_state(spec) == "partial" else {}
        traj["metadata"] = read_metadata(spec.meta_path)
        if failure is not None:  # what the failed run wrote (its frames, its metadata), if anything
            traj["failure"] = failure
            if traj["metadata"] is None or traj["metadata"].get("fingerprint") != spec.fingerprint:
                traj["metadata"] = None
                return traj
        resolve(traj["metadata"]["dtype"])  # measured in the run's precision, whatever ran before in this process
        return traj

    def metrics(self, run) -> dict:
        return self.analysis.metrics(run, self.trajectory(run))

    def record(self, run, metrics: Optional[dict] = None) -> dict:
        """The run's record (RECORD_COLUMNS, err_<name>, the other columns), written as record.json."""
        m = self.metrics(run) if metrics is None else metrics
        if self.failure(run) is not None:
            spec = self.spec(run)
            if (read_metadata(spec.meta_path) or {}).get("fingerprint") != spec.fingerprint:
                return {}  # failed before its metadata was written: nothing to record
        if hasattr(self.analysis, "record"):
            parts = dict(self.analysis.record(run, m))
        else:
            parts = {"errors": {k[4:]: v for k, v in m.items() if k.startswith("err_")}, "run": run.name,
                     **{k: v for k, v in m.items() if not k.startswith("err_")}}
        target = parts.pop("target", self.target)
        rec = record(self.out_dir / run.name, experiment=self.name, target=target, method=self.method(run), **parts)
        save_record(self.out_dir / run.name, rec)
        return rec

    def write_table(self, only=None):
        """Rebuild every current run's record and the metrics table(s) from exactly those runs (`TABLE`);
        the table of metrics.csv's runs, or of the first table's when the runs go to several. `only`
        (run names, e.g. a group's): only the tables those runs go to, so that a group's step writes (and
        its stamp lists) the tables of its own runs, not another group's."""
        wanted = None if only is None else {self.table_path(r) for r in self.runs if r.name in only}
        rows = {}
        for run in self.runs:
            if wanted is not None and self.table_path(run) not in wanted:
                continue
            rows.setdefault(self.table_path(run), [])
            if self.state(run) == "current":
                m = self.metrics(run)
                if self.computes:  # no metadata.json, no record: the row is its metrics
                    rows[self.table_path(run)].append(m)
                    continue
                rec = self.record(run, m)
                rows[self.table_path(run)].append(rec if self.table_spec.rows == "records" else m)
        t = self.table_spec
        tables = {path: write_table(path, r, sort=list(t.sort) or None, ascending=list(t.ascending) if t.ascending else True)
                  for path, r in rows.items()}
        return tables.get(self.metrics_path, next(iter(tables.values()), None))

    def table(self, runs=None):
        """The table of `runs` (default: every run; they go to one table), refused unless it lists
        exactly those runs, each current."""
        runs = self.runs if runs is None else list(runs)
        paths = sorted({self.table_path(r) for r in runs})
        require(len(paths) == 1, "runs", f"go to {len(paths)} tables ({[p.name for p in paths]}): ask for one")
        missing = [r.name for r in runs if self.state(r) != "current"]
        if missing:
            raise MissingOutput(f"{self.name} ({self.profile}): runs {', '.join(missing)} are missing or were made from "
                                f"other inputs; run `make {self.name} PROFILE={self.profile}`")
        df = read_table(paths[0])
        listed = sorted(df["run"]) if "run" in df else len(df)
        if listed != (sorted(r.name for r in runs) if "run" in df else len(runs)):
            raise MissingOutput(f"{paths[0]}: lists {listed} runs, not the profile's; run "
                                f"`make {self.name} PROFILE={self.profile}`")
        return df


def plot_main(plot, script: str, doc=None, argv=None, gif: Optional[Callable] = None):
    """A plot script's command line: `plot(experiment, out_dir) -> png path` for the folder of
    `script` (its __file__), `--profile`, `--results`, `--out` (default <results>/<folder name>); with
    `gif(experiment) -> run` (or (run, options of lab.animate.render)), `--gif PATH` writes only an
    animation of that run's trajectory."""
    from .cli import profile_main

    def options(ap):
        ap.add_argument("--out", default=None, help="figure folder (default <results>/<experiment>)")
        if gif is not None:
            ap.add_argument("--gif", default=None, help="write only an animation of the figure's run to this file")

    def main(args):
        exp = Experiment(Path(script).parent, args.profile, args.results)
        if getattr(args, "gif", None):
            from . import animate

            run, kw = (lambda r: r if isinstance(r, tuple) else (r, {}))(gif(exp))
            animate.render(exp.current(run).traj, args.gif, **kw)
            return
        out = Path(args.out) if args.out else exp.out_dir
        out.mkdir(parents=True, exist_ok=True)
        print(f"{Path(script).stem} -> {plot(exp, out)}")

    return profile_main(main, doc, options, argv)


def progress_lines(every: int) -> Callable:
    """A run callback printing one line every `every` frames (for logs of runs without a progress bar)."""
    import time

    from sph import diagnostics

    t0, count = time.perf_counter(), [0]

    def log(step, t, state):
        count[0] += 1
        if count[0] % every == 0:
            print(f"step {step} t={t:.3f} u_max={float(diagnostics.u_max(state)):.4f} "
                  f"[{time.perf_counter() - t0:.0f} s this session, {time.strftime('%H:%M:%S')}]", flush=True)
    return log


def main(argv=None):
    def options(ap):
        ap.add_argument("folder", help="the experiment folder (config.yaml, study.py)")
        ap.add_argument("--only", nargs="*", default=None, help="run names to run (default: all)")
        ap.add_argument("--group", default=None, help="only the runs of this group (a run's `groups`)")
        ap.add_argument("--method", nargs="*", default=None, help="only the runs of these methods (a run's `method`)")
        ap.add_argument("--no-progress", action="store_true")
        ap.add_argument("--log-every", type=int, default=None, help="print a progress line every N frames")
        ap.add_argument("--devices", type=int, default=None,
                        help="devices per run (sph.parallel; default: the profile's devices:, else 1; a CPU-only "
                             "host is split into that many XLA devices)")

    def work(args):
        if args.devices is not None:
            require(args.devices >= 1, "--devices", f"must be >= 1, got {args.devices}")
        exp = Experiment(args.folder, args.profile, args.results, devices=args.devices)
        if exp.devices > 1:
            from sph.parallel.devices import use_devices

            use_devices(exp.devices)
        names = [r.name for r in exp.runs]
        if args.only is not None:
            bad = [n for n in args.only if n not in names]
            require(not bad, "--only", f"{bad[:1]} is not one of the profile's runs {names}")
        only = args.only
        if args.group is not None:
            groups = sorted({g for r in exp.runs for g in getattr(r, "groups", ())})
            require(args.group in groups, "--group", f"{args.group!r} is not a group of the profile's runs {groups}")
            only = [r.name for r in exp.runs if args.group in r.groups and (only is None or r.name in only)]
        if args.method is not None:
            methods = sorted({exp.method(r) for r in exp.runs})
            bad = [m for m in args.method if m not in methods]
            require(not bad, "--method", f"{bad[:1]} is not one of the profile's methods {methods}")
            only = [r.name for r in exp.runs if exp.method(r) in args.method and (only is None or r.name in only)]
        callback = None
        if args.log_every:
            require(args.log_every >= 1, "--log-every", f"must be >= 1, got {args.log_every}")
            callback = progress_lines(args.log_every)
        exp.run_all(only, not args.no_progress, callback)
        tables = [str(t) for t in getattr(exp, "part_tables", None) or sorted({exp.table_path(r) for r in exp.runs})]
        print(f"{exp.name}: {len(exp.runs) if only is None else len(only)} runs -> {', '.join(tables)}")

    return profile_main(work, __doc__, options, argv)


if __name__ == "__main__":
    main()
