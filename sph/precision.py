"""Floating-point precision: float64 where gradients are checked, float32 where speed matters.

Importing `sph` does not touch JAX's global x64 flag, so machine-learning code that imports `sph`
(Solver-in-the-Loop) keeps training in float32. The caller's `numerics.dtype` decides: asking for
float64 (`resolve("float64")`, which `build_solver` does) switches x64 on explicitly, once, for the
process (`enable_x64`); every array the solver creates is cast to the precision the config asks for,
so float32 runs stay float32 whether or not x64 is on.
"""
import jax
import jax.numpy as jnp

DTYPES = {"float32": jnp.float32, "float64": jnp.float64}


def x64_enabled() -> bool:
    return bool(jax.config.jax_enable_x64)


def enable_x64() -> None:
    """Switch JAX to 64-bit for the whole process (needed before any float64 array is created)."""
    if not x64_enabled():
        jax.config.update("jax_enable_x64", True)


def resolve(dtype: str):
    """Return the jnp dtype for a config string, with a clear error for anything else; "float64"
    enables x64 (explicitly: it is what the caller's config asks for)."""
    try:
        out = DTYPES[dtype]
    except KeyError:
        raise ValueError(f"dtype: {dtype!r} is not one of {sorted(DTYPES)}") from None
    if out == jnp.float64:
        enable_x64()
    return out
