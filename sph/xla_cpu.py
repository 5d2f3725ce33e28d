"""XLA's CPU flags that this project's pair sums run fastest with, set by the entry points.

`import sph` leaves the process alone; the scripts (`lab.cli.main_guard` / `profile_main`),
the benchmarks and the tests' conftest call `set_cpu_defaults()` before their first JAX computation,
and a library user opts in with the same call:

    import sph
    sph.set_cpu_defaults()     # before the first JAX computation of the process (CPU: ~1.7x faster steps)

Process-wide by nature (XLA reads XLA_FLAGS once, when its CPU backend starts); `SPH_XLA_DEFAULTS=0`
turns it off. It changes only how XLA's CPU backend compiles reductions (not what they compute:
results agree to round-off), and nothing on GPU or TPU.
"""
import os


def set_cpu_defaults():
    """Hand no reductions to YNNPACK on the CPU (XLA flag `--xla_cpu_experimental_ynn_fusion_type=`).

    XLA 0.10 fuses a reduction and its elementwise producers into a YNNPACK call; for the pair sums
    of a step (an elementwise chain over (rows, K) reduced over K) that call is 1.2-1.9x slower than
    XLA's own fused loop (TGV, float64: 2D dx 0.02 2.7 -> 1.4 ms per step, 3D 32^3 161 -> 113 ms;
    float32 2D 1.85 -> 1.55 ms, 3D unchanged). XLA reads its flags once, when its backend starts, so
    this takes effect only if called before the first JAX computation of the process (the
    entry points call it first); later it is a no-op. Appended to XLA_FLAGS (inherited by child
    processes) unless the flag is already set there, only for the jaxlib versions it was measured
    with (an unknown flag aborts XLA), and not at all with SPH_XLA_DEFAULTS=0."""
    flag = "--xla_cpu_experimental_ynn_fusion_type"
    flags = os.environ.get("XLA_FLAGS", "")
    if os.environ.get("SPH_XLA_DEFAULTS", "1") == "0" or flag in flags:
        return
    import jaxlib

    if jaxlib.__version__ in ("0.10.2",):
        os.environ["XLA_FLAGS"] = f"{flags} {flag}=".strip()

