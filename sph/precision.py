"""Floating-point precision: float64 where gradients are checked, float32 where speed matters.

x64 is switched on process-wide once (it must happen before arrays are created); every array the
solver creates is then cast to the precision the config asks for, so float32 runs stay float32.
"""
import jax
import jax.numpy as jnp

DTYPES = {"float32": jnp.float32, "float64": jnp.float64}

jax.config.update("jax_enable_x64", True)


def resolve(dtype: str):
    """Return the jnp dtype for a config string, with a clear error for anything else."""
    try:
        return DTYPES[dtype]
    except KeyError:
        raise ValueError(f"dtype: {dtype!r} is not one of {sorted(DTYPES)}") from None
