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


@njit(cache=True)
def nearest_on_spheres(x, y, z, spheres):
    """
    Return the radial projection of a point onto the sphere whose surface is nearest.

    spheres: (n, 4) rows (cx, cy, cz, r). This is "projection onto the scalp" wherever a
    point needs its place on the scalp (springs of type 3, walls, snapping roots).
    """
    best = 1e30
    bk = 0
    for k in range(spheres.shape[0]):
        dx, dy, dz = x - spheres[k, 0], y - spheres[k, 1], z - spheres[k, 2]
        d = sqrt(dx * dx + dy * dy + dz * dz) - spheres[k, 3]
        if d < best:
            best = d
            bk = k
    dx, dy, dz = x - spheres[bk, 0], y - spheres[bk, 1], z - spheres[bk, 2]
    d = max(sqrt(dx * dx + dy * dy + dz * dz), 1e-12)
    f = spheres[bk, 3] / d
    return spheres[bk, 0] + f * dx, spheres[bk, 1] + f * dy, spheres[bk, 2] + f * dz


@njit(cache=True)
def nearest_on_spheres_many(points, spheres, out):
    """nearest_on_spheres for every row of points (n, 3), into out (n, 3)."""
    for i in range(points.shape[0]):
        out[i, 0], out[i, 1], out[i, 2] = nearest_on_spheres(points[i, 0], points[i, 1],
                                                             points[i, 2], spheres)
    return out
