"""Top level of the experiment scripts: a configuration or run error is one line, not a traceback.

    from sph.cli import main_guard

    if __name__ == "__main__":
        main_guard(main)          # main() parses its own arguments (argparse)

`main_guard(fn, *args)` calls `fn(*args)` and returns its result. If it raises

    ConfigError               (a bad key or value, a degenerate scene, InsufficientMemory)
                              prints "error: <file>: profiles.<profile>.<key>: <what>" and exits 2;
                              the profile named is the one the key is written in, e.g. `paper`
                              when `smoke` inherits the bad key from it (`configtools.load_profile`)
    SimulationError           (BlowUp, ParticleEscaped, NeighborOverflow: step, particle, position,
                              likely cause, where the last good frame is kept) prints
                              "error: <message>" and exits 3

on stderr, without a traceback (set SPH_TRACEBACK=1 to see it). Everything else propagates.
`format_error(e)` is the line it prints.
"""
import os
import sys

from .configtools import ConfigError
from .diagnostics import SimulationError

EXIT_CONFIG = 2
EXIT_SIMULATION = 3


def format_error(e: BaseException) -> str:
    """One line: the error's message with newlines folded, prefixed by its kind."""
    kind = "config error" if isinstance(e, ConfigError) else f"{type(e).__name__}"
    text = " ".join(str(e).split())
    return f"error ({kind}): {text}"


def main_guard(fn, *args, **kwargs):
    """Run `fn(*args, **kwargs)`; ConfigError -> one line on stderr and exit code 2, SimulationError
    -> one line and exit code 3 (see the module docstring). Returns fn's result otherwise."""
    try:
        return fn(*args, **kwargs)
    except (ConfigError, SimulationError) as e:
        if os.environ.get("SPH_TRACEBACK"):
            raise
        print(format_error(e), file=sys.stderr, flush=True)
        raise SystemExit(EXIT_CONFIG if isinstance(e, ConfigError) else EXIT_SIMULATION) from None
