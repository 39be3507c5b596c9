"""
Visibility culling: strips that cannot be seen from a viewpoint are not drawn (thesis 3.3).

A strip is skipped only when all of it, its vertices and its U-shape walls, lies in the
shadow of the head's spheres (so it faces away too). The ball test is
exact: a ball B is shadowed by sphere S when it lies inside the cone of rays from the eye
that touch S and no nearer to the eye than the tangent length sqrt(|ES|^2 - r^2) (any ray
in that cone has entered S by then). Strips are covered by balls around their simulated
vertices and along their walls, with radii that leave room for the refinement between
them; the test suite checks against a ray caster that no culled strip is hit by any ray.
"""

from math import asin, sqrt

from numba import njit
import numpy as np

from hair_sim.render.ushape import strip_wall_bottoms


@njit(cache=True)
def _ball_hidden_by(bx, by, bz, rho, eye, occ, k):
    """Return True if the ball (b, rho) is in the shadow of occluding sphere k."""
    dx, dy, dz = bx - eye[0], by - eye[1], bz - eye[2]
    db = sqrt(dx * dx + dy * dy + dz * dz)
    cx, cy, cz = occ[k, 0] - eye[0], occ[k, 1] - eye[1], occ[k, 2] - eye[2]
    dc = sqrt(cx * cx + cy * cy + cz * cz)
    r = occ[k, 3]
    if db <= rho or dc <= r or db - rho < sqrt(dc * dc - r * r):
        return False
    cosang = min(1.0, max(-1.0, (dx * cx + dy * cy + dz * cz) / (db * dc)))
    return np.arccos(cosang) + asin(min(1.0, rho / db)) <= asin(r / dc)


@njit(cache=True)
def _ball_hidden(bx, by, bz, rho, eye, occ):
    """Return True if some occluding sphere shadows the ball (b, rho)."""
    for k in range(occ.shape[0]):
        if _ball_hidden_by(bx, by, bz, rho, eye, occ, k):
            return True
    return False


@njit(cache=True)
def _deviation(pos, st, j):
    """Return |P[j-1] - 2 P[j] + P[j+1]| of strand st (0 at the ends)."""
    V = pos.shape[1]
    if j <= 0 or j >= V - 1:
        return 0.0
    dx = pos[st, j - 1, 0] - 2 * pos[st, j, 0] + pos[st, j + 1, 0]
    dy = pos[st, j - 1, 1] - 2 * pos[st, j, 1] + pos[st, j + 1, 1]
    dz = pos[st, j - 1, 2] - 2 * pos[st, j, 2] + pos[st, j + 1, 2]
    return sqrt(dx * dx + dy * dy + dz * dz)


@njit(cache=True)
def _patch_hidden(p0, p1, q0, q1, dev, eye, occ, leaf):
    """
    Return True if a bilinear patch thickened by dev is in the shadow of the spheres.

    The patch spans an edge p0 -> p1 and its wall bottoms q0 -> q1. A sub-patch lies in
    the hull of its corners, so its corners' bounding ball (+ dev) shadowed by one sphere
    settles it; otherwise it is split in four, down to `leaf` size, where an unshadowed
    ball means visible.
    """
    stack = np.empty((64, 4))
    stack[0, 0], stack[0, 1], stack[0, 2], stack[0, 3] = 0.0, 1.0, 0.0, 1.0
    top = 1
    corners = np.empty((4, 3))
    while top > 0:
        top -= 1
        t0, t1, f0, f1 = stack[top, 0], stack[top, 1], stack[top, 2], stack[top, 3]
        for c in range(4):
            t = t0 if c < 2 else t1
            f = f0 if c % 2 == 0 else f1
            for d in range(3):
                e = (1 - t) * p0[d] + t * p1[d]
                w = (1 - t) * q0[d] + t * q1[d]
                corners[c, d] = (1 - f) * e + f * w
        mx = 0.25 * (corners[0, 0] + corners[1, 0] + corners[2, 0] + corners[3, 0])
        my = 0.25 * (corners[0, 1] + corners[1, 1] + corners[2, 1] + corners[3, 1])
        mz = 0.25 * (corners[0, 2] + corners[1, 2] + corners[2, 2] + corners[3, 2])
        rho = 0.0
        for c in range(4):
            rho = max(rho, sqrt((corners[c, 0] - mx) ** 2 + (corners[c, 1] - my) ** 2
                                + (corners[c, 2] - mz) ** 2))
        if _ball_hidden(mx, my, mz, rho + dev + 1e-4, eye, occ):
            continue
        if rho < leaf or top > 59:
            return False
        tm, fm = 0.5 * (t0 + t1), 0.5 * (f0 + f1)
        for (a0, a1, b0, b1) in ((t0, tm, f0, fm), (tm, t1, f0, fm), (t0, tm, fm, f1),
                                 (tm, t1, fm, f1)):
            stack[top, 0], stack[top, 1], stack[top, 2], stack[top, 3] = a0, a1, b0, b1
            top += 1
    return True


@njit(cache=True)
def visible_strips(pos,
                   strip_strands,
                   sigma,
                   projection,
                   eye,
                   occ,
                   leaf,
                   bottoms,
                   out):
    """
    Write 1 into out[s] for strips that may be seen from eye, 0 for culled ones.

    The drawn edge of a strip is an Oslo refinement of its simulated edge polygon and lies
    within |second difference| / 6 of it (refined control polygons of a cubic B-spline
    stay between the control polygon and the curve); its wall runs down to bottoms close
    to those of the simulated vertices. Each edge segment with its wall is a bilinear patch
    thickened by that deviation; a strip is culled when every patch is in the shadow of
    the spheres (only strips facing away can be). A strip with a simulated vertex in plain
    view is visible at once; the wall bottoms (scratch array `bottoms`) and the patches are
    worked out only for the others. Returns the number of visible strips.
    """
    n_strips = strip_strands.shape[0]
    V = pos.shape[1]
    count = 0
    for s in range(n_strips):
        a, b = strip_strands[s, 0], strip_strands[s, 1]
        # cheap and exact first: a simulated vertex in plain view makes the strip visible
        vis = False
        for q in range(2):
            st = a if q == 0 else b
            for j in range(V):
                if not _ball_hidden(pos[st, j, 0], pos[st, j, 1], pos[st, j, 2], 0.0, eye,
                                    occ):
                    vis = True
                    break
            if vis:
                break
        if not vis:
            strip_wall_bottoms(
                pos,
                strip_strands,
                s,
                sigma[s],
                projection,
                bottoms,
            )
        for q in range(2):
            if vis:
                break
            st = a if q == 0 else b
            for j in range(V - 1):
                dev = max(_deviation(pos, st, j), _deviation(pos, st, j + 1)) / 6.0
                if not _patch_hidden(pos[st, j], pos[st, j + 1], bottoms[st, j],
                                     bottoms[st, j + 1], dev, eye, occ, leaf):
                    vis = True
                    break
        out[s] = 1 if vis else 0
        if vis:
            count += 1
    return count
