"""Small numba vector helpers shared by the physics and render kernels."""

from math import sqrt

from numba import njit


@njit(cache=True)
def perpendicular_unit(wx, wy, wz, ux, uy, uz, eps):
    """
    Return the unit part of w perpendicular to the unit vector u.

    When w is (within eps) along u, any unit vector perpendicular to u is returned instead.
    """
    dot = wx * ux + wy * uy + wz * uz
    ox, oy, oz = wx - dot * ux, wy - dot * uy, wz - dot * uz
    n = sqrt(ox * ox + oy * oy + oz * oz)
    if n < eps:
        if abs(ux) < 0.9:
            ox, oy, oz = 0.0, -uz, uy
        else:
            ox, oy, oz = uz, 0.0, -ux
        n = sqrt(ox * ox + oy * oy + oz * oz)
    return ox / n, oy / n, oz / n
