"""
Generate the shipped hairstyles' control hairs (config/hairstyles/*.yaml).

Each control hair is draped over the default head: it starts at a root on the scalp,
follows the scalp at a small clearance in a chosen direction, bends towards gravity and
falls past the collision spheres. Its control points are samples of that path. The short
style is derived from the long one by moving control points only (thesis 6.1, fig. 6.4).
Run from the repository root: .venv/bin/python tools/make_styles.py
"""

import os
import sys

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)

from hair_sim import paths  # noqa: E402
from hair_sim.modeling.hairstyle import hairstyle_from_dict, save_hairstyle  # noqa: E402
from hair_sim.modeling.head import load_head  # noqa: E402
from hair_sim.modeling.strips import snap_to_scalp  # noqa: E402

HEAD = load_head(paths.shipped_head('default_adult'))
OUT = os.path.join(ROOT, 'config', 'hairstyles')


def scalp_normal(p):
    """Outward normal of the nearest scalp sphere at p."""
    d = np.linalg.norm(p - HEAD.scalp[:, :3], axis=1) - HEAD.scalp[:, 3]
    c = HEAD.scalp[np.argmin(d), :3]
    return (p - c) / np.linalg.norm(p - c)


def drape(root, heading, length, n_ctrl, clearance=0.012, fall=4.0, ds=0.002, turn=None):
    """
    Return n_ctrl control points along a hair draped from `root` towards `heading`.

    turn: (arc length, new heading): past that arc length the hair swings to the new
    heading (a parting's sweep); gravity takes over as the hair gets longer.
    """
    p = snap_to_scalp(HEAD, np.array([root], dtype=float))[0]
    t = np.asarray(heading, dtype=float)
    path = [p.copy()]
    s = 0.0
    spheres = HEAD.collision
    down = np.array([0.0, 0.0, -1.0])
    while s < length:
        n = scalp_normal(p)
        if turn is not None and s > turn[0]:
            t = t + 0.08 * (np.asarray(turn[1], float) - t)
        w = fall * s                              # gravity wins as the hair gets longer
        t = t - np.dot(t, n) * n * (1.0 if p[2] > -0.02 else 0.0)
        t = t / np.linalg.norm(t) + w * ds * 60 * down
        t /= np.linalg.norm(t)
        p = p + ds * t
        lift = clearance * min(1.0, (s + ds) / 0.006)
        for _ in range(3):                        # keep clear of every collision sphere
            rel = p - spheres[:, :3]
            dist = np.linalg.norm(rel, axis=1)
            gap = dist - spheres[:, 3] - lift
            k = np.argmin(gap)
            if gap[k] >= 0:
                break
            p = spheres[k, :3] + rel[k] / dist[k] * (spheres[k, 3] + lift)
        s += ds
        path.append(p.copy())
    path = np.array(path)
    seg = np.linalg.norm(np.diff(path, axis=0), axis=1)
    arc = np.concatenate([[0.0], np.cumsum(seg)])
    targets = np.linspace(0.0, arc[-1], n_ctrl)
    pts = np.array([[np.interp(a, arc, path[:, k]) for k in range(3)] for a in targets])
    pts[0] = path[0]
    return pts


def on_scalp(direction):
    """Point of the scalp boundary seen from the head centre in `direction`."""
    d = np.asarray(direction, dtype=float)
    d /= np.linalg.norm(d)
    return snap_to_scalp(HEAD, (np.array([0.0, 0.0, 0.02]) + 0.2 * d)[None])[0]


def crown_ring(angles_deg, length, n_ctrl, ring=0.35, crown=(-0.35, 0.0, 1.0), sweep=None,
               front_clearance=None, **kw):
    """
    Return control hairs on a ring around the crown, each heading away from it.

    sweep: above this azimuth (deg) the heading turns sideways, off the face.
    front_clearance: the volume grows from `clearance` at the back to this at the front.
    """
    c = np.asarray(crown, float)
    c /= np.linalg.norm(c)
    e1 = np.cross(c, [0.0, 1.0, 0.0])
    e1 /= np.linalg.norm(e1)                        # towards the back at azimuth 0
    e1 = -e1 if e1[0] > 0 else e1
    e2 = np.cross(c, e1)
    hairs = []
    for a in np.radians(angles_deg):
        radial = np.cos(a) * e1 + np.sin(a) * e2
        root = on_scalp(c * np.cos(ring) + radial * np.sin(ring))
        turn = None
        if sweep is not None and abs(a) > np.radians(sweep):
            # front hairs: over the top first, then swept to their side, off the face
            f = (abs(a) - np.radians(sweep)) / (np.pi - np.radians(sweep))
            turn = (0.1 + 0.02 * f, np.array([-0.2, -np.sign(a), 0.0]))
        args = dict(kw)
        if front_clearance is not None:
            back = kw.get('clearance', 0.012)
            args['clearance'] = back + (front_clearance - back) * (abs(a) / np.pi) ** 2
        hairs.append(drape(root, radial, length, n_ctrl, turn=turn, **args))
    return hairs


def line_hairs(start_dir, end_dir, n, heading, length, n_ctrl, **kw):
    """Control hairs with roots along a scalp arc, all heading one way."""
    hairs = []
    for f in np.linspace(0.0, 1.0, n):
        d = (1 - f) * np.asarray(start_dir, float) + f * np.asarray(end_dir, float)
        h = heading(f) if callable(heading) else heading
        hairs.append(drape(on_scalp(d), h, length, n_ctrl, **kw))
    return hairs


def patch(name, hairs, strips, degree=(3, 3)):
    """Return a patch mapping for the YAML file."""
    return {'name': name, 'degree': list(degree), 'strips': strips,
            'control_hairs': [[[round(float(x), 6) for x in p] for p in h] for h in hairs]}


def style(name, patches, vertices=10, rows=30, cols=3, color=(0.30, 0.19, 0.11), seed=1):
    """Return a style mapping for the YAML file."""
    return {'name': name, 'head': 'default_adult',
            'lod': {'vertices': vertices, 'render_rows': rows, 'render_columns': cols},
            'material': {'color': list(color),
                         'texture': {'width': 64, 'height': 256, 'streaks': 40, 'seed': seed,
                                     'edge_fade': 0.12, 'tip_fade': 0.1}},
            'patches': patches}


def shorten(long_style, factor):
    """Derive a short style by moving control points along each control hair (6.1)."""
    out = long_style
    for pi, p in enumerate(long_style.patches):
        for h in range(p.n_hairs):
            pts = p.points[h]
            arc = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(pts, axis=0),
                                                                  axis=1))])
            for k in range(2, p.n_points):    # keep the root and the lift-off point
                a = arc[1] + factor * (arc[k] - arc[1])
                new = np.array([np.interp(a, arc, pts[:, c]) for c in range(3)])
                out = out.with_control_point(pi, h, k, np.round(new, 6))
    return out


# control hair azimuths around the crown (0 = back): denser at the back, where long hair
# hangs and most of it is
WHORL = 179.5 * np.sign(np.linspace(-1, 1, 16)) * np.abs(np.linspace(-1, 1, 16)) ** 1.5


def main():
    """Write the four shipped styles."""
    n = 7
    long_d = style('thesis_long', [
        patch('crown', crown_ring(WHORL, 0.30, n, ring=0.07, sweep=110, clearance=0.019,
                                  front_clearance=0.028), 46),
    ])
    long_style = hairstyle_from_dict(long_d, os.path.join(OUT, 'thesis_long.yaml'))
    save_hairstyle(long_style, os.path.join(OUT, 'thesis_long.yaml'))
    short = shorten(long_style, 0.42)
    short = short.derive('thesis_short')
    save_hairstyle(short, os.path.join(OUT, 'thesis_short.yaml'))
    bob = style('bob_fringe', [
        patch('crown', crown_ring(np.linspace(-135, 135, 11), 0.17, 6, fall=3.0), 28),
        patch('fringe', line_hairs((0.55, 0.75, 0.8), (0.55, -0.75, 0.8), 7,
                                   (1.0, 0.0, -0.2), 0.085, 5, fall=2.0), 14),
    ], color=(0.08, 0.06, 0.05), seed=2)
    save_hairstyle(hairstyle_from_dict(bob, os.path.join(OUT, 'bob_fringe.yaml')),
                   os.path.join(OUT, 'bob_fringe.yaml'))
    side = style('side_swept_long', [
        patch('sweep', line_hairs((0.75, 0.3, 0.7), (-0.35, 0.3, 1.0), 6,
                                  lambda f: (0.35 - 0.5 * f, -1.0, 0.0), 0.34, n), 24),
        patch('part_left', line_hairs((0.75, 0.36, 0.7), (-0.35, 0.36, 1.0), 4,
                                      (-0.2, 1.0, 0.0), 0.30, n), 8),
        patch('back', crown_ring(np.linspace(-95, 95, 8), 0.32, n, crown=(-0.45, 0.25, 1.0)),
              16),
    ], vertices=10, color=(0.55, 0.38, 0.2), seed=3)
    save_hairstyle(hairstyle_from_dict(side, os.path.join(OUT, 'side_swept_long.yaml')),
                   os.path.join(OUT, 'side_swept_long.yaml'))


if __name__ == '__main__':
    main()
