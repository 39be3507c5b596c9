"""Small vector helpers shared by the physics and render kernels (numba), and inputs."""

from math import copysign, pi, sqrt

from numba import njit
import numpy as np

from hair_sim.kernels import njit_without_refcounts


# atan on |u| <= 0.66 as u + u z P(z) / Q(z), z = u^2: the rational of S. L. Moshier's
# Cephes library (atan.c, public domain), about 1e-16 relative there
_ATAN_P = (-8.750608600031904122785e-1, -1.615753718733365076637e1,
           -7.500855792314704667340e1, -1.228866684490136173410e2,
           -6.485021904942025371773e1)
_ATAN_Q = (2.485846490142306297962e1, 1.650270098316988542046e2,
           4.328810604912902668951e2, 4.853903996359136964868e2,
           1.945506571482613964425e2)
_HALF_PI = 0.5 * pi
_QUARTER_PI = 0.25 * pi
_PI_TAIL = 1.2246467991473532e-16      # pi - float(pi): the low bits the offsets lose


@njit_without_refcounts
def atan2_vectorizable(y, x):
    """
    Return atan2(y, x) for finite y, x, within 2 ulp of libm's, without a branch or call.

    A loop that calls libm's atan2 is not vectorised (the call is opaque to LLVM); this
    one is selects and arithmetic, so a loop over many angles runs four at a time (AVX2).
    The ratio of the smaller to the larger of |x|, |y| is reduced to |u| <= 0.66 by
    atan(t) = pi/4 + atan((t - 1) / (t + 1)), then the octant is restored. Signs follow
    libm (atan2(+-0, x < 0) = +-pi, atan2(+-0, +0) = +-0) except at (+-0, -0), where this
    gives +-0 and libm +-pi. Non-finite input gives NaN or a wrong angle, not libm's
    limits (the kernels take angles of finite unit vectors).
    """
    ax = abs(x)
    ay = abs(y)
    small = min(ax, ay)
    large = max(ax, ay)
    # t = small / large, and past 0.66 u = (t - 1) / (t + 1), in one division each way
    reduced = small > 0.66 * large
    num_u = small - large if reduced else small
    den_u = small + large if reduced else large
    u = num_u / den_u if large > 0.0 else 0.0
    z = u * u
    p = _ATAN_P
    q = _ATAN_Q
    num = (((p[0] * z + p[1]) * z + p[2]) * z + p[3]) * z + p[4]
    den = ((((z + q[0]) * z + q[1]) * z + q[2]) * z + q[3]) * z + q[4]
    a = u + u * z * num / den
    a = _QUARTER_PI + (a + 0.25 * _PI_TAIL) if reduced else a
    a = _HALF_PI - a + 0.5 * _PI_TAIL if ay > ax else a
    a = pi - a + _PI_TAIL if x < 0.0 else a
    return copysign(a, y)


# sin and cos on |z| <= pi/4 as polynomials, and pi/4 split in three for the reduction
# (Cody and Waite): S. L. Moshier's Cephes library (sin.c, public domain)
_SIN_C = (1.58962301576546568060e-10, -2.50507477628578072866e-8,
          2.75573136213857245213e-6, -1.98412698295895385996e-4,
          8.33333333332211858878e-3, -1.66666666666666307295e-1)
_COS_C = (-1.13585365213876817300e-11, 2.08757008419747316778e-9,
          -2.75573141792967388112e-7, 2.48015872888517045348e-5,
          -1.38888888888730564116e-3, 4.16666666666665929218e-2)
_DP1 = 7.85398125648498535156e-1
_DP2 = 3.77489470793079817668e-8
_DP3 = 2.69515142907905952645e-15
_FOUR_OVER_PI = 4.0 / pi


@njit_without_refcounts
def sin_vectorizable(x):
    """
    Return sin(x) for finite |x| < 2^30, within a few ulp of libm's, without a branch.

    A loop calling libm's sin is not vectorised; this is selects and arithmetic, so a loop
    over many arguments runs four at a time (AVX2). x is reduced by the octant
    j = floor(|x| 4 / pi), rounded up to even, to |z| <= pi/4, then the sine or cosine
    polynomial is taken by the quadrant (j mod 8) and the sign restored (Cephes sin.c). The
    reduction loses accuracy beyond 2^30; the kernels reduce their phases first.
    """
    a = abs(x)
    y = np.floor(a * _FOUR_OVER_PI)
    y = y + (y - 2.0 * np.floor(0.5 * y))         # rounded up to even (floats throughout:
    j = y - 8.0 * np.floor(0.125 * y)             # AVX2 has no double-to-int64 conversion)
    negative = (j > 3.0) != (copysign(1.0, x) < 0.0)     # (-0.0 keeps its sign)
    z = ((a - y * _DP1) - y * _DP2) - y * _DP3
    zz = z * z
    c = _COS_C
    s = _SIN_C
    cos_z = 1.0 - 0.5 * zz + zz * zz * (((((c[0] * zz + c[1]) * zz + c[2]) * zz + c[3])
                                         * zz + c[4]) * zz + c[5])
    sin_z = z + z * zz * (((((s[0] * zz + s[1]) * zz + s[2]) * zz + s[3]) * zz + s[4])
                          * zz + s[5])
    r = cos_z if (j == 2.0) | (j == 6.0) else sin_z
    return -r if negative else r


@njit_without_refcounts
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


@njit_without_refcounts
def nearest_on_spheres(x, y, z, spheres):
    """
    Return the radial projection of a point onto the sphere whose surface is nearest.

    spheres: (n, 4) rows (cx, cy, cz, r). This is "projection onto the scalp" wherever a
    point needs its place on the scalp (springs of type 3, walls, snapping roots).
    """
    best = 1e30
    bk = 0
    bd = 0.0
    for k in range(spheres.shape[0]):
        dx, dy, dz = x - spheres[k, 0], y - spheres[k, 1], z - spheres[k, 2]
        d = sqrt(dx * dx + dy * dy + dz * dz)
        if d - spheres[k, 3] < best:
            best = d - spheres[k, 3]
            bk = k
            bd = d
    f = spheres[bk, 3] / max(bd, 1e-12)
    return (spheres[bk, 0] + f * (x - spheres[bk, 0]), spheres[bk, 1] + f * (y - spheres[bk, 1]),
            spheres[bk, 2] + f * (z - spheres[bk, 2]))


@njit_without_refcounts
def nearest_on_spheres_many(points, spheres, out):
    """nearest_on_spheres for every row of points (n, 3), into out (n, 3)."""
    for i in range(points.shape[0]):
        out[i, 0], out[i, 1], out[i, 2] = nearest_on_spheres(points[i, 0], points[i, 1],
                                                             points[i, 2], spheres)
    return out


@njit_without_refcounts
def _dot(ax, ay, az, bx, by, bz):
    return ax * bx + ay * by + az * bz


@njit_without_refcounts
def _triangle_distance_sq(p, a, b, c):
    """Squared distance from p to triangle abc (Ericson, Real-Time Collision Detection 5.1.5)."""
    abx, aby, abz = b[0] - a[0], b[1] - a[1], b[2] - a[2]
    acx, acy, acz = c[0] - a[0], c[1] - a[1], c[2] - a[2]
    d1 = _dot(abx, aby, abz, p[0] - a[0], p[1] - a[1], p[2] - a[2])
    d2 = _dot(acx, acy, acz, p[0] - a[0], p[1] - a[1], p[2] - a[2])
    d3 = _dot(abx, aby, abz, p[0] - b[0], p[1] - b[1], p[2] - b[2])
    d4 = _dot(acx, acy, acz, p[0] - b[0], p[1] - b[1], p[2] - b[2])
    d5 = _dot(abx, aby, abz, p[0] - c[0], p[1] - c[1], p[2] - c[2])
    d6 = _dot(acx, acy, acz, p[0] - c[0], p[1] - c[1], p[2] - c[2])
    va = d3 * d6 - d5 * d4
    vb = d5 * d2 - d1 * d6
    vc = d1 * d4 - d3 * d2
    u = 0.0      # closest point a + u * ab + w * ac
    w = 0.0
    if d1 <= 0.0 and d2 <= 0.0:
        pass
    elif d3 >= 0.0 and d4 <= d3:
        u = 1.0
    elif d6 >= 0.0 and d5 <= d6:
        w = 1.0
    elif vc <= 0.0 and d1 >= 0.0 and d3 <= 0.0:
        u = d1 / (d1 - d3)
    elif vb <= 0.0 and d2 >= 0.0 and d6 <= 0.0:
        w = d2 / (d2 - d6)
    elif va <= 0.0 and d4 - d3 >= 0.0 and d5 - d6 >= 0.0:
        w = (d4 - d3) / ((d4 - d3) + (d5 - d6))
        u = 1.0 - w
    else:
        den = 1.0 / (va + vb + vc)
        u = vb * den
        w = vc * den
    ex = p[0] - (a[0] + u * abx + w * acx)
    ey = p[1] - (a[1] + u * aby + w * acy)
    ez = p[2] - (a[2] + u * abz + w * acz)
    return ex * ex + ey * ey + ez * ez


@njit(cache=True)
def distance_to_triangles(points, upper, vertices, triangles, out):
    """
    Write into out (n,) the exact distance of each point (n, 3) to a triangle mesh.

    upper (n,) bounds each distance from above (np.inf when unknown); triangles whose
    bounding sphere lies farther are skipped, which is what makes a good bound pay.
    """
    nt = triangles.shape[0]
    centre = np.empty((nt, 3))
    reach = np.empty(nt)
    for t in range(nt):
        for k in range(3):
            centre[t, k] = (vertices[triangles[t, 0], k] + vertices[triangles[t, 1], k]
                            + vertices[triangles[t, 2], k]) / 3.0
        r = 0.0
        for j in range(3):
            v = vertices[triangles[t, j]]
            r = max(r, sqrt((v[0] - centre[t, 0]) ** 2 + (v[1] - centre[t, 1]) ** 2
                            + (v[2] - centre[t, 2]) ** 2))
        reach[t] = r
    for i in range(points.shape[0]):
        p = points[i]
        best = upper[i] * upper[i] if upper[i] < 1e150 else 1e300
        for t in range(nt):
            lower = sqrt((p[0] - centre[t, 0]) ** 2 + (p[1] - centre[t, 1]) ** 2
                         + (p[2] - centre[t, 2]) ** 2) - reach[t]
            if lower > 0.0 and lower * lower >= best:
                continue
            d = _triangle_distance_sq(p, vertices[triangles[t, 0]], vertices[triangles[t, 1]],
                                      vertices[triangles[t, 2]])
            if d < best:
                best = d
        out[i] = sqrt(best)
    return out


# |v| below this may have lost digits to squares that underflowed (1e-300 squared is 0)
_SMALLEST_PLAIN_LENGTH = 1e-150


def vector_lengths(v):
    """
    Return |v| along the last axis, also where the squares overflow or underflow.

    Where the plain norm is finite and not tiny it is returned as it is (so a direction
    or a wind normalised by it is the same to the bit); elsewhere v is scaled by its
    largest component first (1e154 and 1e-320 have lengths, not inf and 0). A zero
    vector has length 0; a vector with a NaN or an infinity has length NaN.
    """
    v = np.asarray(v, dtype=np.float64)
    with np.errstate(over='ignore', under='ignore', invalid='ignore', divide='ignore'):
        # (one vector: norm's own dot product, which rounds unlike the sum along an axis)
        plain = np.linalg.norm(v) if v.ndim == 1 else np.linalg.norm(v, axis=-1)
        big = np.abs(v).max(axis=-1)
        scaled = big * np.linalg.norm(v / big[..., None], axis=-1)
    kept = np.isfinite(plain) & (plain >= _SMALLEST_PLAIN_LENGTH)
    return np.where(kept, plain, np.where(big > 0.0, scaled, big))


@njit_without_refcounts
def wrap_angle(a):
    """Wrap an angle difference into (-pi, pi]."""
    while a > pi:
        a -= 2.0 * pi
    while a <= -pi:
        a += 2.0 * pi
    return a
