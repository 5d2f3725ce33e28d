"""Atomic file writes that two processes (or threads) may make at once: each writer fills a temporary
file of its own beside the target (`<name>.<pid>-<thread>.tmp`), then renames it over the target, so
a reader sees the old or the new file whole, and concurrent writers of the same file (`make -j2`, two
processes of one sweep writing the same study's records) never rename each other's half-written or
already-moved temporary file."""
import os
import threading
from pathlib import Path


def tmp_path(path) -> Path:
    """This writer's temporary file for `path` (ends in .tmp: run stamps skip it)."""
    path = Path(path)
    return path.with_name(f"{path.name}.{os.getpid()}-{threading.get_ident()}.tmp")


def write_text(path, text: str) -> Path:
    """Write `text` to `path` atomically (folder created); returns `path`."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = tmp_path(path)
    try:
        tmp.write_text(text)
        tmp.replace(path)
    finally:
        tmp.unlink(missing_ok=True)
    return path
