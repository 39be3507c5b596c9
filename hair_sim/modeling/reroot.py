"""
Move a hairstyle onto another head through a scalp parametrisation (not a plain snap).

    hair_sim_head reroot STYLE.yaml HEAD.yaml [--out NEW_STYLE.yaml]

Every control point is written in shell coordinates of the old head: a direction u from
the projection sphere's centre (thesis 3.2) and a height h above the scalp union along u.
The direction is carried to the new head through the scalp's extents (each axis and sign
scaled by new reach / old reach, so a root at the front hairline stays at the front
hairline of a longer or narrower head), and the point is put back at the same height above
the new scalp. Roots (h = 0) land on the new scalp; the hair keeps its shape and its
clearance. Control points that would end up inside one of the new head's body spheres
(ears, a jaw the old head did not have) are pushed out of it. The result is a derived style
whose `head:` names the new head file, checked like any style before it is written.
"""

import os

import numpy as np

from hair_sim.fileio import unwritable_file
from hair_sim.modeling.errors import HairstyleError
from hair_sim.modeling.hairstyle import hairstyle_from_dict, save_hairstyle

CLEARANCE = 0.002       # m a moved control point keeps from the new head's body spheres
MAX_CLEARANCE = 0.01
PUSH_PASSES = 8


def scalp_exit(head, directions):
    """
    Distance from the projection centre to the scalp union along unit directions (n, 3).

    The ray leaves the union where it leaves the sphere it leaves last: the largest far
    intersection over the scalp spheres (the centre lies inside one, so one always counts).
    """
    c = head.projection_sphere[:3]
    best = np.zeros(len(directions))
    for s in head.scalp:
        oc = c - s[:3]
        b = directions @ oc
        disc = b * b - (oc @ oc - s[3] ** 2)
        hit = disc >= 0.0
        far = np.where(hit, -b + np.sqrt(np.maximum(disc, 0.0)), 0.0)
        best = np.maximum(best, far)
    return best


def scalp_reach(head):
    """Reach of the scalp union from the projection centre: ((+x, +y, +z), (-x, -y, -z))."""
    axes = np.vstack([np.eye(3), -np.eye(3)])
    r = scalp_exit(head, axes)
    return r[:3], r[3:]


def map_directions(u, old, new):
    """Carry unit directions (n, 3) from one scalp to another by per-axis, per-sign reach."""
    (op, on), (np_, nn) = scalp_reach(old), scalp_reach(new)
    v = np.where(u >= 0.0, u / op * np_, u / on * nn)
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def move_points(points, old, new):
    """Return points (n, 3) moved from head `old` to head `new` in shell coordinates."""
    p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    rel = p - old.projection_sphere[:3]
    dist = np.linalg.norm(rel, axis=1)
    u = rel / np.maximum(dist, 1e-12)[:, None]
    height = dist - scalp_exit(old, u)
    u_new = map_directions(u, old, new)
    return new.projection_sphere[:3] + (scalp_exit(new, u_new) + height)[:, None] * u_new


def push_out(points, spheres, clearance, keep):
    """Push points out of spheres (k, 4) to `clearance`; rows in `keep` stay put."""
    p = points.copy()
    for _ in range(PUSH_PASSES):
        moved = False
        for s in spheres:
            rel = p - s[:3]
            d = np.linalg.norm(rel, axis=1)
            inside = (d < s[3] + clearance) & ~keep
            if inside.any():
                moved = True
                p[inside] = s[:3] + rel[inside] / np.maximum(d[inside], 1e-12)[:, None] \
                    * (s[3] + clearance)
        if not moved:
            break
    return p


def reroot_style(style, head, head_ref, name=None):
    """
    Return `style` moved onto `head` (a HeadModel) as a validated derived style.

    head_ref is what the new style's `head:` says (a head name or a .yaml path relative
    to where the style will be saved). Control points are kept CLEARANCE out of the new
    head's body spheres; when the strips built from them still cut the scalp (a patch's
    surface spans a bumpier scalp as a chord), every control point but the roots is kept
    one more CLEARANCE out of the scalp spheres, up to MAX_CLEARANCE. A strip may still
    graze a small body sphere between control hairs (an ear the old head did not have):
    the solver's guard moves it out on the first step.
    """
    from hair_sim.modeling.strips import build_strips
    moved_points = []
    for patch in style.patches:
        moved_points.append(move_points(patch.points.reshape(-1, 3), style.head, head))
    clearance = 0.0
    while True:
        data = style.to_dict()
        data['name'] = name or '%s_on_%s' % (style.name, head.name)
        data['head'] = head_ref
        for patch, d, pts in zip(style.patches, data['patches'], moved_points):
            roots = np.zeros((patch.n_hairs, patch.n_points), dtype=bool)
            roots[:, 0] = True
            keep = roots.reshape(-1)
            out = push_out(pts, head.body, CLEARANCE, keep)
            if clearance > 0.0:
                out = push_out(out, head.scalp, clearance, keep)
            d['control_hairs'] = out.reshape(patch.points.shape).round(6).tolist()
        moved = hairstyle_from_dict(data, head=head, where='style %r moved to head %r'
                                    % (style.name, head.name))
        rest = build_strips(moved).rest
        if head.scalp_distance(rest[:, 1:]).min() > 0.0 or clearance >= MAX_CLEARANCE:
            return moved
        clearance += CLEARANCE


def reroot_file(style_path, head_path, out=None, force=False):
    """Move the style file onto the head file; write the derived style; return its path."""
    from hair_sim.modeling.hairstyle import load_hairstyle
    from hair_sim.modeling.head import load_head
    style = load_hairstyle(style_path)
    head = load_head(head_path)
    if out is None:
        out = os.path.join(os.path.dirname(os.path.abspath(head_path)),
                           '%s_on_%s.yaml' % (style.name, head.name))
    out = os.path.abspath(out)
    why = unwritable_file(out)
    if why:
        raise HairstyleError(why)
    if os.path.exists(out) and not force:
        raise HairstyleError('%s exists (use --force to replace it)' % out)
    ref = os.path.relpath(os.path.abspath(head_path), os.path.dirname(out))
    moved = reroot_style(style, head, ref)
    save_hairstyle(moved, out)
    return out, moved
