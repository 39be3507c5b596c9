"""
Per-step numba kernels of the strand solver (thesis ch. 4 and 5). They write in place.

Every segment i of a strand has a zenith theta and an azimuth phi (thesis fig. 4.3) in a
polar chart of its own: three orthonormal rows (x, y, z) of `chart`, z the polar axis. A
chart is fixed in the world, so the angles carry inertia when the head turns; the rest
direction is rotated into the world with the head every step and the hinge spring
(eq. 3) pulls towards it. Charts are re-centred whenever the segment or its rest
direction comes within 45 degrees of a pole, with both placed on the new equator. Every
step re-centres first, so eqs. 1-6 are always evaluated at least 45 degrees from a pole
(sin(theta) >= 0.707, recorded in stats[3]). Within a step a segment turns at most
MAX_TURN before the position guard, which may turn it further; whatever angles result,
the next step re-centres before using them.
"""

from math import acos, atan2, cos, pi, sin, sqrt

from numba import njit
import numpy as np

from hair_sim.vecmath import perpendicular_unit

POLE_COS = cos(pi / 4.0)     # re-chart when |cos(theta)| exceeds this (45 deg from a pole)
MAX_TURN = 0.35              # rad: largest change of theta or phi in one step (guard)
GUARD_MARGIN = 2e-4          # m: the position guard puts vertices this far outside spheres
SEGMENT_TOLERANCE = 2e-4     # m: a segment's inner point deeper than this is pushed out
CONTACT_SKIN = 1e-3          # m: within this of a surface a vertex counts as in contact for
#                              eq. 7, so hair resting on the head (just outside, where the
#                              guard leaves it) keeps its inward force removed and settles
EXPLICIT = 0
IMPLICIT = 1
# Weights of x^{n+1}, x^n, x^{n-1} in the implicit hinge spring. (1/4, 1/2, 1/4) would be
# the trapezoidal rule: no numerical damping, but modes the step cannot resolve (stiff,
# very short segments) then ring for ever at the Nyquist rate. Leaning on x^{n+1} damps
# them (|z| -> sqrt(0.3 / 0.4) per step as omega dt -> infinity) while resolved modes keep
# their period within 1 % up to omega dt ~ 0.35.
W_NEXT, W_NOW, W_PREV = 0.4, 0.3, 0.3


@njit(cache=True)
def _wrap(a):
    """Wrap an angle difference into (-pi, pi]."""
    while a > pi:
        a -= 2.0 * pi
    while a <= -pi:
        a += 2.0 * pi
    return a


@njit(cache=True)
def _angles(C, dx, dy, dz):
    """Return (theta, phi) of unit direction d in chart C."""
    th, ph, _ = _angles_cos(C, dx, dy, dz)
    return th, ph


@njit(cache=True)
def _angles_cos(C, dx, dy, dz):
    """Return (theta, phi, cos(theta)) of unit direction d in chart C."""
    cz = C[2, 0] * dx + C[2, 1] * dy + C[2, 2] * dz
    cx = C[0, 0] * dx + C[0, 1] * dy + C[0, 2] * dz
    cy = C[1, 0] * dx + C[1, 1] * dy + C[1, 2] * dz
    cz = min(1.0, max(-1.0, cz))
    return acos(cz), atan2(cy, cx), cz


@njit(cache=True)
def _direction(C, th, ph):
    """Return the unit direction of angles (theta, phi) in chart C."""
    st = sin(th)
    ct = cos(th)
    a = st * cos(ph)
    b = st * sin(ph)
    return (a * C[0, 0] + b * C[1, 0] + ct * C[2, 0],
            a * C[0, 1] + b * C[1, 1] + ct * C[2, 1],
            a * C[0, 2] + b * C[1, 2] + ct * C[2, 2])


@njit(cache=True)
def _rechart(C, dx, dy, dz, rx, ry, rz):
    """Re-centre chart C in place so that d and the rest direction r lie on its equator."""
    zx = dy * rz - dz * ry
    zy = dz * rx - dx * rz
    zz = dx * ry - dy * rx
    n = sqrt(zx * zx + zy * zy + zz * zz)
    if n < 1e-6:                      # d parallel to r: keep the old polar axis, minimally
        zx, zy, zz = perpendicular_unit(C[2, 0], C[2, 1], C[2, 2], dx, dy, dz, 1e-6)
    else:
        zx /= n
        zy /= n
        zz /= n
    C[0, 0], C[0, 1], C[0, 2] = dx, dy, dz
    C[2, 0], C[2, 1], C[2, 2] = zx, zy, zz
    C[1, 0] = zy * dz - zz * dy
    C[1, 1] = zz * dx - zx * dz
    C[1, 2] = zx * dy - zy * dx


@njit(cache=True)
def init_charts(directions, chart, theta, phi):
    """Set each segment's chart so its direction sits at theta = pi/2, phi = 0."""
    n_s, n_seg = theta.shape
    for s in range(n_s):
        for i in range(n_seg):
            dx, dy, dz = directions[s, i, 0], directions[s, i, 1], directions[s, i, 2]
            C = chart[s, i]
            C[2, 0], C[2, 1], C[2, 2] = 0.0, 0.0, 1.0
            _rechart(C, dx, dy, dz, dx, dy, dz)
            theta[s, i], phi[s, i] = _angles(C, dx, dy, dz)


@njit(cache=True)
def rotate_charts(chart, R):
    """Rotate every chart by R (a teleport: the hair turns rigidly with the head)."""
    n_s, n_seg = chart.shape[0], chart.shape[1]
    for s in range(n_s):
        for i in range(n_seg):
            for r in range(3):
                x, y, z = chart[s, i, r, 0], chart[s, i, r, 1], chart[s, i, r, 2]
                chart[s, i, r, 0] = R[0, 0] * x + R[0, 1] * y + R[0, 2] * z
                chart[s, i, r, 1] = R[1, 0] * x + R[1, 1] * y + R[1, 2] * z
                chart[s, i, r, 2] = R[2, 0] * x + R[2, 1] * y + R[2, 2] * z


@njit(cache=True)
def _rotate(R, x, y, z):
    """Return R (x, y, z)."""
    return (R[0, 0] * x + R[0, 1] * y + R[0, 2] * z, R[1, 0] * x + R[1, 1] * y + R[1, 2] * z,
            R[2, 0] * x + R[2, 1] * y + R[2, 2] * z)


@njit(cache=True)
def root_kinematics(root_head, spheres_head, R, p, v, a, w, alpha, roots, root_acc, spheres,
                    sphere_vel):
    """
    Place roots and spheres with the head and give their accelerations and velocities.

    A point at r from the head origin moves with v + w x r and accelerates with
    a + alpha x r + w x (w x r) (the inertial force of thesis eq. 5 uses the roots').
    """
    for s in range(root_head.shape[0]):
        rx, ry, rz = _rotate(R, root_head[s, 0], root_head[s, 1], root_head[s, 2])
        roots[s, 0], roots[s, 1], roots[s, 2] = rx + p[0], ry + p[1], rz + p[2]
        cx = w[1] * rz - w[2] * ry
        cy = w[2] * rx - w[0] * rz
        cz = w[0] * ry - w[1] * rx
        root_acc[s, 0] = a[0] + alpha[1] * rz - alpha[2] * ry + w[1] * cz - w[2] * cy
        root_acc[s, 1] = a[1] + alpha[2] * rx - alpha[0] * rz + w[2] * cx - w[0] * cz
        root_acc[s, 2] = a[2] + alpha[0] * ry - alpha[1] * rx + w[0] * cy - w[1] * cx
    for k in range(spheres_head.shape[0]):
        rx, ry, rz = _rotate(R, spheres_head[k, 0], spheres_head[k, 1], spheres_head[k, 2])
        spheres[k, 0], spheres[k, 1], spheres[k, 2] = rx + p[0], ry + p[1], rz + p[2]
        spheres[k, 3] = spheres_head[k, 3]
        sphere_vel[k, 0] = v[0] + w[1] * rz - w[2] * ry
        sphere_vel[k, 1] = v[1] + w[2] * rx - w[0] * rz
        sphere_vel[k, 2] = v[2] + w[0] * ry - w[1] * rx


@njit(cache=True)
def strand_sphere_masks(root, reach, spheres, masks):
    """Broad phase: bit k of masks[s] is set when sphere k can touch strand s."""
    n_s = root.shape[0]
    n_k = spheres.shape[0]
    checked = 0
    for s in range(n_s):
        m = 0
        for k in range(n_k):
            dx = root[s, 0] - spheres[k, 0]
            dy = root[s, 1] - spheres[k, 1]
            dz = root[s, 2] - spheres[k, 2]
            lim = reach[s] + spheres[k, 3]
            checked += 1
            if dx * dx + dy * dy + dz * dz < lim * lim:
                m |= np.int64(1) << np.int64(k)
        masks[s] = m
    return checked


@njit(cache=True)
def _wind_at(x, y, z, t, base, amp, mdir, mk, mw, mph):
    """Return the wind velocity at a point: mean plus the seeded turbulence modes."""
    wx, wy, wz = base[0], base[1], base[2]
    if amp > 0.0:
        for m in range(mdir.shape[0]):
            s = amp * sin(mk[m, 0] * x + mk[m, 1] * y + mk[m, 2] * z - mw[m] * t + mph[m])
            wx += s * mdir[m, 0]
            wy += s * mdir[m, 1]
            wz += s * mdir[m, 2]
    return wx, wy, wz


@njit(cache=True)
def external_forces(pos, pos_prev, h_prev, mass, length, root_acc, gravity, wind_on,
                    wind_base, wind_amp, mdir, mk, mw, mph, t, drag_factor, f_dist, f_end):
    """
    Set the distributed force of every segment (eq. 5) and clear the end forces.

    F = rho d (g + a) + d f: gravity, the inertial force of the root's acceleration and the
    wind drag 0.5 rho_air Cd width l |v_perp| v_perp on the segment's relative velocity.
    The gusts' wavelengths (0.5 - 3 m) are longer than a strand, so the turbulence is
    evaluated once per strand, at its middle vertex.
    """
    n_s, n_seg = mass.shape
    inv_h = 1.0 / h_prev
    mid_v = (n_seg + 1) // 2
    for s in range(n_s):
        ax = gravity[0] - root_acc[s, 0]
        ay = gravity[1] - root_acc[s, 1]
        az = gravity[2] - root_acc[s, 2]
        wx = wy = wz = 0.0
        if wind_on:
            wx, wy, wz = _wind_at(pos[s, mid_v, 0], pos[s, mid_v, 1], pos[s, mid_v, 2], t,
                                  wind_base, wind_amp, mdir, mk, mw, mph)
        for i in range(n_seg):
            m = mass[s, i]
            fx, fy, fz = m * ax, m * ay, m * az
            if wind_on:
                seg_len = length[s, i]
                vx = 0.5 * (pos[s, i, 0] + pos[s, i + 1, 0]
                            - pos_prev[s, i, 0] - pos_prev[s, i + 1, 0]) * inv_h
                vy = 0.5 * (pos[s, i, 1] + pos[s, i + 1, 1]
                            - pos_prev[s, i, 1] - pos_prev[s, i + 1, 1]) * inv_h
                vz = 0.5 * (pos[s, i, 2] + pos[s, i + 1, 2]
                            - pos_prev[s, i, 2] - pos_prev[s, i + 1, 2]) * inv_h
                rx, ry, rz = wx - vx, wy - vy, wz - vz
                dx = (pos[s, i + 1, 0] - pos[s, i, 0]) / seg_len
                dy = (pos[s, i + 1, 1] - pos[s, i, 1]) / seg_len
                dz = (pos[s, i + 1, 2] - pos[s, i, 2]) / seg_len
                dot = rx * dx + ry * dy + rz * dz
                rx -= dot * dx
                ry -= dot * dy
                rz -= dot * dz
                q = drag_factor * seg_len * sqrt(rx * rx + ry * ry + rz * rz)
                fx += q * rx
                fy += q * ry
                fz += q * rz
            f_dist[s, i, 0] = fx
            f_dist[s, i, 1] = fy
            f_dist[s, i, 2] = fz
            f_end[s, i, 0] = 0.0
            f_end[s, i, 1] = 0.0
            f_end[s, i, 2] = 0.0


@njit(cache=True)
def _remove_inward(f, nx, ny, nz, w):
    """Eq. 7: drop the fraction w of the component of force f (in place) along -N."""
    d = f[0] * nx + f[1] * ny + f[2] * nz
    if d < 0.0:
        f[0] -= w * d * nx
        f[1] -= w * d * ny
        f[2] -= w * d * nz


@njit(cache=True)
def _contact_weight(d, r):
    """
    Return how much in contact a point at distance d from a centre is.

    1 up to where the guard leaves vertices (GUARD_MARGIN outside), 0 past the skin, linear
    between: an on/off switch would chatter at the skin's edge.
    """
    return min(1.0, max(0.0, (r + CONTACT_SKIN - d) / (CONTACT_SKIN - GUARD_MARGIN)))


@njit(cache=True)
def reaction_constraint_forces(pos, pos_prev, h_prev, length, spheres, sphere_vel, masks,
                               k_per_m, c_per_m, f_dist, f_end):
    """
    Collision response by reaction constraints (eqs. 7-10) for vertices and segments.

    A vertex P in contact (inside, or within CONTACT_SKIN outside) keeps only the outward
    part of its input force (eq. 7) and gets F_constrained = -(k PT + c V.N) N (eq. 8), PT
    the signed distance from the nearest surface point T along the outward normal N (only
    its inward part pushes) and V the velocity relative to the sphere. k and c are given
    per metre of strand and scaled by the segment's length, like its mass.
    A segment whose inner point Q is inside (both ends outside) gets the same response at Q
    with the input force interpolated from its ends, moved to the free end with weight t so
    that the torque about the segment's start is the same; a segment whose start already
    touches the sphere (a root on the scalp) is left to that vertex's own test. Returns
    the contacts found.
    """
    n_s, n_seg = f_dist.shape[0], f_dist.shape[1]
    inv_h = 1.0 / h_prev
    contacts = 0
    for s in range(n_s):
        mask = masks[s]
        if mask == 0:
            continue
        for kk in range(spheres.shape[0]):
            if not (mask >> np.int64(kk)) & np.int64(1):
                continue
            cx, cy, cz, r = spheres[kk, 0], spheres[kk, 1], spheres[kk, 2], spheres[kk, 3]
            for i in range(n_seg):
                px, py, pz = pos[s, i + 1, 0], pos[s, i + 1, 1], pos[s, i + 1, 2]
                ex, ey, ez = px - cx, py - cy, pz - cz
                d2 = ex * ex + ey * ey + ez * ez
                reach = r + CONTACT_SKIN + length[s, i]
                if d2 > reach * reach:
                    continue        # neither the end nor any point of the segment is in contact
                k = k_per_m * length[s, i]
                c = c_per_m * length[s, i]
                d = sqrt(d2)
                if d < r + CONTACT_SKIN and d > 1e-12:
                    nx, ny, nz = ex / d, ey / d, ez / d
                    vx = (px - pos_prev[s, i + 1, 0]) * inv_h - sphere_vel[kk, 0]
                    vy = (py - pos_prev[s, i + 1, 1]) * inv_h - sphere_vel[kk, 1]
                    vz = (pz - pos_prev[s, i + 1, 2]) * inv_h - sphere_vel[kk, 2]
                    w = _contact_weight(d, r)
                    _remove_inward(f_dist[s, i], nx, ny, nz, w)
                    _remove_inward(f_end[s, i], nx, ny, nz, w)
                    mag = k * max(r - d, 0.0) - w * c * (vx * nx + vy * ny + vz * nz)  # eq. 8
                    f_end[s, i, 0] += mag * nx
                    f_end[s, i, 1] += mag * ny
                    f_end[s, i, 2] += mag * nz
                    contacts += 1
                    continue
                ax, ay, az = pos[s, i, 0], pos[s, i, 1], pos[s, i, 2]
                ox, oy, oz = ax - cx, ay - cy, az - cz
                if ox * ox + oy * oy + oz * oz < (r + CONTACT_SKIN) ** 2:
                    continue        # the start touches this sphere: its own vertex test rules
                sx, sy, sz = px - ax, py - ay, pz - az
                ll = sx * sx + sy * sy + sz * sz
                tt = ((cx - ax) * sx + (cy - ay) * sy + (cz - az) * sz) / ll
                if tt <= 0.0 or tt >= 1.0:
                    continue
                qx, qy, qz = ax + tt * sx - cx, ay + tt * sy - cy, az + tt * sz - cz
                dq = sqrt(qx * qx + qy * qy + qz * qz)
                if dq >= r + CONTACT_SKIN or dq < 1e-12:
                    continue
                nx, ny, nz = qx / dq, qy / dq, qz / dq
                # input force at Q, interpolated between the segment's two ends
                fin = np.empty(3)
                for a in range(3):
                    f1 = f_dist[s, i, a] + f_end[s, i, a]
                    f0 = 0.0 if i == 0 else f_dist[s, i - 1, a] + f_end[s, i - 1, a]
                    fin[a] = (1.0 - tt) * f0 + tt * f1
                vx = ((1 - tt) * (ax - pos_prev[s, i, 0]) + tt * (px - pos_prev[s, i + 1, 0])) \
                    * inv_h - sphere_vel[kk, 0]
                vy = ((1 - tt) * (ay - pos_prev[s, i, 1]) + tt * (py - pos_prev[s, i + 1, 1])) \
                    * inv_h - sphere_vel[kk, 1]
                vz = ((1 - tt) * (az - pos_prev[s, i, 2]) + tt * (pz - pos_prev[s, i + 1, 2])) \
                    * inv_h - sphere_vel[kk, 2]
                fn = fin[0] * nx + fin[1] * ny + fin[2] * nz
                w = _contact_weight(dq, r)
                mag = -w * min(fn, 0.0) + k * max(r - dq, 0.0) - w * c * (
                    vx * nx + vy * ny + vz * nz)                               # eq. 10
                f_end[s, i, 0] += tt * mag * nx
                f_end[s, i, 1] += tt * mag * ny
                f_end[s, i, 2] += tt * mag * nz
                contacts += 1
    return contacts


@njit(cache=True)
def _scalp_projection(x, y, z, scalp):
    """Return the radial projection of a point onto its nearest scalp sphere."""
    best = 1e30
    bk = 0
    for k in range(scalp.shape[0]):
        dx, dy, dz = x - scalp[k, 0], y - scalp[k, 1], z - scalp[k, 2]
        d = sqrt(dx * dx + dy * dy + dz * dz) - scalp[k, 3]
        if d < best:
            best = d
            bk = k
    dx, dy, dz = x - scalp[bk, 0], y - scalp[bk, 1], z - scalp[bk, 2]
    d = max(sqrt(dx * dx + dy * dy + dz * dz), 1e-12)
    f = scalp[bk, 3] / d
    return scalp[bk, 0] + f * dx, scalp[bk, 1] + f * dy, scalp[bk, 2] + f * dz


@njit(cache=True)
def _wall_sd(pos, px, py, pz, a, b, j):
    """wall_signed_distance with Q's scalp projection (px, py, pz) given."""
    n_v = pos.shape[1]
    qx, qy, qz = pos[b, j, 0], pos[b, j, 1], pos[b, j, 2]
    j0 = max(j - 1, 0)
    j1 = min(j + 1, n_v - 1)
    tx = pos[b, j1, 0] - pos[b, j0, 0]
    ty = pos[b, j1, 1] - pos[b, j0, 1]
    tz = pos[b, j1, 2] - pos[b, j0, 2]
    wx, wy, wz = px - qx, py - qy, pz - qz
    nx, ny, nz = ty * wz - tz * wy, tz * wx - tx * wz, tx * wy - ty * wx
    n = sqrt(nx * nx + ny * ny + nz * nz)
    if n < 1e-15:
        return 1e30, 0.0, 0.0, 0.0, 0.0
    nx /= n
    ny /= n
    nz /= n
    rx, ry, rz = pos[a, j, 0] - qx, pos[a, j, 1] - qy, pos[a, j, 2] - qz
    ww = wx * wx + wy * wy + wz * wz
    along = (rx * wx + ry * wy + rz * wz) / ww if ww > 1e-18 else 0.0
    return rx * nx + ry * ny + rz * nz, nx, ny, nz, along


@njit(cache=True)
def wall_signed_distance(pos, scalp, a, b, j):
    """
    Signed distance of vertex j of strand a from strand b's projected wall (thesis 5.2).

    The wall is the polygon from b's vertex Q down to its scalp projection Q', locally the
    plane through Q spanned by b's tangent and QQ'. Returns (distance, nx, ny, nz, along)
    with the unit normal and the position of a's vertex along QQ' (0 at Q, 1 at Q').
    """
    px, py, pz = _scalp_projection(pos[b, j, 0], pos[b, j, 1], pos[b, j, 2], scalp)
    return _wall_sd(pos, px, py, pz, a, b, j)


@njit(cache=True)
def strip_springs(pos, length, scalp, pairs, rest1, k1, wall_sign, k2, d2, rest3, k3, f_end,
                  proj):
    """
    Springs of thesis 5.2, eq. 11 (F = -k x), added to the end forces of the segments.

    Type 1 joins vertex j of facing strands of neighbouring strips; type 2 is inserted only
    when a vertex comes within d2 of its neighbour's projected wall and pushes it back to
    d2; type 3 joins a vertex to its own scalp projection (rest3 < 0 disables it). The
    constants are per metre of strand, scaled by the length of the segment each vertex ends.
    Returns the number of type-2 springs inserted. proj is scratch space (n_strands,
    n_vertices, 3) for every vertex's scalp projection, computed once and shared.
    """
    n_v = pos.shape[1]
    inserted = 0
    for s in range(pos.shape[0]):
        for j in range(1, n_v):
            px, py, pz = _scalp_projection(pos[s, j, 0], pos[s, j, 1], pos[s, j, 2], scalp)
            proj[s, j, 0], proj[s, j, 1], proj[s, j, 2] = px, py, pz
    for q in range(pairs.shape[0]):
        a, b = pairs[q, 0], pairs[q, 1]
        for j in range(1, n_v):
            if k1 > 0.0:
                dx = pos[b, j, 0] - pos[a, j, 0]
                dy = pos[b, j, 1] - pos[a, j, 1]
                dz = pos[b, j, 2] - pos[a, j, 2]
                d = sqrt(dx * dx + dy * dy + dz * dz)
                if d > 1e-12:
                    f = 0.5 * k1 * (length[a, j - 1] + length[b, j - 1]) * (d - rest1[q, j]) / d
                    f_end[a, j - 1, 0] += f * dx
                    f_end[a, j - 1, 1] += f * dy
                    f_end[a, j - 1, 2] += f * dz
                    f_end[b, j - 1, 0] -= f * dx
                    f_end[b, j - 1, 1] -= f * dy
                    f_end[b, j - 1, 2] -= f * dz
            if k2 > 0.0:
                for side in range(2):
                    me, other = (a, b) if side == 0 else (b, a)
                    sd, nx, ny, nz, along = _wall_sd(pos, proj[other, j, 0], proj[other, j, 1],
                                                     proj[other, j, 2], me, other, j)
                    sd *= wall_sign[q, j, side]
                    taper = min(1.0, max(0.0, 4.0 * (along + 0.25)),
                                max(0.0, 4.0 * (1.25 - along)))
                    if sd < d2 and taper > 0.0:
                        f = taper * k2 * length[me, j - 1] * (d2 - sd) * wall_sign[q, j, side]
                        f_end[me, j - 1, 0] += f * nx
                        f_end[me, j - 1, 1] += f * ny
                        f_end[me, j - 1, 2] += f * nz
                        # reaction on the wall's top vertex Q (the scalp holds Q')
                        g = f * min(1.0, max(0.0, 1.0 - along))
                        f_end[other, j - 1, 0] -= g * nx
                        f_end[other, j - 1, 1] -= g * ny
                        f_end[other, j - 1, 2] -= g * nz
                        inserted += 1
    if k3 > 0.0:
        for s in range(pos.shape[0]):
            for j in range(1, n_v):
                if rest3[s, j] < 0.0:
                    continue
                dx = pos[s, j, 0] - proj[s, j, 0]
                dy = pos[s, j, 1] - proj[s, j, 1]
                dz = pos[s, j, 2] - proj[s, j, 2]
                d = sqrt(dx * dx + dy * dy + dz * dz)
                if d > 1e-12:
                    f = -k3 * length[s, j - 1] * (d - rest3[s, j]) / d
                    f_end[s, j - 1, 0] += f * dx
                    f_end[s, j - 1, 1] += f * dy
                    f_end[s, j - 1, 2] += f * dz
    return inserted


@njit(cache=True)
def _guard(px, py, pz, ex, ey, ez, seg_len, spheres, mask):
    """
    Position guard: turn the segment p->e (length l) so no vertex ends inside a sphere.

    The penalty force of eq. 8 must stay soft for the explicit force term, so a fast
    vertex can still cross a sphere's surface within one step; this moves the end vertex
    (or the segment's deepest point) radially out to GUARD_MARGIN outside the sphere by
    turning the segment about its start. Spheres that contain the start are left alone.
    Returns the new end point and whether anything moved.
    """
    moved = False
    for _ in range(12):
        changed = False
        for kk in range(spheres.shape[0]):
            if not (mask >> np.int64(kk)) & np.int64(1):
                continue
            cx, cy, cz, r = spheres[kk, 0], spheres[kk, 1], spheres[kk, 2], spheres[kk, 3]
            dx, dy, dz = ex - cx, ey - cy, ez - cz
            d2 = dx * dx + dy * dy + dz * dz
            if d2 > (r + seg_len) * (r + seg_len):
                continue            # the end is so far out that no point of the segment is in
            sx, sy, sz = px - cx, py - cy, pz - cz
            if sx * sx + sy * sy + sz * sz < (r - 1e-4) * (r - 1e-4):
                continue
            d = sqrt(d2)
            tx, ty, tz = 0.0, 0.0, 0.0
            hit = False
            if d < r:
                # The end p + l d' stays outside iff d'.u <= kappa (u: unit vector from p to
                # the centre, D: their distance): project d onto that cone, exactly.
                D = sqrt(sx * sx + sy * sy + sz * sz)
                ux, uy, uz = -sx / D, -sy / D, -sz / D
                rr = r + GUARD_MARGIN
                kappa = (D * D + seg_len * seg_len - rr * rr) / (2.0 * seg_len * D)
                if kappa > -1.0:
                    kappa = min(kappa, 1.0)
                    # (heading straight at the centre: any side will do)
                    ox, oy, oz = perpendicular_unit(ex - px, ey - py, ez - pz, ux, uy, uz,
                                                    1e-12)
                    sk = sqrt(max(0.0, 1.0 - kappa * kappa))
                    tx = px + kappa * ux + sk * ox
                    ty = py + kappa * uy + sk * oy
                    tz = pz + kappa * uz + sk * oz
                    hit = True
            else:
                # A segment whose start rests on the surface may sag in like a chord lying
                # on the sphere (at most l^2 / 8r); one whose start is clear of the skin
                # may dip SEGMENT_TOLERANCE. The allowance is continuous in the start's
                # height and the guard stops exactly at it, so a resting segment reaches a
                # fixed point instead of flickering across a threshold.
                ds = sqrt(sx * sx + sy * sy + sz * sz)
                allow = SEGMENT_TOLERANCE + seg_len * seg_len / (8.0 * r) * min(
                    1.0, max(0.0, (r + CONTACT_SKIN - ds) / CONTACT_SKIN))
                ux, uy, uz = ex - px, ey - py, ez - pz
                tt = -(sx * ux + sy * uy + sz * uz) / (seg_len * seg_len)
                if 0.0 < tt < 1.0:
                    qx, qy, qz = sx + tt * ux, sy + tt * uy, sz + tt * uz
                    dq = sqrt(qx * qx + qy * qy + qz * qz)
                    if dq < r - allow:
                        f = (r - allow + 1e-6) / max(dq, 1e-12)
                        # where the segment's point at tt must go, seen from p
                        tx = px + (cx + f * qx - px) / tt
                        ty = py + (cy + f * qy - py) / tt
                        tz = pz + (cz + f * qz - pz) / tt
                        hit = True
            if hit:
                ux, uy, uz = tx - px, ty - py, tz - pz
                n = sqrt(ux * ux + uy * uy + uz * uz)
                if n > 1e-12:
                    inv = seg_len / n
                    ex, ey, ez = px + inv * ux, py + inv * uy, pz + inv * uz
                    moved = True
                    changed = True
        if not changed:
            break
    return ex, ey, ez, moved


@njit(cache=True)
def integrate_strands(theta, phi, theta_prev, phi_prev, chart, rest_dir, length, inv_inertia,
                      k_hinge, damping, f_dist, f_end, R, roots, spheres, masks, collide,
                      pos, pos_prev, h, integrator, stats):
    """
    Advance every segment by eq. 1, from root to tip, and place the vertices.

    explicit: eq. 6 as the thesis writes it (with M/I): th+ = 2th - th- - gamma dt (th -
    th-) + dt^2 M/I. implicit: the hinge spring (eq. 3) is taken at the weighted mean
    W_NEXT x+ + W_NOW x + W_PREV x- and the damping centred, (x+ - x-) / 2dt, both
    implicitly; the external moment (eq. 4) explicitly. Unconditionally stable for the
    spring; unresolved stiff modes are damped.
    stats gets [max speed of a segment's end about its start (m/s), re-charts, guard moves,
    min sin(theta), turn clamps].
    """
    n_s, n_seg = theta.shape
    max_rate = 0.0
    recharts = 0
    guards = 0
    clamps = 0
    min_sin = 1.0
    h2 = h * h
    for s in range(n_s):
        for j in range(n_seg + 1):
            pos_prev[s, j, 0] = pos[s, j, 0]
            pos_prev[s, j, 1] = pos[s, j, 1]
            pos_prev[s, j, 2] = pos[s, j, 2]
        px, py, pz = roots[s, 0], roots[s, 1], roots[s, 2]
        pos[s, 0, 0], pos[s, 0, 1], pos[s, 0, 2] = px, py, pz
        mask = masks[s] if collide else np.int64(0)
        for i in range(n_seg):
            C = chart[s, i]
            rx, ry, rz = _rotate(R, rest_dir[s, i, 0], rest_dir[s, i, 1], rest_dir[s, i, 2])
            th, ph = theta[s, i], phi[s, i]
            thp, php = theta_prev[s, i], phi_prev[s, i]
            th0, ph0, ct0 = _angles_cos(C, rx, ry, rz)
            ct = cos(th)
            if abs(ct) > POLE_COS or abs(ct0) > POLE_COS:
                dx, dy, dz = _direction(C, th, ph)
                qx, qy, qz = _direction(C, thp, php)
                _rechart(C, dx, dy, dz, rx, ry, rz)
                th, ph = _angles(C, dx, dy, dz)
                thp, php = _angles(C, qx, qy, qz)
                th0, ph0 = _angles(C, rx, ry, rz)
                recharts += 1
                ct = cos(th)
            st = sin(th)
            sp, cp = sin(ph), cos(ph)
            if st < min_sin:
                min_sin = st
            # unit vectors along increasing theta and phi (fig. 4.3)
            etx = ct * cp * C[0, 0] + ct * sp * C[1, 0] - st * C[2, 0]
            ety = ct * cp * C[0, 1] + ct * sp * C[1, 1] - st * C[2, 1]
            etz = ct * cp * C[0, 2] + ct * sp * C[1, 2] - st * C[2, 2]
            epx = -sp * C[0, 0] + cp * C[1, 0]
            epy = -sp * C[0, 1] + cp * C[1, 1]
            epz = -sp * C[0, 2] + cp * C[1, 2]
            seg_len = length[s, i]
            # eq. 4: M_theta = u F_theta, M_phi = v F_phi with u = l/2, v = (l/2) sin(theta)
            # for the distributed force; forces at the segment's end act with lever l.
            fdt = f_dist[s, i, 0] * etx + f_dist[s, i, 1] * ety + f_dist[s, i, 2] * etz
            fdp = f_dist[s, i, 0] * epx + f_dist[s, i, 1] * epy + f_dist[s, i, 2] * epz
            fet = f_end[s, i, 0] * etx + f_end[s, i, 1] * ety + f_end[s, i, 2] * etz
            fep = f_end[s, i, 0] * epx + f_end[s, i, 1] * epy + f_end[s, i, 2] * epz
            m_th = 0.5 * seg_len * fdt + seg_len * fet
            m_ph = (0.5 * seg_len * fdp + seg_len * fep) * st
            k = k_hinge[s, i]
            ii = inv_inertia[s, i]
            x_th = th - th0                 # deviations from the rest angles (eq. 3)
            x_thp = thp - th0
            x_ph = _wrap(ph - ph0)
            x_php = x_ph - _wrap(ph - php)
            if integrator == EXPLICIT:
                # eq. 6
                n_th = 2 * x_th - x_thp - damping * h * (x_th - x_thp) + h2 * ii * (
                    -k * x_th + m_th)
                n_ph = 2 * x_ph - x_php - damping * h * (x_ph - x_php) + h2 * ii * (
                    -k * x_ph + m_ph)
            else:
                a = k * h2 * ii
                b = 0.5 * damping * h
                den = 1.0 + a * W_NEXT + b
                n_th = (2 * x_th - x_thp - a * (W_NOW * x_th + W_PREV * x_thp) + b * x_thp
                        + h2 * ii * m_th) / den
                n_ph = (2 * x_ph - x_php - a * (W_NOW * x_ph + W_PREV * x_php) + b * x_php
                        + h2 * ii * m_ph) / den
            d_th = n_th - x_th
            d_ph = n_ph - x_ph
            if abs(d_th) > MAX_TURN or abs(d_ph) > MAX_TURN:   # guard: counted, not hidden
                d_th = min(MAX_TURN, max(-MAX_TURN, d_th))
                d_ph = min(MAX_TURN, max(-MAX_TURN, d_ph))
                clamps += 1
            new_th = th + d_th
            new_ph = ph + d_ph
            dx, dy, dz = _direction(C, new_th, new_ph)
            ex, ey, ez = px + seg_len * dx, py + seg_len * dy, pz + seg_len * dz
            moved = False
            if mask != 0:
                ex, ey, ez, moved = _guard(px, py, pz, ex, ey, ez, seg_len, spheres,
                                           mask)
            if moved:
                # contact: the segment is turned out of the sphere and stopped there
                inv = 1.0 / seg_len
                new_th, new_ph = _angles(C, (ex - px) * inv, (ey - py) * inv, (ez - pz) * inv)
                theta_prev[s, i] = new_th
                phi_prev[s, i] = new_ph
                guards += 1
            else:
                theta_prev[s, i] = th
                phi_prev[s, i] = new_ph - d_ph
            wrapped = _wrap(new_ph)
            phi_prev[s, i] += wrapped - new_ph
            theta[s, i] = new_th
            phi[s, i] = wrapped
            sn = sin(new_th)
            turn = max(abs(new_th - theta_prev[s, i]), abs(wrapped - phi_prev[s, i]) * sn)
            rate = turn * seg_len / h
            if rate > max_rate:
                max_rate = rate
            pos[s, i + 1, 0], pos[s, i + 1, 1], pos[s, i + 1, 2] = ex, ey, ez
            px, py, pz = ex, ey, ez
    stats[0] = max_rate
    stats[1] += recharts
    stats[2] += guards
    stats[3] = min(stats[3], min_sin)
    stats[4] += clamps
    return n_s * n_seg


@njit(cache=True)
def guard_rest_shape(rest, spheres):
    """
    Make a rest shape (head frame) consistent with the position guard, in place.

    A modeled strand may have chords that sag a little into the scalp; a hinge spring
    pulling towards such a shape would fight the guard for ever. Each segment, root to tip,
    is turned exactly as the guard would turn it. Returns the number of segments moved.
    """
    n_s, n_v = rest.shape[0], rest.shape[1]
    all_spheres = (np.int64(1) << np.int64(spheres.shape[0])) - np.int64(1)
    moved = 0
    for s in range(n_s):
        for j in range(n_v - 1):
            px, py, pz = rest[s, j, 0], rest[s, j, 1], rest[s, j, 2]
            dx, dy, dz = rest[s, j + 1, 0] - px, rest[s, j + 1, 1] - py, rest[s, j + 1, 2] - pz
            seg_len = sqrt(dx * dx + dy * dy + dz * dz)
            ex, ey, ez, m = _guard(px, py, pz, rest[s, j + 1, 0], rest[s, j + 1, 1],
                                   rest[s, j + 1, 2], seg_len, spheres, all_spheres)
            if m:
                # carry the rest of the strand along rigidly so other segments keep theirs
                ox, oy, oz = ex - rest[s, j + 1, 0], ey - rest[s, j + 1, 1], ez - rest[s, j + 1, 2]
                for k in range(j + 1, n_v):
                    rest[s, k, 0] += ox
                    rest[s, k, 1] += oy
                    rest[s, k, 2] += oz
                moved += 1
    return moved
