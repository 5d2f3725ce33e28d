"""Ctrl-C that is never lost: installed when the harness is first imported (lab/__init__.py), before JAX.

Python raises KeyboardInterrupt wherever the main thread happens to be; inside a garbage-collector
callback (JAX registers `_xla_gc_callback`, which runs at every collection) Python prints "Exception
ignored" and carries on (so too in a finalizer, `__del__`): an interrupt during imports or
compilation could be dropped, and the run went on to the end. `_on_sigint` asks again 50 ms later when it lands in such a callback. It
replaces only Python's default handler, in the main thread (not where Ctrl-C is ignored, as in a
background job, or handled otherwise). An interrupt before a script's `lab.cli.main_guard` (while
it imports) prints one line too (`_excepthook`); what the scripts do with it is `main_guard`'s.
"""
import gc
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


def _ignored_here(frame) -> bool:
    """Whether an exception raised at `frame` would be ignored: it runs inside a garbage-collector
    callback or a finalizer (`__del__`)."""
    codes = {getattr(cb, "__code__", None) for cb in gc.callbacks}
    while frame is not None:
        if frame.f_code in codes or frame.f_code.co_name == "__del__":
            return True
        frame = frame.f_back
    return False


def _on_sigint(signum, frame):
    if _ignored_here(frame):
        threading.Timer(0.05, os.kill, (os.getpid(), signal.SIGINT)).start()
        return
    raise KeyboardInterrupt


def install() -> None:
    """The one-line excepthook, and the SIGINT handler where Python's default is in place."""
    sys.excepthook = _excepthook
    if threading.current_thread() is threading.main_thread() and \
            signal.getsignal(signal.SIGINT) is signal.default_int_handler:
        signal.signal(signal.SIGINT, _on_sigint)
