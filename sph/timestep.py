"""Time-step selection from the stability limits of explicit WCSPH (Adami 2012, eqs. 23-25)."""
import numpy as np


def time_step(h, c_ref, u_ref, eta, rho_ref, g_max, cfl=0.25, diffusivity=0.0) -> dict:
    """Return the individual limits and their minimum `dt`:

    convective  cfl h / (c_ref + u_ref)
    viscous     cfl h^2 rho_ref / eta          (none when eta = 0)
    body force  cfl sqrt(h / |g|_max)          (none without body force)
    thermal     cfl h^2 / alpha, alpha = kappa / (rho c_p)   (only with heat; same form as viscous)
    """
    limits = {"convective": cfl * h / (c_ref + u_ref)}
    if eta > 0:
        limits["viscous"] = cfl * h**2 * rho_ref / eta
    if g_max > 0:
        limits["body_force"] = cfl * np.sqrt(h / g_max)
    if diffusivity > 0:
        limits["thermal"] = cfl * h**2 / diffusivity
    limits["dt"] = min(limits.values())
    return limits
