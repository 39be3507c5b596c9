"""U-shape strips (thesis 3.1, 3.2): projections, fix-ups, winding, UVs and counts."""

import math

import numpy as np
import pytest

from hair_sim.render import mesh as mesh_mod, ushape


def walls_of(renderer, k):
    """Return (edge vertices, projections) (k, 2 sides, rows, 3) of the last U-shape."""
    lod = renderer.lod
    C, R = lod.columns, lod.rows
    out = renderer.last_f64[:k]
    edges = np.stack([out[:, C * R:C * R + R], out[:, C * R + 2 * R:C * R + 3 * R]], axis=1)
    proj = np.stack([out[:, C * R + R:C * R + 2 * R], out[:, C * R + 3 * R:]], axis=1)
    return edges, proj


def test_projections_on_scalp_or_fixed_up_exactly(settled, renderer):
    """Projected vertices lie on the scalp within delta; fix-ups have |AA'| = C, AA' normal."""
    m = renderer.mesh_of(settled)
    r = renderer
    edges, proj = walls_of(r, m.n_strips)
    head = settled.head
    flags = m.flags
    on_scalp = flags == 0
    d = head.scalp_distance(proj[on_scalp])
    assert on_scalp.sum() > 1000
    assert np.abs(d).max() <= mesh_mod.DELTA
    fixed = flags > 0
    assert fixed.sum() > 0                                   # long tails get fixed up
    v = proj[fixed] - edges[fixed]
    np.testing.assert_allclose(np.linalg.norm(v, axis=1), mesh_mod.FIX_LENGTH, atol=1e-9)
    # perpendicular to the strip polygon at that row: AB (across) and AC (along)
    grid = r._grid[:m.n_strips]
    C = r.lod.columns
    ab = grid[:, C - 1] - grid[:, 0]                          # (k, R, 3)
    up = np.concatenate([grid[:, 0, 1:2] - grid[:, 0, 0:1],
                         0.5 * (grid[:, 0, 2:] - grid[:, 0, :-2]),
                         grid[:, 0, -1:] - grid[:, 0, -2:-1]], axis=1)
    upb = np.concatenate([grid[:, -1, 1:2] - grid[:, -1, 0:1],
                          0.5 * (grid[:, -1, 2:] - grid[:, -1, :-2]),
                          grid[:, -1, -1:] - grid[:, -1, -2:-1]], axis=1)
    ac = 0.5 * (up + upb)
    k_idx, side, row = np.nonzero(fixed)
    vv = proj[k_idx, side, row] - edges[k_idx, side, row]
    assert np.abs((vv * ab[k_idx, row]).sum(1)).max() < 1e-9
    assert np.abs((vv * ac[k_idx, row]).sum(1)).max() < 1e-9


def ang(u, v):
    """Return the angle between vectors u and v."""
    return np.arccos(np.clip(np.dot(u, v) / np.linalg.norm(u) / np.linalg.norm(v), -1, 1))


def test_tangent_point_properties():
    """
    A' is on S, AA' touches S there, lies in the plane of A, B, O, turned away from B.

    B is beside A as across a strip lying over the scalp (angle(AB, AO) + the tangent's
    angle below 180 degrees; beyond that no tangent point satisfies the thesis' condition).
    """
    rng = np.random.default_rng(7)
    o = np.array([0.0, 0.0, 0.02])
    rs = 0.045
    for _ in range(200):
        u = rng.normal(size=3)
        a = o + u / np.linalg.norm(u) * rng.uniform(0.06, 0.3)      # outside S
        b = a + rng.normal(size=3) / 50
        beta = np.arcsin(rs / np.linalg.norm(o - a))
        if ang(b - a, o - a) + beta >= np.pi:
            continue
        t = np.array(ushape.tangent_point(*a, *b, o, rs))
        assert abs(np.linalg.norm(t - o) - rs) < 1e-12
        assert abs(np.dot(t - a, t - o)) < 1e-12                   # tangent at A'
        n = np.cross(b - a, o - a)
        assert abs(np.dot(t - a, n / np.linalg.norm(n))) < 1e-12   # in plane x-y
        assert ang(b - a, o - a) < ang(b - a, t - a)
    assert np.array_equal(ushape.tangent_point(*a, *b, o, 0.0), tuple(o))   # point centre


def flat_strip(height, centre_z=0.2):
    """Return a (1, 3, rows, 3) grid of a flat strip above the top of a unit-ish scalp."""
    rows = np.linspace(-0.02, 0.02, 5)
    grid = np.zeros((1, 3, 5, 3))
    for c, y in enumerate((-0.005, 0.0, 0.005)):
        grid[0, c, :, 0] = rows
        grid[0, c, :, 1] = y
        grid[0, c, :, 2] = centre_z + height
    return grid


def run_ushape(grid, sigma):
    """Run the U-shape kernel on one strip over a scalp sphere of radius 0.2 at the origin."""
    scalp = np.array([[0.0, 0.0, 0.0, 0.2]])
    out = np.zeros((1, (3 + 4) * 5, 3))
    flags = np.zeros((1, 2, 5), dtype=np.int64)
    projection = ushape.Projection(scalp=scalp, centre=np.array([0.0, 0.0, 0.0]), rs=0.05,
                                   delta=1e-4, max_dist=0.04, fix_len=0.006)
    ushape.ushape(grid, np.array([sigma]), np.array([0]), projection, out, flags,
                  ushape.wall_scratch(len(projection.scalp)))
    return out, flags


def test_ordinary_too_far_and_reverse_volume_cases():
    """Constructed cases: ordinary ones projected, a far tail and a reverse volume fixed."""
    # AB x AC points along -z here (x is along, y across): towards the scalp, sigma = +1
    out, flags = run_ushape(flat_strip(0.01), +1.0)
    assert np.all(flags == 0)
    proj = out[0, 3 * 5 + 5:3 * 5 + 10]
    assert np.all(np.abs(np.linalg.norm(proj, axis=1) - 0.2) <= 1e-4)
    out, flags = run_ushape(flat_strip(0.08), +1.0)            # 8 cm up: too far
    assert np.all(flags == 1)
    proj = out[0, 3 * 5 + 5:3 * 5 + 10]
    edge = out[0, 3 * 5:3 * 5 + 5]
    np.testing.assert_allclose(proj - edge, np.tile([0, 0, -0.006], (5, 1)), atol=1e-12)
    out, flags = run_ushape(flat_strip(0.01), -1.0)            # scalp side flipped
    assert np.all(flags == 2)
    proj = out[0, 3 * 5 + 5:3 * 5 + 10]
    edge = out[0, 3 * 5:3 * 5 + 5]
    np.testing.assert_allclose(proj - edge, np.tile([0, 0, 0.006], (5, 1)), atol=1e-12)


def test_mesh_invariants_winding_and_uvs(settled, renderer):
    """Indices in range, no degenerate triangle, one UV per vertex, counts, outward faces."""
    m = renderer.mesh_of(settled)
    lod = renderer.lod
    C, R, S = lod.columns, lod.rows, m.n_strips
    assert m.vertices.shape == (S * (C + 4) * R, 3) and m.vertices.dtype == np.float32
    assert m.uvs.shape == (len(m.vertices), 2) and m.uvs.dtype == np.float32
    assert m.indices.shape == (S * 2 * (C + 1) * (R - 1), 3) and m.indices.dtype == np.uint32
    assert m.indices.max() < len(m.vertices)
    np.testing.assert_array_equal(m.strip_offsets, np.arange(S + 1) * 2 * (C + 1) * (R - 1))
    tri = m.vertices[m.indices].astype(np.float64)
    normal = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    area = 0.5 * np.linalg.norm(normal, axis=1)
    assert area.min() > 1e-10                                   # no degenerate triangles
    # the strip faces look away from the scalp (outer side front-facing, CCW)
    per = 2 * (C + 1) * (R - 1)
    grid_tris = (np.arange(len(tri)) % per) < 2 * (C - 1) * (R - 1)
    centre = tri.mean(axis=1)
    outward = centre - settled.head.nearest_on_scalp(centre)
    dots = (normal * outward).sum(1)
    assert (dots[grid_tris] > 0).mean() > 0.97
    # UVs: v from 0 at the root to 1 at the tip on the strip and both walls
    v = m.uvs[:, 1].reshape(S, C + 4, R)
    np.testing.assert_allclose(v, np.broadcast_to(np.linspace(0, 1, R), v.shape), atol=1e-7)
    np.testing.assert_allclose(m.uvs[:, 0].reshape(S, C + 4, R)[:, :C, 0],
                               np.broadcast_to(np.linspace(0, 1, C), (S, C)), atol=1e-7)


def test_nothing_is_stored_between_frames(settled, renderer):
    """The U-shape is a function of the current strands: same input, same mesh; moved, new."""
    a = renderer.mesh_of(settled)
    b = renderer.mesh_of(settled)
    assert np.array_equal(a.vertices, b.vertices)
    r = renderer
    R, p = settled.head_pose
    moved = r.mesh(settled.pos + [0.0, 0.0, 0.001], R, p + [0.0, 0.0, 0.001])
    np.testing.assert_allclose(moved.vertices - a.vertices, np.tile([0, 0, 0.001],
                                                                    (len(a.vertices), 1)),
                               atol=2e-6)


def bisect_between_points(a, target, scalp, delta):
    """Thesis 3.2 as written: bisect between the points X (outside) and Y (inside)."""
    def inside(q, depth):
        return bool((np.linalg.norm(q - scalp[:, :3], axis=1) < scalp[:, 3] - depth).any())
    a, target = np.asarray(a, float), np.asarray(target, float)
    if inside(a, delta):
        return a
    x, y = a.copy(), target.copy()
    while ((x - y) ** 2).sum() > delta * delta:
        z = 0.5 * (x + y)
        if inside(z, 0.0):
            y = z
        else:
            x = z
    return 0.5 * (x + y)


@pytest.mark.parametrize('n_spheres', [1, 2, 5, 12])
def test_projection_is_the_bisection_between_points(n_spheres):
    """
    project_to_scalp gives the thesis' bisection between the points.

    It bisects the segment's parameter with the spheres' intervals. Segments that enter
    once, that graze, that pass through a sphere and out again, that end outside, and that
    start within delta of the skin.
    """
    rng = np.random.default_rng(n_spheres)
    delta = 5e-4
    spans = np.empty((n_spheres, 2))
    kinds = set()
    for _ in range(400):
        scalp = np.column_stack([rng.normal(scale=0.03, size=(n_spheres, 3)),
                                 rng.uniform(0.02, 0.08, n_spheres)])
        a = rng.normal(size=3)
        a *= rng.uniform(0.06, 0.3) / np.linalg.norm(a)
        target = rng.normal(scale=0.05, size=3) * rng.choice([0.2, 1.0, 4.0])
        got = np.array(ushape.project_to_scalp(tuple(a), tuple(target), scalp, delta, spans))
        want = bisect_between_points(a, target, scalp, delta)
        np.testing.assert_allclose(got, want, atol=1e-12)
        d = np.linalg.norm(target - scalp[:, :3], axis=1) < scalp[:, 3]
        kinds.add('ends inside' if d.any() else 'ends outside')
    assert kinds == {'ends inside', 'ends outside'}


def walls_edge_by_edge(grid, sigma, projection):
    """Each wall vertex by tangent_point, project_to_scalp and the fix-ups, one at a time."""
    K, C, R = grid.shape[:3]
    spans = np.empty((len(projection.scalp), 2))
    walls = np.zeros((K, 2, 2 * R, 3))
    flags = np.zeros((K, 2, R), dtype=np.int64)
    for k in range(K):
        for r in range(R):
            r0, r1 = max(r - 1, 0), min(r + 1, R - 1)
            n = np.array(ushape.strip_normal(*(tuple(grid[k, c, rr]) for rr in (r, r0, r1)
                                               for c in (0, C - 1)))) * sigma[k]
            for side, (ca, cb) in enumerate(((0, C - 1), (C - 1, 0))):
                a, b = grid[k, ca, r], grid[k, cb, r]
                t = ushape.tangent_point(*a, *b, projection.centre, projection.rs)
                p = np.array(ushape.project_to_scalp(tuple(a), t, projection.scalp,
                                                     projection.delta, spans))
                v = p - a
                if math.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]) > projection.max_dist:
                    flags[k, side, r] = 1
                elif v[0] * n[0] + v[1] * n[1] + v[2] * n[2] < 0.0:
                    flags[k, side, r] = 2
                if flags[k, side, r]:
                    p = a + projection.fix_len * n
                walls[k, side, r], walls[k, side, R + r] = a, p
    return walls, flags


@pytest.mark.parametrize('rows', [5, 30, 300])
@pytest.mark.parametrize('n_spheres', [1, 3])
def test_vectorised_walls_are_the_edge_by_edge_walls_bit_for_bit(rows, n_spheres):
    """
    Check that the walls of ushape, projected in vectorised phases, are the scalar ones.

    They must be, to the bit, what tangent_point, project_to_scalp and the fix-ups give
    edge by edge: for strips crumpled around a scalp of several spheres, with edges deep
    inside it, passing through a sphere and out again, too far, and reversed (the rare
    ones take the scalar path inside ushape), and strips longer than WALL_ROWS rows.
    """
    rng = np.random.default_rng(rows + n_spheres)
    scalp = np.column_stack([rng.normal(scale=0.02, size=(n_spheres, 3)),
                             rng.uniform(0.06, 0.09, n_spheres)])
    projection = ushape.Projection(scalp=scalp, centre=np.array([0.0, 0.0, 0.01]), rs=0.04,
                                   delta=2e-4, max_dist=0.05, fix_len=0.006)
    K, C = 6, 3
    # random walks over the scalp, some starting inside it: every kind of edge
    steps = rng.normal(scale=0.012, size=(K, rows, 3))
    start = rng.normal(size=(K, 3))
    start *= rng.uniform(0.0, 0.12, (K, 1)) / np.linalg.norm(start, axis=1, keepdims=True)
    start[0] = scalp[0, :3]                  # one strip starts deep inside the scalp
    left = start[:, None, :] + np.cumsum(steps, axis=1)
    right = left + rng.normal(scale=0.004, size=(K, rows, 3))
    grid = np.stack([left, 0.5 * (left + right), right], axis=1)
    sigma = rng.choice([-1.0, 1.0], K)
    out = np.zeros((K, (C + 4) * rows, 3))
    flags = np.zeros((K, 2, rows), dtype=np.int64)
    ushape.ushape(grid, sigma, np.arange(K), projection, out, flags,
                  ushape.wall_scratch(n_spheres))
    walls, want_flags = walls_edge_by_edge(grid, sigma, projection)
    got = out[:, C * rows:].reshape(K, 2, 2 * rows, 3)
    assert np.array_equal(got, walls) and np.array_equal(flags, want_flags)
    assert set(np.unique(want_flags)) == {0, 1, 2}
    deep = (np.linalg.norm(grid[:, [0, -1], :, None, :] - scalp[:, :3], axis=-1)
            < scalp[:, 3] - projection.delta).any(axis=-1)
    assert deep.any() and not deep.all()
