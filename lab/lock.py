"""One writer per output folder: an exclusive lock held while a run (or a cached result) is written.

`make -j2` may start two processes that want the same run folder (two targets sharing a relaxed
start or a run). `folder_lock(folder)` takes an exclusive `fcntl.flock` on a lock file in the folder
(``.run.lock``; stamps ignore ``*.lock``, lab.stamp); a second writer waits for it, after
printing who holds it, and then finds the run complete and skips it (`lab.runs.run_cached`
checks the stored state only once it holds the lock). The kernel drops the lock when its holder
exits, also on SIGKILL, so a killed run never leaves a stale lock behind; the file itself stays.

    with folder_lock(run_folder):
        ...  # write traj.h5, metadata.json
"""
import fcntl
import os
import socket
import sys
import time
from contextlib import contextmanager
from pathlib import Path

LOCK_NAME = ".run.lock"


def holder_line() -> str:
    """Who holds the lock: pid, host, start time and command (written into the lock file)."""
    cmd = " ".join(os.path.basename(a) if i == 0 else a for i, a in enumerate(sys.argv))[:200]
    return f"pid {os.getpid()} on {socket.gethostname()} since {time.strftime('%Y-%m-%d %H:%M:%S')} ({cmd})"


@contextmanager
def folder_lock(folder, name: str = LOCK_NAME, quiet: bool = False):
    """Hold an exclusive lock on `folder` (created if missing) for the `with` block; wait while another
    process holds it, printing its holder line once."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / name
    with open(path, "a+") as f:
        try:
            fcntl.flock(f, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            f.seek(0)
            holder = f.read().strip() or "another process"
            if not quiet:
                print(f"{folder}: being written by {holder}; waiting for it", flush=True)
            fcntl.flock(f, fcntl.LOCK_EX)
            if not quiet:
                print(f"{folder}: released, continuing", flush=True)
        try:
            f.seek(0)
            f.truncate()
            f.write(holder_line() + "\n")
            f.flush()
            yield path
        finally:
            f.seek(0)
            f.truncate()
            f.flush()
            fcntl.flock(f, fcntl.LOCK_UN)
