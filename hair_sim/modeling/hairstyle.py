"""
Hairstyle files: schema, validation, loading, editing and atomic saving (thesis ch. 6).

A hairstyle is one or more patches; each patch is an ordered list of control hairs with the
same number of control points (thesis 6.1), in the head frame, root first. The automatic
step (6.2) lives in `strips.py`.
"""

import copy
from dataclasses import dataclass, field, replace
import os

import numpy as np

from hair_sim import paths
from hair_sim.modeling.errors import HairstyleError
from hair_sim.modeling.head import HeadModel, load_head
from hair_sim.modeling.nurbs import check_knots, clamped_uniform_knots
from hair_sim.modeling.yamlio import read_yaml, write_yaml_atomic

# Bounds that keep a style real-time and a file from asking for absurd work.
LIMITS = {
    'patches': 32, 'control_hairs': 256, 'control_points': 64, 'degree': 5,
    'strips': 4000, 'vertices': 64, 'render_rows': 256, 'render_columns': 16,
}
DEFAULT_ROOT_TOLERANCE = 0.005      # m: control hair roots must be this close to the scalp
DEFAULT_MATERIAL = {
    'color': [0.30, 0.19, 0.11],     # dark brown, linear RGB
    'texture': {'width': 64, 'height': 256, 'streaks': 40, 'seed': 1,
                'edge_fade': 0.12, 'tip_fade': 0.1},
}


@dataclass
class Patch:
    """One NURBS patch: control hairs across (u), control points along (v)."""

    name: str
    points: np.ndarray          # (n_hairs, n_points, 3) head frame, root first
    weights: np.ndarray         # (n_hairs, n_points)
    degree_u: int               # across the control hairs
    degree_v: int               # along a control hair
    knots_u: np.ndarray
    knots_v: np.ndarray
    strips: int                 # physics LOD: strips simulated in this patch
    explicit: dict = field(default_factory=dict)   # which optional keys the file gave

    @property
    def n_hairs(self):
        """Return the number of control hairs."""
        return self.points.shape[0]

    @property
    def n_points(self):
        """Return the number of control points on each control hair."""
        return self.points.shape[1]


@dataclass
class Hairstyle:
    """A validated hairstyle with its head model."""

    name: str
    head_ref: str
    head: HeadModel
    patches: list
    vertices: int               # physics LOD: simulated vertices per strand
    render_rows: int            # render LOD: rows drawn per strip (root to tip)
    render_columns: int         # render LOD: columns drawn per strip (across, >= 2)
    material: dict
    root_tolerance: float = DEFAULT_ROOT_TOLERANCE
    path: str = ''

    @property
    def n_strips(self):
        """Return the number of strips simulated (physics LOD)."""
        return sum(p.strips for p in self.patches)

    def to_dict(self):
        """Return the YAML mapping of this style; load(save(style)) gives it back exactly."""
        out = {'name': self.name, 'head': self.head_ref,
               'lod': {'vertices': self.vertices, 'render_rows': self.render_rows,
                       'render_columns': self.render_columns},
               'root_tolerance': float(self.root_tolerance),
               'material': _plain(self.material), 'patches': []}
        for p in self.patches:
            d = {'name': p.name, 'degree': [p.degree_u, p.degree_v], 'strips': p.strips,
                 'control_hairs': [[[float(x) for x in pt] for pt in hair] for hair in p.points]}
            if p.explicit.get('weights'):
                d['weights'] = [[float(w) for w in row] for row in p.weights]
            if p.explicit.get('knots_u'):
                d['knots_across'] = [float(k) for k in p.knots_u]
            if p.explicit.get('knots_v'):
                d['knots_along'] = [float(k) for k in p.knots_v]
            out['patches'].append(d)
        return out

    def with_control_point(self, patch, hair, point, position):
        """Return a new style with one control point moved (thesis 6.1); self is unchanged."""
        if not 0 <= patch < len(self.patches):
            raise HairstyleError('edit: no patch %d (the style has %d)'
                                 % (patch, len(self.patches)))
        p = self.patches[patch]
        if not 0 <= hair < p.n_hairs:
            raise HairstyleError('edit: patch %r has no control hair %d (it has %d)'
                                 % (p.name, hair, p.n_hairs))
        if not 0 <= point < p.n_points:
            raise HairstyleError('edit: control hair %d of patch %r has no control point %d '
                                 '(it has %d)' % (hair, p.name, point, p.n_points))
        pos = np.asarray(position, dtype=np.float64)
        if pos.shape != (3,) or not np.all(np.isfinite(pos)):
            raise HairstyleError('edit: the new position must be 3 finite numbers')
        pts = p.points.copy()
        pts[hair, point] = pos
        patches = list(self.patches)
        patches[patch] = replace(p, points=pts)
        new = replace(self, patches=patches)
        validate(new, where='edit of patch %r control hair %d point %d' % (p.name, hair, point))
        return new

    def derive(self, name, **changes):
        """Return a copy renamed `name` with dataclass fields replaced (e.g. vertices=12)."""
        new = replace(self, name=name, path='', **changes)
        validate(new, where='derived style %r' % name)
        return new

    def with_strip_count(self, total):
        """Return a copy whose patches share `total` strips in proportion (physics LOD)."""
        cur = np.array([p.strips for p in self.patches], dtype=np.float64)
        want = np.maximum(1, np.round(cur / cur.sum() * total)).astype(int)
        want[np.argmax(want)] += total - want.sum()
        patches = [replace(p, strips=int(max(s, (p.n_hairs + 1) // 2)))
                   for p, s in zip(self.patches, want)]
        return self.derive('%s_%d' % (self.name, total), patches=patches)


def _plain(obj):
    """Convert numpy scalars/arrays inside obj to plain Python for YAML."""
    if isinstance(obj, dict):
        return {str(k): _plain(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple, np.ndarray)):
        return [_plain(v) for v in obj]
    if isinstance(obj, (np.floating, float)):
        return float(obj)
    if isinstance(obj, (np.integer, int)) and not isinstance(obj, bool):
        return int(obj)
    return obj


def _int(value, name, lo, hi, where):
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise HairstyleError('%s: %s must be a whole number, not %r' % (where, name, value))
    if not lo <= value <= hi:
        raise HairstyleError('%s: %s = %d is outside [%d, %d]' % (where, name, value, lo, hi))
    return int(value)


def _array(value, name, where, shape_hint):
    try:
        arr = np.array(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise HairstyleError('%s: %s must be %s of numbers' % (where, name, shape_hint))
    if not np.all(np.isfinite(arr)):
        raise HairstyleError('%s: %s contains a non-finite number (NaN or inf)' % (where, name))
    return arr


def _resolve_head(ref, style_path):
    ref = str(ref)
    candidates = []
    base = os.path.dirname(style_path) if style_path else os.getcwd()
    if ref.endswith('.yaml'):
        candidates.append(ref if os.path.isabs(ref) else os.path.join(base, ref))
    else:
        candidates += [os.path.join(base, '..', 'heads', ref + '.yaml'),
                       os.path.join(paths.heads_dir(), ref + '.yaml')]
    for c in candidates:
        if os.path.isfile(c):
            return load_head(c)
    raise HairstyleError('head %r not found (looked in %s)' % (ref, ', '.join(
        os.path.normpath(c) for c in candidates)))


def _parse_patch(i, d, where):
    if not isinstance(d, dict):
        raise HairstyleError('%s: patch #%d must be a mapping' % (where, i))
    name = str(d.get('name', 'patch%d' % i))
    pw = "%s: patch %r (#%d)" % (where, name, i)
    hairs = d.get('control_hairs')
    if not isinstance(hairs, list):
        raise HairstyleError('%s: "control_hairs" must be a list of control hairs' % pw)
    if len(hairs) < 2:
        raise HairstyleError('%s: has %d control hair(s); a patch needs at least 2'
                             % (pw, len(hairs)))
    if len(hairs) > LIMITS['control_hairs']:
        raise HairstyleError('%s: %d control hairs is over the limit of %d'
                             % (pw, len(hairs), LIMITS['control_hairs']))
    counts = []
    for h, hair in enumerate(hairs):
        if not isinstance(hair, list) or not all(isinstance(pt, (list, tuple)) for pt in hair):
            raise HairstyleError('%s: control hair %d must be a list of [x, y, z] points'
                                 % (pw, h))
        for k, pt in enumerate(hair):
            if len(pt) != 3:
                raise HairstyleError('%s: control hair %d point %d has %d coordinates, not 3'
                                     % (pw, h, k, len(pt)))
        counts.append(len(hair))
    for h, c in enumerate(counts):
        if c != counts[0]:
            raise HairstyleError(
                '%s: control hair %d has %d control points but control hair 0 has %d; all '
                'control hairs of a patch must have the same number (thesis 6.1)'
                % (pw, h, c, counts[0]))
    if counts[0] < 2 or counts[0] > LIMITS['control_points']:
        raise HairstyleError('%s: control hairs need 2 to %d control points, have %d'
                             % (pw, LIMITS['control_points'], counts[0]))
    for h, hair in enumerate(hairs):
        try:
            arr = np.array(hair, dtype=np.float64)
        except (TypeError, ValueError):
            raise HairstyleError('%s: control hair %d has a non-numeric coordinate' % (pw, h))
        if not np.all(np.isfinite(arr)):
            raise HairstyleError('%s: control hair %d has a non-finite coordinate (NaN or inf)'
                                 % (pw, h))
        if np.abs(arr).max() > 5.0:
            raise HairstyleError('%s: control hair %d has a point over 5 m from the head'
                                 % (pw, h))
    points = np.array(hairs, dtype=np.float64)
    deg = d.get('degree', [3, 3])
    if isinstance(deg, (int, np.integer)) and not isinstance(deg, bool):
        deg = [deg, deg]
    if not isinstance(deg, list) or len(deg) != 2:
        raise HairstyleError('%s: degree must be an integer or [across, along]' % pw)
    du = _int(deg[0], 'degree across', 1, LIMITS['degree'], pw)
    dv = _int(deg[1], 'degree along', 1, LIMITS['degree'], pw)
    explicit = {}
    if 'weights' in d:
        w = _array(d['weights'], 'weights', pw, 'one list per control hair')
        if w.shape != points.shape[:2]:
            raise HairstyleError('%s: weights must have one value per control point, shape '
                                 '%s, not %s' % (pw, points.shape[:2], w.shape))
        if np.any(w <= 0):
            raise HairstyleError('%s: weights must be positive' % pw)
        explicit['weights'] = True
    else:
        w = np.ones(points.shape[:2])
    knots = {}
    for key, attr, n, p in (('knots_across', 'knots_u', points.shape[0], du),
                            ('knots_along', 'knots_v', points.shape[1], dv)):
        if key in d:
            k = _array(d[key], key, pw, 'a list')
            why = check_knots(k, n, p) if k.ndim == 1 else 'must be a flat list'
            if why:
                raise HairstyleError('%s: %s %s' % (pw, key, why))
            knots[attr] = (k - k[0]) / (k[-1] - k[0])
            explicit[attr] = True
        else:
            if n <= p:
                continue
            knots[attr] = clamped_uniform_knots(n, p)
    strips = _int(d.get('strips', max(2, points.shape[0])), 'strips', 1, LIMITS['strips'], pw)
    return Patch(name=name, points=points, weights=w, degree_u=du, degree_v=dv,
                 knots_u=knots.get('knots_u'), knots_v=knots.get('knots_v'), strips=strips,
                 explicit=explicit)


def validate(style, where=None):
    """Check the cross-field rules of a style; raise HairstyleError naming what is wrong."""
    where = where or 'hairstyle %s' % (style.path or style.name)
    if not style.patches:
        raise HairstyleError('%s: has no patches' % where)
    for i, p in enumerate(style.patches):
        pw = '%s: patch %r (#%d)' % (where, p.name, i)
        if p.degree_v >= p.n_points:
            raise HairstyleError('%s: degree along (%d) must be below the number of control '
                                 'points per hair (%d)' % (pw, p.degree_v, p.n_points))
        if p.degree_u >= p.n_hairs:
            raise HairstyleError('%s: degree across (%d) must be below the number of control '
                                 'hairs (%d)' % (pw, p.degree_u, p.n_hairs))
        if 2 * p.strips < p.n_hairs:
            raise HairstyleError('%s: %d strips give %d columns, fewer than its %d control '
                                 'hairs; knot insertion can only add columns'
                                 % (pw, p.strips, 2 * p.strips, p.n_hairs))
        if style.vertices < p.n_points:
            raise HairstyleError('%s: lod.vertices (%d) is below the %d control points per '
                                 'hair; knot insertion can only add points'
                                 % (pw, style.vertices, p.n_points))
        if not np.all(np.isfinite(p.points)):
            raise HairstyleError('%s: a control point is not finite' % pw)
        dist = style.head.scalp_distance(p.points[:, 0])
        bad = np.flatnonzero(np.abs(dist) > style.root_tolerance)
        if bad.size:
            h = int(bad[0])
            raise HairstyleError(
                '%s: control hair %d root is %.1f mm %s the scalp; roots must be within '
                '%.1f mm of it' % (pw, h, abs(dist[h]) * 1e3,
                                   'inside' if dist[h] < 0 else 'away from',
                                   style.root_tolerance * 1e3))
    if style.n_strips > LIMITS['strips']:
        raise HairstyleError('%s: %d strips in all is over the limit of %d'
                             % (where, style.n_strips, LIMITS['strips']))
    return style


def hairstyle_from_dict(data, path='', head=None):
    """Build and validate a Hairstyle from its YAML mapping; path only names it in errors."""
    where = 'hairstyle file %s' % path if path else 'hairstyle'
    if not isinstance(data, dict):
        raise HairstyleError('%s: the top level must be a mapping' % where)
    unknown = set(data) - {'name', 'head', 'lod', 'material', 'patches', 'root_tolerance'}
    if unknown:
        raise HairstyleError('%s: unknown key(s) %s' % (where, ', '.join(sorted(unknown))))
    if 'patches' not in data:
        raise HairstyleError('%s: missing "patches"' % where)
    if not isinstance(data['patches'], list) or not data['patches']:
        raise HairstyleError('%s: "patches" must be a non-empty list' % where)
    if len(data['patches']) > LIMITS['patches']:
        raise HairstyleError('%s: %d patches is over the limit of %d'
                             % (where, len(data['patches']), LIMITS['patches']))
    head_ref = data.get('head', 'default_adult')
    if head is None:
        try:
            head = _resolve_head(head_ref, path)
        except HairstyleError as exc:
            raise HairstyleError('%s: %s' % (where, exc))
    lod = data.get('lod', {})
    if not isinstance(lod, dict):
        raise HairstyleError('%s: "lod" must be a mapping' % where)
    vertices = _int(lod.get('vertices', 10), 'lod.vertices', 2, LIMITS['vertices'], where)
    rows = _int(lod.get('render_rows', 3 * vertices), 'lod.render_rows', 2,
                LIMITS['render_rows'], where)
    cols = _int(lod.get('render_columns', 2), 'lod.render_columns', 2,
                LIMITS['render_columns'], where)
    if rows < vertices:
        raise HairstyleError('%s: lod.render_rows (%d) must be at least lod.vertices (%d)'
                             % (where, rows, vertices))
    material = copy.deepcopy(DEFAULT_MATERIAL)
    given = data.get('material', {})
    if not isinstance(given, dict):
        raise HairstyleError('%s: "material" must be a mapping' % where)
    if 'color' in given:
        c = _array(given['color'], 'material.color', where, '3')
        if c.shape != (3,) or np.any(c < 0) or np.any(c > 1):
            raise HairstyleError('%s: material.color must be 3 numbers in [0, 1]' % where)
        material['color'] = [float(x) for x in c]
    if 'texture' in given:
        if not isinstance(given['texture'], dict):
            raise HairstyleError('%s: material.texture must be a mapping' % where)
        for k, v in given['texture'].items():
            if k not in material['texture']:
                raise HairstyleError('%s: unknown material.texture key %r' % (where, k))
            material['texture'][k] = v
    tol = data.get('root_tolerance', DEFAULT_ROOT_TOLERANCE)
    if isinstance(tol, bool) or not isinstance(tol, (int, float)) or not 0 < tol <= 0.05:
        raise HairstyleError('%s: root_tolerance must be a number in (0, 0.05] m' % where)
    patches = [_parse_patch(i, p, where) for i, p in enumerate(data['patches'])]
    style = Hairstyle(name=str(data.get('name', 'unnamed')), head_ref=str(head_ref), head=head,
                      patches=patches, vertices=vertices, render_rows=rows,
                      render_columns=cols, material=material, root_tolerance=float(tol),
                      path=os.path.abspath(path) if path else '')
    return validate(style, where)


def load_hairstyle(path):
    """Load and validate a hairstyle file; raise HairstyleError (naming the file) if bad."""
    path = os.path.abspath(path)
    return hairstyle_from_dict(read_yaml(path, 'hairstyle'), path)


def save_hairstyle(style, path):
    """Write `style` to `path` atomically (temporary file, fsync, rename)."""
    validate(style)
    write_yaml_atomic(path, style.to_dict())
    return path
