"""How many devices a process has, and asking for more on a host without accelerators (issue 40).

    from sph.parallel.devices import use_devices
    use_devices(4)      # before the first JAX computation: on a CPU-only host, 4 XLA host devices

XLA splits a CPU into N devices only if told before its backend starts
(`--xla_force_host_platform_device_count=N` in XLA_FLAGS), so `use_devices(n)` appends that flag while
no backend has started yet, then checks that the default backend has n devices. The flag only adds
host (CPU) devices: on a machine with GPUs the default backend stays the GPUs, and asking for more
GPUs than there are is refused, naming both counts. Called after the backend started with too few
devices, it refuses too, saying how to set the flag before Python starts.
"""
import os

FLAG = "--xla_force_host_platform_device_count"


def _backend_started() -> bool:
    try:
        from jax._src import xla_bridge
    except ImportError:  # pragma: no cover  (a jax without it: assume started, the check below decides)
        return True
    return xla_bridge.backends_are_initialized()


def use_devices(n: int) -> int:
    """Make sure this process sees at least `n` devices (see the module docstring); returns n."""
    if not (isinstance(n, int) and not isinstance(n, bool) and n >= 1):
        raise ValueError(f"devices: must be a whole number >= 1, got {n!r}")
    if n == 1:
        return n
    flags = os.environ.get("XLA_FLAGS", "")
    if FLAG not in flags and not _backend_started():
        os.environ["XLA_FLAGS"] = f"{flags} {FLAG}={n}".strip()
    import jax

    have = jax.device_count()
    if have < n:
        raise ValueError(f"devices: {n} asked for but this process has {have} {jax.default_backend()} device(s); "
                         f"on a CPU-only host start Python with XLA_FLAGS={FLAG}={n} (or let `make DEVICES={n}` "
                         f"do it), on GPUs use at most {have} per process or launch several processes")
    return n
