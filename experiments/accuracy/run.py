"""The TGV sweep of the accuracy-cost atlas: every method x dx x dtype x kernel of the profile, each
(kernel, dtype) as experiments/tgv2d run by the harness (lab.experiment: its study.py, its config's
base profile with this sweep's overrides) with its own runs (cached, resumable: lab.runs), into
results/<profile>/accuracy/tgv/<kernel>_<dtype>/tgv2d/. Runs that exist are reused;
the other problems of the atlas (cavity, dam break, heat) are not run here: atlas.py reads the run
records their own experiments wrote.

    python experiments/accuracy/run.py --profile smoke [--results results/smoke]
"""
import time

from lab.configtools import ConfigError, load_profile, to_mapping
from lab.experiment import Experiment, load_study

try:
    from . import settings as S
except ImportError:  # run as a script: its folder comes first on the import path
    import settings as S


def tgv_experiment(atlas: "S.Atlas", kernel: str, dtype: str, results=".") -> Experiment:
    """The 2D Taylor-Green experiment of one (kernel entry, dtype) of the sweep, its results under
    S.tgv_results(results, ...), validated as tgv2d's own config (a kernel entry "name@<factor>" also
    sets numerics.h_factor)."""
    sw = atlas.tgv
    base = load_profile(load_study(S.TGV_FOLDER).Settings, S.TGV_FOLDER / "config.yaml", sw.base_profile)
    names = [m.name for m in base.methods]
    for i, m in enumerate(sw.methods):
        if m not in names:
            raise ConfigError(f"tgv.methods[{i}]: {m!r} is not a method of tgv2d's {sw.base_profile!r} "
                              f"profile ({names})")
    methods = [{"name": m.name, "effects": to_mapping(m.effects)} for m in base.methods
               if m.name in sw.methods]
    name, h_factor = S.kernel_spec(kernel)
    numerics = {"kernel": name, "dtype": dtype}
    if h_factor is not None:
        numerics["h_factor"] = h_factor
    return Experiment(S.TGV_FOLDER, sw.base_profile, S.tgv_results(results, kernel, dtype), overrides={
        "numerics": numerics, "methods": methods, "dx": list(sw.dx),
        "t_end": sw.t_end, "frames": sw.frames, "eval_times": [sw.t_end / 2, sw.t_end]})


def run_sweep(atlas: "S.Atlas", results, progress: bool = True) -> int:
    t0 = time.perf_counter()
    n = 0
    for kernel in atlas.tgv.kernels:
        for dtype in atlas.tgv.dtypes:
            exp = tgv_experiment(atlas, kernel, dtype, results)
            print(f"accuracy: TGV sweep, kernel {kernel}, {dtype}", flush=True)
            n += len(exp.run_all(progress=progress))
    print(f"accuracy: {n} TGV runs in {time.perf_counter() - t0:.1f} s", flush=True)
    return n


def options(ap):
    ap.add_argument("--no-progress", action="store_true")


def main(args):
    run_sweep(S.load(args.profile), args.results, not args.no_progress)


if __name__ == "__main__":
    from lab.cli import profile_main

    profile_main(main, __doc__, options)
