"""The command line of every script: its `--profile` / `--results` tail, and errors as one line.

    from lab.cli import profile_main

    def main(args):                 # args.profile, args.results (default results/<profile>), own options
        ...

    if __name__ == "__main__":
        profile_main(main, __doc__, options=lambda ap: ap.add_argument("--only", nargs="*"))

A script whose whole work is one function of the profile's settings and the results folder ends in
`experiment_main(work, S.load, __doc__)` instead, a plot script with an `--out` folder in
`figure_main(plot, S.load, __doc__, "fig5")`.

`profile_main(main, doc, options)` parses `--profile` (default paper), `--results` (default
results/<profile>) and the script's own options (`options(parser)` adds them), then calls
`main(args)` through `main_guard`. `main_guard(fn, *args)` sets XLA's CPU defaults
(`sph.xla_cpu`, before the script's first JAX computation), calls `fn(*args)` and returns
its result. If it raises

    ConfigError               (a bad key or value, a degenerate scene, InsufficientMemory)
                              prints "error: <file>: profiles.<profile>.<key>: <what>" and exits 2;
                              the profile named is the one the key is written in, e.g. `paper`
                              when `smoke` inherits the bad key from it (`configtools.load_profile`)
    SimulationError           (BlowUp, ParticleEscaped, NeighborOverflow: step, particle, position,
                              likely cause, where the last good frame is kept) prints
                              "error: <message>" and exits 3
    io.OutputError            (a result file missing or damaged: a trajectory, a metrics table)
                              prints "error (damaged file): <file>: <what>; <what to do>", exits 4
    KeyboardInterrupt         (Ctrl-C) prints "interrupted: <script> stopped; ... resume with the
                              same command" and exits 130

on stderr, without a traceback (set SPH_TRACEBACK=1 to see it). Everything else propagates. A bad
command line (an unknown option, an option such as `--only` given without a value) is one line too,
"error (usage): ...", exit 2.
`format_error(e)` is the line it prints. `select(option, given, allowed)` checks a command-line
subset (`--only`, `--dx`) against the profile's own values; `run_options(grid, kind, values)` are
the options of a study's run.py that choose such subsets.
"""
import argparse
import os
import sys
from typing import Callable, Optional

import numpy as np

from sph.errors import SimulationError
from sph.errors import ConfigError
from .io import OutputError
from sph.xla_cpu import set_cpu_defaults
from .interrupt import interrupted_line

EXIT_CONFIG = 2
EXIT_SIMULATION = 3
EXIT_OUTPUT = 4
EXIT_INTERRUPTED = 130


def format_error(e: BaseException) -> str:
    """One line: the error's message with newlines folded, prefixed by its kind."""
    if isinstance(e, ConfigError):
        kind = "config error"
    elif isinstance(e, OutputError):
        kind = "damaged file"
    else:
        kind = f"{type(e).__name__}"
    text = " ".join(str(e).split())
    return f"error ({kind}): {text}"


def main_guard(fn, *args, **kwargs):
    """Run `fn(*args, **kwargs)` after setting XLA's CPU defaults; ConfigError -> one line on stderr
    and exit code 2, SimulationError -> 3, a damaged result file (io.OutputError) -> 4, Ctrl-C -> one
    line and 130 (see the module docstring; a script's entry point, `script_main`, leaves at once
    on Ctrl-C). Returns fn's result otherwise."""
    set_cpu_defaults()
    try:
        return fn(*args, **kwargs)
    except KeyboardInterrupt:
        if os.environ.get("SPH_TRACEBACK"):
            raise
        print(interrupted_line(), file=sys.stderr, flush=True)
        raise SystemExit(EXIT_INTERRUPTED) from None
    except (ConfigError, SimulationError, OutputError) as e:
        if os.environ.get("SPH_TRACEBACK"):
            raise
        print(format_error(e), file=sys.stderr, flush=True)
        code = EXIT_CONFIG if isinstance(e, ConfigError) else EXIT_SIMULATION if isinstance(e, SimulationError) \
            else EXIT_OUTPUT
        raise SystemExit(code) from None


def script_main(fn, *args, **kwargs):
    """`main_guard(fn, ...)` as a script's entry point (the process ends with it): after Ctrl-C it
    leaves at once with 130 (`exit_interrupted`) instead of raising SystemExit."""
    try:
        return main_guard(fn, *args, **kwargs)
    except SystemExit as e:
        if e.code == EXIT_INTERRUPTED:
            exit_interrupted()
        raise


def exit_interrupted():
    """Leave with EXIT_INTERRUPTED (130) at once, after flushing stdout and stderr. By now the
    interrupt has unwound every `with` and `finally` of the run (trajectory files closed, their last
    checkpoint kept, locks and temporary files released); the interpreter's own teardown is skipped
    because XLA's CPU client, torn down while its worker threads are still running an interrupted
    computation, can crash there (a segmentation fault, exit 139, instead of 130). Only for a
    process that ends here (`script_main`): it ends the process, whoever called it."""
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError):
            pass
    os._exit(EXIT_INTERRUPTED)





class _Parser(argparse.ArgumentParser):
    """argparse with one-line errors ("error (usage): ...", exit 2) and no option left without the
    values it needs: `--only` with nothing after it is an error, not "run nothing"."""

    def error(self, message):
        print(f"error (usage): {self.prog}: {message} (see --help)", file=sys.stderr, flush=True)
        raise SystemExit(EXIT_CONFIG)

    def parse_args(self, args=None, namespace=None):
        ns = super().parse_args(args, namespace)
        for a in self._actions:
            if a.option_strings and a.nargs in ("*", "+") and getattr(ns, a.dest, None) == []:
                self.error(f"{a.option_strings[0]} needs at least one value; leave it out to mean all")
        return ns


def profile_parser(doc: Optional[str], options: Optional[Callable] = None) -> argparse.ArgumentParser:
    """The parser of a script: `--profile`, `--results` and the options `options(parser)` adds."""
    ap = _Parser(description=doc, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--profile", default="paper", help="profile of the config file (default paper)")
    ap.add_argument("--results", default=None, help="results folder (default results/<profile>)")
    if options is not None:
        options(ap)
    return ap


def profile_args(doc: Optional[str], argv=None, options: Optional[Callable] = None) -> argparse.Namespace:
    """The parsed command line (`profile_parser`), `results` defaulting to results/<profile>."""
    args = profile_parser(doc, options).parse_args(argv)
    if args.results is None:
        args.results = f"results/{args.profile}"
    return args


def profile_main(main: Callable, doc: Optional[str], options: Optional[Callable] = None, argv=None):
    """A script's command-line tail: `main(profile_args(doc, argv, options))` through `main_guard`."""
    guard = script_main if argv is None else main_guard   # argv given: called from Python, not a script's end
    return guard(lambda: main(profile_args(doc, argv, options)))


def experiment_main(work: Callable, load: Callable, doc: Optional[str], argv=None):
    """The command-line tail of a script whose whole work is `work(load(profile), results)` (e.g.
    `experiment_main(plot, settings.load, __doc__)`), through `profile_main`."""
    return profile_main(lambda args: work(load(args.profile), args.results), doc, argv=argv)


def run_options(grid: str, kind: type, values: str) -> Callable:
    """options(parser) of a study's run.py: `--only` (method names), `grid` (e.g. `--dx`, of type
    `kind`: a subset of the profile's `values`) and `--no-progress`; check the subsets with `select`."""

    def options(ap):
        ap.add_argument("--only", nargs="*", default=None, help="method names to run (default: all)")
        ap.add_argument(grid, nargs="*", type=kind, default=None,
                        help=f"run only these of the profile's {values} (default: all)")
        ap.add_argument("--no-progress", action="store_true")

    return options


def figure_main(plot: Callable, load: Callable, doc: Optional[str], name: str, argv=None):
    """The command-line tail of a plot script: `plot(load(profile), results, out)`, `--out` the figure
    folder (default <results>/<name>), through `profile_main`."""

    def options(ap):
        ap.add_argument("--out", default=None, help=f"figure folder (default <results>/{name})")

    return profile_main(lambda args: plot(load(args.profile), args.results, args.out), doc, options, argv)


def select(option: str, given: Optional[list], allowed: list) -> Optional[list]:
    """A command-line subset (`--only`, `--dx`) of the config's own values, or None for all of
    them. A value the config does not have is an error naming the option: the config, validated
    on load, is the only place that defines runs (`--dx 0.03` cannot bypass its rules)."""
    if given is None:
        return None
    if not given:
        raise ConfigError(f"{option}: given without a value: name at least one of {list(allowed)}, or leave "
                          "the option out to mean all")
    out = []
    for g in given:
        match = [a for a in allowed if (np.isclose(a, g, rtol=1e-9, atol=0) if isinstance(a, float) else a == g)]
        if not match:
            raise ConfigError(f"{option} {g!r}: not one of this profile's values {list(allowed)}; "
                              "add it to the profile in config.yaml (where it is validated) to run it")
        out.append(match[0])
    return out
