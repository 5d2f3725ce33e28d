"""The two-process side of `make bench-peer` (bench/bench_peer.py): timing workers, the driver's
client for them, and the summary / table of their rounds. Standard library and NumPy only, so that
it imports in every environment (.venv, .venv-lb, .venv-peer) and in tests without JAX.

A worker is a process that has built one code's solver for one case; it speaks JSON lines:

    worker -> driver   {"ready": true, ...case info..., "warmup_s": s}   after one warm-up round
    driver -> worker   {"cmd": "run", "steps": n}
    worker -> driver   {"steps": n, "wall_s": s, "cpu_s": s}             one timed round
    driver -> worker   {"cmd": "quit"}
    worker -> driver   {"rss_base_gb": .., "rss_peak_gb": .., "rss_max_gb": .., "rss_method": ..}

Times are measured inside the worker around the round only (no pipe or start-up cost): wall
(`perf_counter`) and CPU time of the whole process, all threads (`process_time`). Memory, from
/proc/self/status: `rss_base_gb` the resident set after importing JAX and starting its CPU backend,
before the case is built; `rss_peak_gb` the peak resident set during the timed rounds (VmHWM, reset
through /proc/self/clear_refs after the warm-up, so compilation peaks are excluded); `rss_max_gb`
the peak over the process's life (ru_maxrss, compilation included). Where clear_refs is refused,
`rss_peak_gb` is ru_maxrss after the rounds (`rss_method` says which).

The driver alternates rounds: peer, ours, peer, ours, ... (`interleave`); the idle worker waits on
its pipe and uses no CPU.
"""
import json
import os
import resource
import subprocess
import sys
import time

import numpy as np

GB = 1024.0**3


# ---------------------------------------------------------------------------------------------------
# worker side
# ---------------------------------------------------------------------------------------------------

def _status_kb(field):
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith(field + ":"):
                return int(line.split()[1])
    raise KeyError(field)


def rss_gb():
    """The resident set now, GB."""
    return _status_kb("VmRSS") * 1024 / GB


def open_channel():
    """The worker's protocol stream: the real stdout, kept for JSON lines only; file descriptor 1 (and
    with it `print`, JAX's and XLA's messages) then goes to stderr. Call before importing JAX."""
    out = os.fdopen(os.dup(1), "w", buffering=1)
    os.dup2(2, 1)
    return out


def send(out, msg):
    out.write(json.dumps(msg) + "\n")
    out.flush()


def serve(out, run, steps, info):
    """The worker loop: one warm-up round of `steps` (it also compiles), `ready` with `info`, then
    timed rounds until `quit`. `run(n)` advances n steps and returns when they are done."""
    t0 = time.perf_counter()
    run(steps)
    warmup_s = time.perf_counter() - t0
    try:
        with open("/proc/self/clear_refs", "w") as f:
            f.write("5")  # reset the peak resident set (VmHWM) to the current one
        method = "VmHWM after warm-up"
    except OSError:
        method = "ru_maxrss"
    send(out, {"ready": True, **info, "warmup_s": warmup_s})
    for line in sys.stdin:
        msg = json.loads(line)
        if msg["cmd"] == "run":
            n = int(msg["steps"])
            t0, c0 = time.perf_counter(), time.process_time()
            run(n)
            send(out, {"steps": n, "wall_s": time.perf_counter() - t0, "cpu_s": time.process_time() - c0})
        elif msg["cmd"] == "quit":
            max_gb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024 / GB
            peak_gb = _status_kb("VmHWM") * 1024 / GB if method.startswith("VmHWM") else max_gb
            send(out, {"rss_base_gb": info.get("rss_base_gb", float("nan")), "rss_peak_gb": peak_gb,
                       "rss_max_gb": max_gb, "rss_method": method})
            return
        else:
            raise ValueError(f"unknown command {msg!r}")


# ---------------------------------------------------------------------------------------------------
# driver side
# ---------------------------------------------------------------------------------------------------

class WorkerError(RuntimeError):
    pass


class Worker:
    """A worker process started with `argv` (its stderr passes through to ours)."""

    def __init__(self, argv, name, env=None, cwd=None):
        self.name = name
        self.proc = subprocess.Popen(argv, stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True,
                                     env=env, cwd=cwd, bufsize=1)
        self.info = self._recv()
        if not self.info.get("ready"):
            raise WorkerError(f"{name}: expected ready, got {self.info}")

    def _recv(self):
        line = self.proc.stdout.readline()
        if not line:
            code = self.proc.wait()
            raise WorkerError(f"{self.name} worker ended (exit code {code}) without answering; its "
                              "messages are above")
        return json.loads(line)

    def _ask(self, msg):
        self.proc.stdin.write(json.dumps(msg) + "\n")
        self.proc.stdin.flush()
        return self._recv()

    def run(self, steps):
        return self._ask({"cmd": "run", "steps": steps})

    def quit(self):
        final = self._ask({"cmd": "quit"})
        self.proc.stdin.close()
        self.proc.wait(timeout=60)
        return final

    def kill(self):
        if self.proc.poll() is None:
            self.proc.kill()
            self.proc.wait()


def interleave(first, second, steps, repeats):
    """`repeats` rounds of `steps` steps, alternating first, second, first, ...: the rounds of each."""
    rounds = ([], [])
    for _ in range(repeats):
        for i, w in enumerate((first, second)):
            rounds[i].append(w.run(steps))
    return rounds


def summarize(peer_rounds, ours_rounds):
    """Min / median wall and CPU ms per step of each code, and the ratios peer / ours (of the mins,
    of the medians)."""
    out = {}
    per = {}
    for who, rounds in (("jax_sph", peer_rounds), ("ours", ours_rounds)):
        steps = np.array([r["steps"] for r in rounds], float)
        for kind in ("wall", "cpu"):
            t = 1e3 * np.array([r[f"{kind}_s"] for r in rounds]) / steps
            per[who, kind] = t
            prefix = f"{who}_" if kind == "wall" else f"{who}_cpu_"
            out[prefix + "min_ms"] = float(t.min())
            out[prefix + "median_ms"] = float(np.median(t))
    for kind, prefix in (("wall", ""), ("cpu", "cpu_")):
        a, b = per["jax_sph", kind], per["ours", kind]
        out[prefix + "ratio_min"] = float(a.min() / b.min())
        out[prefix + "ratio_median"] = float(np.median(a) / np.median(b))
    return out


def _mem(row, who):
    """Peak resident set during the timed rounds above the bare JAX process, GB (None if not measured)."""
    peak, base = row.get(f"{who}_rss_peak_gb"), row.get(f"{who}_rss_base_gb")
    return None if peak is None or base is None else peak - base


def _num(x, width, digits=2):
    return f"{'-':>{width}s}" if x is None or x != x else f"{x:{width}.{digits}f}"


def format_table(rows, title):
    """The printed table: wall ms per step, min and median of each code and their ratios; the median CPU
    ms per step of each and their ratio; the peak memory of the timed rounds above the bare JAX
    process ("-" where not measured)."""
    head = (f"{'case':26s} {'N':>7s} | {'JAX-SPH min':>11s} {'median':>8s} {'ours min':>8s} {'median':>8s} "
            f"{'ratio':>6s} {'median':>6s} | {'CPU JAX-SPH':>11s} {'ours':>8s} {'ratio':>6s} | "
            f"{'GB JAX-SPH':>10s} {'ours':>5s}")
    lines = [title, head]
    for r in rows:
        lines.append(
            f"{r['case']:26s} {r['n']:7d} | {r['jax_sph_min_ms']:11.2f} {r['jax_sph_median_ms']:8.2f} "
            f"{r['ours_min_ms']:8.2f} {r['ours_median_ms']:8.2f} {r['ratio_min']:6.2f} {r['ratio_median']:6.2f} | "
            f"{r['jax_sph_cpu_median_ms']:11.2f} {r['ours_cpu_median_ms']:8.2f} {r['cpu_ratio_median']:6.2f} | "
            f"{_num(_mem(r, 'jax_sph'), 10)} {_num(_mem(r, 'ours'), 5)}")
    lines.append("(ms per step: wall min, median; CPU time (all threads) median; ratio = JAX-SPH / ours; GB = peak "
                 "resident set while stepping minus that of the bare JAX process)")
    return "\n".join(lines)
