"""
Hairstyle files: schema, validation, loading, editing and atomic saving (thesis ch. 6).

A hairstyle is one or more patches; each patch is an ordered list of control hairs with the
same number of control points (thesis 6.1), in the head frame, root first. The automatic
step (6.2) lives in `strips.py`.

Every route into a style (a file, an edit, a derived copy) goes through
`hairstyle_from_dict`, so the same checks and bounds hold for all of them and a saved
style always loads back.
"""

import copy
from dataclasses import dataclass, field, replace
import os

import numpy as np

from hair_sim import budget, paths
from hair_sim.modeling import fields
from hair_sim.modeling.errors import HairstyleError
from hair_sim.modeling.head import HeadModel, load_head
from hair_sim.modeling.nurbs import check_knots, clamped_uniform_knots
from hair_sim.modeling.yamlio import read_yaml, write_yaml_atomic

# Structural bounds; what a machine runs at rate is the budget (hair_sim.budget).
LIMITS = {
    'patches': 32, 'control_hairs': 256, 'control_points': 64, 'degree': 5,
    'strips': 2000, 'vertices': 64, 'render_rows': 256, 'render_columns': 16,
    'total_control_points': 16384,
}
MAX_REACH = 2.0                     # m: no control point farther than this from the head origin
DEFAULT_ROOT_TOLERANCE = 0.005      # m: control hair roots must be this close to the scalp
DEFAULT_MATERIAL = {
    'color': [0.30, 0.19, 0.11],     # dark brown, linear RGB
    'texture': {'width': 64, 'height': 256, 'streaks': 40, 'seed': 1,
                'edge_fade': 0.12, 'tip_fade': 0.1},
}
# material.texture fields: (kind, low, high)
TEXTURE_FIELDS = {
    'width': (int, 4, 512), 'height': (int, 4, 1024), 'streaks': (int, 0, 400),
    'seed': (int, 0, 2 ** 32 - 1), 'edge_fade': (float, 0.0, 0.5), 'tip_fade': (float, 0.0, 1.0),
}
STYLE_KEYS = {'name', 'head', 'lod', 'material', 'patches', 'root_tolerance'}
PATCH_KEYS = {'name', 'degree', 'strips', 'control_hairs', 'weights', 'knots_across',
              'knots_along'}


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

    @property
    def simulated_vertices(self):
        """Return the vertices the solver steps: two strands per strip."""
        return 2 * self.n_strips * self.vertices

    @property
    def drawn_vertices(self):
        """Return the vertices of the U-shape mesh: (columns + 4) x rows per strip."""
        return self.n_strips * (self.render_columns + 4) * self.render_rows

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
        """
        Return a new style with one control point moved (thesis 6.1); self is unchanged.

        The edited style is rebuilt from its mapping by the same checks as a file, so the
        same bounds hold and a saved edit loads back.
        """
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
        where = 'edit of patch %r control hair %d point %d' % (p.name, hair, point)
        try:
            pos = np.array(position, dtype=np.float64)
        except (TypeError, ValueError, OverflowError):
            pos = None
        if pos is None or pos.shape != (3,) or not np.all(np.isfinite(pos)):
            raise HairstyleError('%s: the new position must be 3 finite numbers' % where)
        if np.abs(pos).max() > MAX_REACH:
            raise HairstyleError('%s: the new position is over %g m from the head origin'
                                 % (where, MAX_REACH))
        data = self.to_dict()
        data['patches'][patch]['control_hairs'][hair][point] = [float(x) for x in pos]
        return hairstyle_from_dict(data, head=self.head, where=where)

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


def head_roots(search_dirs):
    """Return the real directories head files may come from: the style dirs and the shipped."""
    from hair_sim.modeling.safepath import allowed_dirs
    return allowed_dirs(search_dirs) + [os.path.realpath(paths.heads_dir())]


def _inside(real, root):
    return os.path.commonpath([real, root]) == root


def _resolve_head(ref, style_path, search_dirs=None):
    """
    Find the head file a style names.

    A name ('default_adult') is looked up as heads/<name>.yaml next to the style's
    directory or inside it, then among the shipped heads; a path ending in .yaml is taken
    relative to the style's directory. With `search_dirs` (the node's hairstyle_dirs) a
    candidate counts only if its real path lies inside one of them or the shipped heads
    directory; candidates elsewhere are not even looked at, and the message names none.
    """
    base = os.path.dirname(style_path) if style_path else os.getcwd()
    if ref.endswith('.yaml'):
        candidates = [ref if os.path.isabs(ref) else os.path.join(base, ref)]
    elif '/' in ref or '\\' in ref or ref.startswith('.'):
        raise HairstyleError('head %r: a head is a name or a path ending in .yaml' % ref)
    else:
        candidates = [os.path.join(base, '..', 'heads', ref + '.yaml'),
                      os.path.join(base, 'heads', ref + '.yaml'),
                      os.path.join(paths.heads_dir(), ref + '.yaml')]
    roots = head_roots(search_dirs) if search_dirs is not None else None
    for c in candidates:
        real = os.path.realpath(c)
        if roots is not None and not any(_inside(real, r) for r in roots):
            continue
        if os.path.isfile(real):
            return load_head(real)
    if roots is None:
        raise HairstyleError('head %r not found (looked in %s)' % (ref, ', '.join(
            os.path.normpath(c) for c in candidates)))
    # the same answer whether a file outside exists or not, and no path of it
    raise HairstyleError('head %r not found in the hairstyle directories or the shipped '
                         'heads' % os.path.basename(ref))


def _parse_control_hairs(hairs, pw):
    """Return the (hairs, points, 3) control points of a patch, checked hair by hair."""
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
        if not isinstance(hair, list) or not all(isinstance(pt, list) for pt in hair):
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
    rows = []
    for h, hair in enumerate(hairs):
        where = '%s: control hair %d' % (pw, h)
        if not all(fields._real(x) for pt in hair for x in pt):
            raise HairstyleError('%s has a non-numeric coordinate' % where)
        if any(isinstance(x, int) and not -MAX_REACH <= x <= MAX_REACH
               for pt in hair for x in pt):
            raise HairstyleError('%s has a point over %g m from the head origin'
                                 % (where, MAX_REACH))
        arr = np.array(hair, dtype=np.float64)
        if not np.all(np.isfinite(arr)):
            raise HairstyleError('%s has a non-finite coordinate (NaN or inf)' % where)
        if np.abs(arr).max() > MAX_REACH:
            raise HairstyleError('%s has a point over %g m from the head origin'
                                 % (where, MAX_REACH))
        rows.append(arr)
    return np.array(rows)


def _parse_patch(i, d, where):
    if not isinstance(d, dict):
        raise HairstyleError('%s: patch #%d must be a mapping' % (where, i))
    name = fields.string(d.get('name', 'patch%d' % i), 'patch #%d name' % i, where, 64)
    pw = "%s: patch %r (#%d)" % (where, name, i)
    fields.require_mapping(d, 'the patch', pw, PATCH_KEYS)
    points = _parse_control_hairs(d.get('control_hairs'), pw)
    deg = d.get('degree', [3, 3])
    if isinstance(deg, int) and not isinstance(deg, bool):
        deg = [deg, deg]
    if not isinstance(deg, list) or len(deg) != 2:
        raise HairstyleError('%s: degree must be an integer or [across, along]' % pw)
    du = fields.integer(deg[0], 'degree across', 1, LIMITS['degree'], pw)
    dv = fields.integer(deg[1], 'degree along', 1, LIMITS['degree'], pw)
    explicit = {}
    if 'weights' in d:
        w = fields.numeric_array(d['weights'], 'weights', pw, 2, 1e6)
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
            k = fields.numeric_array(d[key], key, pw, 1, 1e6)
            why = check_knots(k, n, p)
            if why is None and (k[-1] - k[0]) <= 1e-9 * max(1.0, abs(k[0]), abs(k[-1])):
                why = 'has (nearly) zero length'
            if why:
                raise HairstyleError('%s: %s %s' % (pw, key, why))
            knots[attr] = (k - k[0]) / (k[-1] - k[0])
            explicit[attr] = True
        else:
            if n <= p:
                continue
            knots[attr] = clamped_uniform_knots(n, p)
    strips = fields.integer(d.get('strips', max(2, points.shape[0])), 'strips', 1,
                            LIMITS['strips'], pw)
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
        if not np.all(np.isfinite(p.points)) or np.abs(p.points).max() > MAX_REACH:
            raise HairstyleError('%s: a control point is not finite or over %g m from the '
                                 'head origin' % (pw, MAX_REACH))
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


def budget_problem(style, sim_rate=budget.DEFAULT_SIM_RATE,
                   publish_rate=budget.DEFAULT_PUBLISH_RATE, model='anjyo'):
    """Return why `style` would not run at these rates on one core (see budget), or None."""
    why = budget.budget_problem(style.simulated_vertices, style.drawn_vertices, sim_rate,
                                publish_rate, model)
    return None if why is None else 'hairstyle %r (%d strips x %d vertices, drawn %d x %d): ' \
        '%s' % (style.name, style.n_strips, style.vertices, style.render_rows,
                style.render_columns, why)


def _parse_material(given, where):
    material = copy.deepcopy(DEFAULT_MATERIAL)
    fields.require_mapping(given, 'material', where, {'color', 'texture'})
    if 'color' in given:
        c = fields.numeric_array(given['color'], 'material.color', where, 1, 1.0, (3,))
        if np.any(c < 0):
            raise HairstyleError('%s: material.color must be 3 numbers in [0, 1]' % where)
        material['color'] = [float(x) for x in c]
    if 'texture' in given:
        tex = fields.require_mapping(given['texture'], 'material.texture', where,
                                     set(TEXTURE_FIELDS))
        for k, v in tex.items():
            kind, lo, hi = TEXTURE_FIELDS[k]
            check = fields.integer if kind is int else fields.number
            material['texture'][k] = check(v, 'material.texture.%s' % k, lo, hi, where)
    return material


def hairstyle_from_dict(data, path='', head=None, search_dirs=None, where=None):
    """
    Build and validate a Hairstyle from its YAML mapping; path only names it in errors.

    head: use this HeadModel instead of resolving the file's `head` (edits keep theirs);
    search_dirs: confine the head file to these hairstyle directories (see _resolve_head).
    """
    where = where or ('hairstyle file %s' % path if path else 'hairstyle')
    if not isinstance(data, dict):
        raise HairstyleError('%s: the top level must be a mapping' % where)
    unknown = [k for k in data if k not in STYLE_KEYS]
    if unknown:
        raise HairstyleError('%s: unknown key(s) %s' % (where, ', '.join(
            str(k)[:30] for k in unknown[:5])))
    if 'patches' not in data:
        raise HairstyleError('%s: missing "patches"' % where)
    if not isinstance(data['patches'], list) or not data['patches']:
        raise HairstyleError('%s: "patches" must be a non-empty list' % where)
    if len(data['patches']) > LIMITS['patches']:
        raise HairstyleError('%s: %d patches is over the limit of %d'
                             % (where, len(data['patches']), LIMITS['patches']))
    total = sum(len(h) for p in data['patches'] if isinstance(p, dict)
                and isinstance(p.get('control_hairs'), list) for h in p['control_hairs']
                if isinstance(h, list))
    if total > LIMITS['total_control_points']:
        raise HairstyleError('%s: %d control points in all is over the limit of %d'
                             % (where, total, LIMITS['total_control_points']))
    name = fields.string(data.get('name', 'unnamed'), 'name', where, 64)
    head_ref = fields.string(data.get('head', 'default_adult'), 'head', where, 200)
    lod = fields.require_mapping(data.get('lod', {}), 'lod', where,
                                 {'vertices', 'render_rows', 'render_columns'})
    vertices = fields.integer(lod.get('vertices', 10), 'lod.vertices', 2, LIMITS['vertices'],
                              where)
    rows = fields.integer(lod.get('render_rows', 3 * vertices), 'lod.render_rows', 2,
                          LIMITS['render_rows'], where)
    cols = fields.integer(lod.get('render_columns', 2), 'lod.render_columns', 2,
                          LIMITS['render_columns'], where)
    if rows < vertices:
        raise HairstyleError('%s: lod.render_rows (%d) must be at least lod.vertices (%d)'
                             % (where, rows, vertices))
    material = _parse_material(data.get('material', {}), where)
    tol = fields.number(data.get('root_tolerance', DEFAULT_ROOT_TOLERANCE), 'root_tolerance',
                        1e-6, 0.05, where)
    patches = [_parse_patch(i, p, where) for i, p in enumerate(data['patches'])]
    if head is None:
        try:
            head = _resolve_head(head_ref, path, search_dirs)
        except HairstyleError as exc:
            raise HairstyleError('%s: %s' % (where, exc)) from None
    style = Hairstyle(name=name, head_ref=head_ref, head=head, patches=patches,
                      vertices=vertices, render_rows=rows, render_columns=cols,
                      material=material, root_tolerance=tol,
                      path=os.path.abspath(path) if path else '')
    return validate(style, where)


def load_hairstyle(path, search_dirs=None):
    """
    Load and validate a hairstyle file; raise HairstyleError (naming the file) if bad.

    search_dirs: when given (the node's hairstyle_dirs), the style's head file must lie
    inside one of them or among the shipped heads.
    """
    path = os.path.abspath(path)
    return hairstyle_from_dict(read_yaml(path, 'hairstyle'), path, search_dirs=search_dirs)


def save_hairstyle(style, path):
    """
    Write `style` to `path` atomically (temporary file, fsync, rename).

    A write that fails (a full disk, a folder without write permission) raises an OSError
    with its errno that names the path and says that the file there is as it was.
    """
    validate(style)
    try:
        write_yaml_atomic(path, style.to_dict())
    except OSError as exc:
        left = 'the file there is unchanged' if os.path.exists(path) else 'nothing written'
        raise OSError(exc.errno, 'could not write %s: %s; %s'
                      % (path, exc.strerror or exc, left)) from exc
    return path
