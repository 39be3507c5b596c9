"""
Fit collision spheres inside a head mesh: bring your own avatar's head.

    hair_sim_head fit MESH [--spheres N] [--out HEAD.yaml]

The mesh (OBJ, GLB/glTF, STL, PLY: whatever trimesh reads) is in the head frame (x forward,
y left, z up, metres; `--axes` and `--scale` map other conventions onto it). Steps:

1. voxelize the surface; flood the outside from the grid's sides and top (an open cut at
   the bottom, such as cropped shoulders, is closed by the grid's floor); close small holes
   (eyes, nostrils) by a morphological closing of the outside; the rest is the inside;
2. a Euclidean distance transform of the inside gives every inside voxel its inscribed
   radius; the candidates are the voxels on the medial ridge (local maxima of the radius);
3. each candidate's radius is made exact against the triangles (distance from its centre to
   the surface, less a margin), so every sphere lies inside the mesh;
4. greedy cover: with the surface sampled by area, pick the candidate that most reduces the
   clipped surface-to-union distance (above the chin, where hair can reach, counted more),
   until N spheres;
5. the spheres whose centres lie above the eye line are the scalp (thesis 3.1: roots sit on
   their union), the others are body spheres; a hairline and projection sphere are derived
   from the scalp in the proportions of the default head.

The fit is reported as percentiles of the surface-to-union distance above the chin.
"""

import io
import os

import numpy as np

from numba import njit

from hair_sim.vecmath import distance_to_triangles

DEFAULT_SPHERES = 63              # the most a head file takes
DEFAULT_PITCH = 0.002           # m, voxel edge
SEAL_VOXELS = 5                 # openings under ~4 * 5 voxels (2 cm) lead to no skin
HOLE_VOXELS = 1                 # holes under ~4 voxels are holes in the mesh
MAX_VOXELS = 60e6
MARGIN = 0.0002                 # m every sphere is kept inside the surface
CLIP = 0.015                    # m: a sample above the chin farther than this counts as this
BODY_CLIP = 0.05                # m: the same below the chin
BODY_SAMPLES = 5000
SAMPLES = 40000                 # surface samples for the cover and the report
CANDIDATES = 6000
TANGENT_SCALES = (1.0, 0.7, 0.5, 0.3, 0.18)
SWAP_PASSES = 2
TAIL = 0.005                    # m: a sample farther than this from the union costs
TAIL_COST = 0.014 ** 2          # this much more (the fit's 99th percentile is its tail)
HAIR_WEIGHT = 100.0             # a sample above the chin counts this many below it
# proportions of the default head (config/heads/default_adult.yaml) below its scalp's top
EYE_DEPTH = 0.11                # m: top of the scalp to the eye line
CHIN_DEPTH = 0.23               # m: top of the scalp to the chin
HAIRLINE_FRONT_DEPTH = 0.035    # m below the top, at the front of the scalp
HAIRLINE_BACK_DEPTH = 0.13      # m below the top, at the back
HAIRLINE_FRONT_FRACTION = 0.79  # front_x: this fraction of the scalp's reach forward
HAIRLINE_BACK_FRACTION = 0.95   # back_x: this fraction of its reach backward


class FitError(ValueError):
    """A mesh cannot be fitted (unreadable, empty, not closed enough)."""


def _extension(path):
    """Return a file's extension, lower case, without the dot ('obj')."""
    return os.path.splitext(path)[1].lower().lstrip('.')


def load_mesh(path, axes='xyz', scale=1.0):
    """
    Read a triangle mesh with trimesh; return (vertices (n, 3), triangles (m, 3)).

    `axes` names, for the head frame's x, y and z, the mesh axis each comes from, with an
    optional sign (for example '-z,x,y' or 'zxy'); `scale` multiplies every coordinate.
    """
    import trimesh
    try:
        try:
            loaded = trimesh.load(path, force='mesh', process=False)
        except ImportError:
            # a text mesh that is not UTF-8 (an OBJ exported with a Latin-1 comment or
            # name): trimesh guesses its encoding with a package this one does not need.
            # The geometry is ASCII: read it with what is not UTF-8 replaced.
            with open(path, 'rb') as f:
                text = f.read().decode('utf-8', errors='replace').encode('utf-8')
            loaded = trimesh.load(io.BytesIO(text), file_type=_extension(path),
                                  force='mesh', process=False)
    except Exception as exc:    # trimesh raises many kinds for a file it cannot read
        raise FitError('%s: cannot read a mesh (%s)' % (path, exc)) from None
    v = np.asarray(getattr(loaded, 'vertices', np.zeros((0, 3))), dtype=np.float64)
    t = np.asarray(getattr(loaded, 'faces', np.zeros((0, 3))), dtype=np.int64)
    if len(v) < 4 or len(t) < 4 or not np.isfinite(v).all():
        raise FitError('%s: no usable triangle mesh (%d vertices, %d triangles)'
                       % (path, len(v), len(t)))
    if not (np.isfinite(scale) and 1e-6 <= scale <= 1e6):
        raise FitError('--scale must be a positive number (metres per mesh unit), not %r'
                       % scale)
    if t.min() < 0 or t.max() >= len(v):
        raise FitError('%s: a triangle names a vertex the mesh does not have' % path)
    return map_axes(v, axes) * float(scale), t


def map_axes(v, axes):
    """Return vertices with their axes mapped onto the head frame (see load_mesh)."""
    tokens = [a for a in axes.replace(' ', '').split(',')] if ',' in axes else \
        _split_signed(axes)
    if len(tokens) != 3:
        raise FitError('--axes needs three axes, such as "xyz" or "z,x,y", not %r' % axes)
    cols = []
    for tok in tokens:
        sign = -1.0 if tok.startswith('-') else 1.0
        name = tok.lstrip('+-')
        if name not in ('x', 'y', 'z'):
            raise FitError('--axes: %r is not x, y or z' % tok)
        cols.append(sign * v[:, 'xyz'.index(name)])
    if len({t.lstrip('+-') for t in tokens}) != 3:
        raise FitError('--axes must use x, y and z once each, not %r' % axes)
    return np.stack(cols, axis=1)


def _split_signed(axes):
    out, sign = [], ''
    for ch in axes:
        if ch in '+-':
            sign = ch
        else:
            out.append(sign + ch)
            sign = ''
    return out


def voxelize_head(vertices, triangles, pitch):
    """
    Voxelize a head mesh; return (inside, outside, origin).

    `inside` and `outside` are (nx, ny, nz) bool grids whose voxel (i, j, k) has its centre
    at origin + pitch * (i, j, k); the grid's floor shuts an open cut below the shoulders.
    The outside is flooded from the grid's sides and top after openings under
    ~4 * SEAL_VOXELS voxels are shut (a morphological closing): an open mouth or the gap
    behind an ear does not let it in, so the walls of the mouth are not skin. The inside is
    what the mesh encloses once only holes under ~4 * HOLE_VOXELS voxels are shut: the
    flesh, without the mouth's cavity or the air behind an ear.
    """
    pad = SEAL_VOXELS + 2
    lo = vertices.min(axis=0) - pad * pitch
    hi = vertices.max(axis=0) + pad * pitch
    lo[2] = _floor(vertices, triangles) + pitch     # above the cut below the shoulders
    shape = np.ceil((hi - lo) / pitch).astype(int) + 1
    if np.prod(shape) > MAX_VOXELS:
        raise FitError('the mesh spans %s m: too large for a %.1f mm grid (is it in metres?)'
                       % (np.round(hi - lo, 2).tolist(), pitch * 1e3))
    surface = np.zeros(shape, dtype=np.bool_)
    _mark_surface(vertices, triangles, lo, pitch, surface)
    outside = _outside(surface, SEAL_VOXELS)
    inside = ~_outside(surface, HOLE_VOXELS) & ~surface
    if inside.sum() < 27:
        raise FitError('the mesh encloses no volume on a %.1f mm grid' % (pitch * 1e3))
    return inside, outside, lo


def _outside(surface, seal):
    """
    Voxels reached from the grid's sides and top once openings under 4 * seal are shut.

    A morphological closing: the surface is thickened by `seal` voxels, the outside flooded
    through the rest, and then grown back by `seal` (not into the surface).
    """
    from scipy import ndimage
    thick = ndimage.binary_dilation(surface, iterations=seal)
    seeds = np.zeros(surface.shape, dtype=bool)
    seeds[0], seeds[-1], seeds[:, 0], seeds[:, -1], seeds[:, :, -1] = (True,) * 5
    seeds &= ~thick
    outside = ndimage.binary_propagation(seeds, mask=~thick)
    return ndimage.binary_dilation(outside, iterations=seal) & ~surface


def _voxel_of(points, origin, pitch, shape):
    """Index tuple of the voxel holding each point (clamped to the grid)."""
    idx = np.round((points - origin) / pitch).astype(int)
    return tuple(np.clip(idx, 0, np.array(shape) - 1).T)


def skin_triangles(vertices, triangles, outside, origin, pitch):
    """Return the triangles that face the outside: the skin (not the inside of the mouth)."""
    from scipy import ndimage
    near = ndimage.binary_dilation(outside, iterations=2)
    centroid = vertices[triangles].mean(axis=1)
    return triangles[near[_voxel_of(centroid, origin, pitch, near.shape)]]


def _floor(vertices, triangles):
    """
    Height of the open cut at the bottom of a cropped mesh (its lowest point if none).

    The cut is the open boundary (edges of one triangle) in the lowest quarter of the mesh;
    the grid starts above its highest vertex so that the grid's floor shuts the cut.
    """
    edges = np.sort(np.concatenate([triangles[:, [0, 1]], triangles[:, [1, 2]],
                                    triangles[:, [2, 0]]]), axis=1)
    unique, count = np.unique(edges, axis=0, return_counts=True)
    z = vertices[np.unique(unique[count == 1]), 2]
    low = vertices[:, 2].min() + 0.25 * np.ptp(vertices[:, 2])
    z = z[z < low]
    return z.max() if len(z) else vertices[:, 2].min()


@njit(cache=True)
def _mark_surface(vertices, triangles, origin, pitch, surface):
    """Mark every voxel a triangle passes through (barycentric samples under pitch / 2)."""
    nx, ny, nz = surface.shape
    for t in range(triangles.shape[0]):
        a = vertices[triangles[t, 0]]
        b = vertices[triangles[t, 1]]
        c = vertices[triangles[t, 2]]
        longest = max(np.sqrt(((b - a) ** 2).sum()), np.sqrt(((c - a) ** 2).sum()),
                      np.sqrt(((c - b) ** 2).sum()))
        n = int(np.ceil(longest / (0.5 * pitch))) + 1
        for i in range(n + 1):
            for j in range(n + 1 - i):
                u = i / n
                w = j / n
                ix = int(np.rint((a[0] + u * (b[0] - a[0]) + w * (c[0] - a[0]) - origin[0])
                                 / pitch))
                iy = int(np.rint((a[1] + u * (b[1] - a[1]) + w * (c[1] - a[1]) - origin[1])
                                 / pitch))
                iz = int(np.rint((a[2] + u * (b[2] - a[2]) + w * (c[2] - a[2]) - origin[2])
                                 / pitch))
                if 0 <= ix < nx and 0 <= iy < ny and 0 <= iz < nz:
                    surface[ix, iy, iz] = True


@njit(cache=True)
def _shrinking_ball_radii(points, normals, samples, r_max, out):
    """
    Write into out the radius of the largest ball touching each point from inside.

    The ball centred at p - r n (n the outward normal) stays clear of every sample q with
    (q - p).n < 0 while r <= |q - p|^2 / (-2 (q - p).n) (the shrinking-ball medial axis).
    """
    for i in range(points.shape[0]):
        r = r_max
        px, py, pz = points[i, 0], points[i, 1], points[i, 2]
        nx, ny, nz = normals[i, 0], normals[i, 1], normals[i, 2]
        for k in range(samples.shape[0]):
            dx = samples[k, 0] - px
            dy = samples[k, 1] - py
            dz = samples[k, 2] - pz
            dn = dx * nx + dy * ny + dz * nz
            if dn < -1e-9:
                bound = (dx * dx + dy * dy + dz * dz) / (-2.0 * dn)
                if bound < r:
                    r = bound
        out[i] = r
    return out


def _outward_normals(skin, faces, points, outside, origin, pitch):
    """Face normals at skin points, flipped where they do not point into the outside."""
    n = skin.face_normals[faces]
    into = outside[_voxel_of(points + 2.0 * pitch * n, origin, pitch, outside.shape)]
    return np.where(into[:, None], n, -n)


def _candidates(skin, inside, outside, origin, pitch, count):
    """Return (centres (k, 3), tangent radii (k,)) of the largest inside balls on the skin."""
    import trimesh
    points, faces = trimesh.sample.sample_surface_even(skin, count, seed=1)
    normals = _outward_normals(skin, faces, points, outside, origin, pitch)
    dense, _ = trimesh.sample.sample_surface_even(skin, 4 * count, seed=2)
    radii = _shrinking_ball_radii(points, normals, dense,
                                  0.5 * np.ptp(skin.vertices, axis=0).max(),
                                  np.empty(len(points)))
    # tangent at each point: the largest ball and smaller ones (a seam between two large
    # balls is filled best by a small one)
    scale = np.repeat(TANGENT_SCALES, len(points))
    radii = np.tile(radii, len(TANGENT_SCALES)) * scale
    centres = np.tile(points, (len(TANGENT_SCALES), 1)) - radii[:, None] * np.tile(
        normals, (len(TANGENT_SCALES), 1))
    ok = inside[_voxel_of(centres, origin, pitch, inside.shape)]
    if not ok.any():
        raise FitError('the mesh is too thin for a %.1f mm grid' % (pitch * 1e3))
    return np.ascontiguousarray(centres[ok]), radii[ok]


@njit(cache=True)
def _cover_cost(x):
    """Cost of a sample x from the union: x^2, plus TAIL_COST once it is over TAIL."""
    return x * x + (TAIL_COST if x > TAIL else 0.0)


@njit(cache=True)
def _cover_gain(start, samp, d, weight, current, c):
    """Decrease of the weighted cost of the samples if candidate c joins the union."""
    gain = 0.0
    for e in range(start[c], start[c + 1]):
        j = samp[e]
        if d[e] < current[j]:
            gain += weight[j] * (_cover_cost(current[j]) - _cover_cost(d[e]))
    return gain


@njit(cache=True)
def _union_distance(start, samp, d, chosen, skip, clip, current):
    """Write into current each sample's clipped distance to the chosen spheres but `skip`."""
    current[:] = clip[:]
    for k in range(chosen.shape[0]):
        if k == skip or chosen[k] < 0:
            continue
        c = chosen[k]
        for e in range(start[c], start[c + 1]):
            if d[e] < current[samp[e]]:
                current[samp[e]] = d[e]


@njit(cache=True)
def _best_candidate(start, samp, d, weight, current):
    best, best_gain = -1, 0.0
    for c in range(start.shape[0] - 1):
        g = _cover_gain(start, samp, d, weight, current, c)
        if g > best_gain:
            best, best_gain = c, g
    return best


@njit(cache=True)
def _greedy_cover(start, samp, d, weight, clip, n_spheres, passes):
    """
    Pick n_spheres candidates minimising the weighted sum of squared clipped distances.

    Greedy, then `passes` rounds of exchange: each chosen sphere in turn is taken out and
    the best candidate given the others put in (the same one when nothing is better).
    """
    chosen = np.full(n_spheres, -1)
    current = np.empty(weight.shape[0])
    _union_distance(start, samp, d, chosen, -1, clip, current)
    for k in range(n_spheres):
        best = _best_candidate(start, samp, d, weight, current)
        if best < 0:
            break
        chosen[k] = best
        for e in range(start[best], start[best + 1]):
            if d[e] < current[samp[e]]:
                current[samp[e]] = d[e]
    for _ in range(passes):
        for k in range(n_spheres):
            if chosen[k] < 0:
                continue
            _union_distance(start, samp, d, chosen, k, clip, current)
            chosen[k] = _best_candidate(start, samp, d, weight, current)
    return chosen[chosen >= 0]


def surface_distance(spheres, points):
    """Distance of points (n, 3) to the union of spheres (k, 4): > 0 outside, < 0 inside."""
    out = np.full(len(points), np.inf)
    for s in spheres:
        np.minimum(out, np.linalg.norm(points - s[:3], axis=1) - s[3], out=out)
    return out


def fit_spheres(vertices, triangles, n_spheres=DEFAULT_SPHERES, pitch=DEFAULT_PITCH,
                eye_depth=EYE_DEPTH, chin_depth=CHIN_DEPTH):
    """
    Fit n_spheres inscribed spheres to a closed-enough head mesh.

    Return (spheres (n, 4) (cx, cy, cz, r), samples (m, 3) on the surface, above_chin (m,)
    bool, top_z) where top_z is the mesh's highest point.
    """
    import trimesh
    from scipy.spatial import cKDTree
    vertices = np.asarray(vertices, dtype=np.float64)
    triangles = np.asarray(triangles, dtype=np.int64)
    if not 1 <= n_spheres <= 63:
        raise FitError('the number of spheres must be 1 to 63, not %d' % n_spheres)
    inside, outside, origin = voxelize_head(vertices, triangles, pitch)
    skin_tris = skin_triangles(vertices, triangles, outside, origin, pitch)
    skin = trimesh.Trimesh(vertices, skin_tris, process=False)
    centres, tangent = _candidates(skin, inside, outside, origin, pitch, CANDIDATES)
    # exact inscribed radius: distance from each candidate centre to the skin's triangles
    # (at most the tangent ball's radius: the ball touches the skin where it was sampled)
    dist = distance_to_triangles(centres, tangent + 1e-9, vertices,
                                 np.ascontiguousarray(skin_tris), np.empty(len(centres)))
    radii = dist - MARGIN
    ok = radii > 0.5 * pitch
    centres, radii = centres[ok], radii[ok]
    top = vertices[:, 2].max()
    samples, _ = trimesh.sample.sample_surface_even(skin, SAMPLES, seed=0)
    above = samples[:, 2] > top - chin_depth
    # the cover's samples: every one above the chin, a fifth of those below (weighted up);
    # a body sample counts from farther away (BODY_CLIP): the shoulders get spheres too
    rng = np.random.default_rng(0)
    body = np.flatnonzero(~above)
    body = rng.choice(body, min(len(body), BODY_SAMPLES), replace=False)
    head = np.flatnonzero(above)
    cover = np.concatenate([head, body])
    weight = np.concatenate([np.full(len(head), HAIR_WEIGHT),
                             np.full(len(body), (~above).sum() / max(len(body), 1))])
    clip = np.concatenate([np.full(len(head), CLIP), np.full(len(body), BODY_CLIP)])
    # per candidate, the samples it can bring under their clip, and their distances (CSR)
    near_head = cKDTree(samples[head]).query_ball_point(centres, radii + CLIP)
    near_body = cKDTree(samples[body]).query_ball_point(centres, radii + BODY_CLIP)
    lists = [np.concatenate([np.asarray(a, dtype=np.int64), len(head) + np.asarray(
        b, dtype=np.int64)]) for a, b in zip(near_head, near_body)]
    start = np.concatenate([[0], np.cumsum([len(js) for js in lists])])
    samp = np.concatenate(lists)
    cand = np.repeat(np.arange(len(centres)), np.diff(start))
    d = np.maximum(np.linalg.norm(samples[cover][samp] - centres[cand], axis=1) - radii[cand],
                   0.0)
    chosen = _greedy_cover(start, samp, d, weight, clip, n_spheres, SWAP_PASSES)
    spheres = np.column_stack([centres[chosen], radii[chosen]])
    return spheres, samples, above, top


def head_from_spheres(spheres, top, name, mesh_file='', eye_depth=EYE_DEPTH):
    """
    Return the head file mapping of fitted spheres (see hair_sim.modeling.head).

    Spheres whose centres lie above the eye line (eye_depth below the mesh's top) are the
    scalp, the others the body; the projection sphere sits at the largest scalp sphere's
    centre with 2/3 of its radius; the hairline keeps the default head's proportions.
    """
    scalp_rows = spheres[:, 2] > top - eye_depth
    if not scalp_rows.any():
        raise FitError('no sphere lies above the eye line (%.3f m below the top): is z up?'
                       % eye_depth)
    scalp = spheres[scalp_rows]
    scalp = scalp[np.argsort(-scalp[:, 3])]
    body = spheres[~scalp_rows]
    body = body[np.argsort(-body[:, 3])]
    big = scalp[0]
    scalp_top = (scalp[:, 2] + scalp[:, 3]).max()
    front = (scalp[:, 0] + scalp[:, 3]).max() - big[0]
    back = big[0] - (scalp[:, 0] - scalp[:, 3]).min()

    def rows(arr, prefix):
        return [{'name': '%s_%d' % (prefix, i),
                 'center': [round(float(x), 5) for x in s[:3]],
                 'radius': round(float(s[3]), 5)} for i, s in enumerate(arr)]
    head = {
        'name': name,
        'frame_id': 'head',
        'scalp_spheres': rows(scalp, 'scalp'),
        'collision_spheres': rows(body, 'body'),
        'projection_sphere': {'center': [round(float(x), 5) for x in big[:3]],
                              'radius': round(float(big[3]) * 2.0 / 3.0, 5)},
        'hairline': {'front_x': round(float(big[0] + HAIRLINE_FRONT_FRACTION * front), 5),
                     'front_z': round(float(scalp_top - HAIRLINE_FRONT_DEPTH), 5),
                     'back_x': round(float(big[0] - HAIRLINE_BACK_FRACTION * back), 5),
                     'back_z': round(float(scalp_top - HAIRLINE_BACK_DEPTH), 5)},
    }
    if mesh_file:
        head['mesh'] = mesh_file
    return head


def fit_report(spheres, samples, above, seconds):
    """Return the fit's numbers: surface-to-union distance percentiles (mm), counts, time."""
    d = surface_distance(spheres, samples) * 1e3
    out = {'spheres': int(len(spheres)), 'seconds': round(seconds, 1)}
    for key, mask in (('above_chin', above), ('whole_mesh', np.ones_like(above))):
        q = np.percentile(d[mask], [50, 90, 99, 100])
        out[key + '_mm'] = {'median': round(float(q[0]), 2), 'p90': round(float(q[1]), 2),
                            'p99': round(float(q[2]), 2), 'max': round(float(q[3]), 2)}
    return out
