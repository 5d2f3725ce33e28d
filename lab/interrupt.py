"""Ctrl-C that is never lost: installed when the harness is first imported (lab/__init__.py), before JAX.

Python raises KeyboardInterrupt wherever the main thread happens to be. Inside a garbage-collector
callback (JAX registers `_xla_gc_callback`, which runs at every collection), a weakref callback or a
finalizer it cannot: it prints "Exception ignored" (through `sys.unraisablehook`) and carries on, so
an interrupt during imports or compilation could be dropped and the run went on to the end.
`_unraisable` asks for such an interrupt again 50 ms later, where it can be raised. An interrupt
before a script's `lab.cli.main_guard` (while it imports) prints one line (`_excepthook`); what the
scripts do with it is `main_guard`'s.
"""
import os
import signal
import sys
import threading


def interrupted_line() -> str:
    """What Ctrl-C prints: the script stopped, what it finished is kept, how to go on."""
    script = os.path.basename(sys.argv[0]) if sys.argv and sys.argv[0] else "python"
    return (f"interrupted: {script} stopped; finished runs and frames are kept, an unfinished run resumes "
            "from its last checkpoint: resume with the same command")


def _excepthook(kind, value, tb, _default=sys.excepthook):
    """Ctrl-C outside `lab.cli.main_guard` (while a script imports, or in a script without it): one
    line, no traceback (Python then leaves by SIGINT: 130 in the shell); everything else as Python
    prints it."""
    if issubclass(kind, KeyboardInterrupt) and not os.environ.get("SPH_TRACEBACK"):
        print(interrupted_line(), file=sys.stderr, flush=True)
        return
    _default(kind, value, tb)


def _unraisable(info, _default=sys.unraisablehook):
    """`sys.unraisablehook`: a KeyboardInterrupt that Python could not raise (it came inside a
    garbage-collector callback, a weakref callback or a finalizer, and was printed as "Exception
    ignored") is asked for again 50 ms later, where it can be raised; everything else as Python
    reports it."""
    if isinstance(info.exc_value, KeyboardInterrupt):
        threading.Timer(0.05, os.kill, (os.getpid(), signal.SIGINT)).start()
        return
    _default(info)


def install() -> None:
    """The one-line excepthook and the hook that re-asks a swallowed Ctrl-C."""
    sys.excepthook = _excepthook
    sys.unraisablehook = _unraisable
