"""Coverage of the scalp by the U-shape (64 viewpoints) and conservative visibility culling."""

import numpy as np
import pytest

from hair_sim import DEFAULT_DT, HairSimulator, load_hairstyle, paths
from hair_sim.render import HairRenderer
from hair_sim.render.coverage import coverage, hair_region_samples
from hair_sim.render.raster import Camera, fibonacci_sphere, visible_strip_ids

SHIPPED = ('bob_fringe', 'side_swept_long', 'thesis_long', 'thesis_short')


def test_ushape_with_sphere_centre_covers_the_scalp(settled, renderer, capsys):
    """Sphere centre covers >= 98 % of rays; point centre and plain strips measurably less."""
    head = settled.head
    samples = hair_region_samples(head)
    R, p = settled.head_pose
    sphere, rays = coverage(renderer.mesh_of(settled), head, samples=samples)
    point_renderer = HairRenderer.for_simulator(settled, point_centre=True)
    point, _ = coverage(point_renderer.mesh_of(settled), head, samples=samples)
    plain, _ = coverage(renderer.mesh(settled.pos, R, p, walls=False), head,
                        samples=samples)
    with capsys.disabled():
        print('\ncoverage over %d rays: sphere centre %.4f, point centre %.4f, plain strips '
              '%.4f' % (rays, sphere, point, plain))
    assert rays > 50000
    assert sphere >= 0.98
    assert point < sphere - 0.03
    assert plain < point - 0.1


def test_culling_never_drops_a_strip_a_ray_hits(settled, renderer):
    """From 24 viewpoints, every strip the ray caster sees is drawn."""
    full = renderer.mesh_of(settled)
    eyes = [np.array([0.8, 0.0, 0.0])] + list(0.7 * fibonacci_sphere(23))
    culled_any = 0
    for eye in eyes:
        cam = Camera(eye, (0.0, 0.0, -0.05), fov_deg=40, width=384, height=384)
        seen = visible_strip_ids(full, settled.head.collision, cam)
        drawn = set(renderer.mesh_of(settled, viewpoint=eye).strip_ids.tolist())
        assert seen <= drawn, (eye, seen - drawn)
        culled_any += full.n_strips - len(drawn)
    assert culled_any > 0


def _shake_step(sim, i):
    """Step frame i of a head shake (yaw 0.6 rad at 1.5 Hz, bob 2 cm at 1 Hz)."""
    t = (i + 1) * DEFAULT_DT
    yaw = 0.6 * np.sin(2 * np.pi * 1.5 * t)
    sim.set_head_pose(t, [0.0, 0.0, 0.02 * np.sin(2 * np.pi * t)],
                      [0.0, 0.0, np.sin(yaw / 2), np.cos(yaw / 2)])
    sim.step(DEFAULT_DT)


def _shaken(name):
    """Return a simulator of shipped style `name` after a head shake (strands off rest)."""
    sim = HairSimulator(load_hairstyle(paths.shipped_style(name)))
    for i in range(90):
        _shake_step(sim, i)
    return sim


@pytest.mark.parametrize('name', SHIPPED)
def test_culling_of_every_style_never_drops_a_strip_a_ray_hits(name):
    """Every shipped style, mid-shake, from 16 viewpoints: every strip a ray hits is drawn."""
    sim = _shaken(name)
    renderer = HairRenderer.for_simulator(sim)
    full = renderer.mesh_of(sim)
    R, p = sim.head_pose
    spheres = sim.head.collision.copy()            # where the head is now (world)
    spheres[:, :3] = spheres[:, :3] @ R.T + p
    culled_any = 0
    for eye in [np.array([0.8, 0.0, 0.0])] + list(0.7 * fibonacci_sphere(15)):
        cam = Camera(eye, (0.0, 0.0, -0.05), fov_deg=40, width=256, height=256)
        seen = visible_strip_ids(full, spheres, cam)
        drawn = set(renderer.mesh_of(sim, viewpoint=eye).strip_ids.tolist())
        assert seen <= drawn, (eye, seen - drawn)
        culled_any += full.n_strips - len(drawn)
    assert culled_any > 0


@pytest.mark.parametrize('name', SHIPPED)
def test_certificates_kept_from_frame_to_frame_never_drop_a_strip_a_ray_hits(name):
    """
    A renderer that keeps its certificates while the head shakes culls soundly.

    Culling checks a strip it proved hidden at the last call by that proof's certificate
    first (culling.certificate_holds), against the strands and head as they are now. Mesh
    every frame of a head shake from two fixed eyes, and every few frames ask a ray
    caster: every strip a ray hits is drawn, and strips hidden by a kept certificate were
    culled on the way.
    """
    sim = HairSimulator(load_hairstyle(paths.shipped_style(name)))
    eyes = [np.array([0.8, 0.0, 0.0]), np.array([-0.3, 0.6, 0.2])]
    kept = [HairRenderer.for_simulator(sim) for _ in eyes]
    certified = 0
    for i in range(64):
        _shake_step(sim, i)
        R, p = sim.head_pose
        for eye, renderer in zip(eyes, kept):
            had = renderer._proofs[:, 0] >= 0              # certificates from the last call
            drawn = renderer.mesh(sim.pos, R, p, viewpoint=eye)
            hidden = np.ones(renderer.n_strips, dtype=bool)
            hidden[drawn.strip_ids] = False
            certified += int((had & hidden).sum())
            if i % 16 == 15:
                full = renderer.mesh(sim.pos, R, p)
                spheres = sim.head.collision.copy()
                spheres[:, :3] = spheres[:, :3] @ R.T + p
                cam = Camera(eye, p + [0.0, 0.0, -0.05], fov_deg=40, width=256, height=256)
                seen = visible_strip_ids(full, spheres, cam)
                assert seen <= set(drawn.strip_ids.tolist()), (i, eye, seen)
    assert certified > 0


def test_culling_remembers_failed_proofs_only_to_draw_more_and_only_for_a_while():
    """
    Culling's memory of failed proofs only adds strips, for at most PROOF_REST calls.

    Frame after frame of a head shake, culling with its memory draws every strip culling
    without it (a fresh renderer each frame) draws, and a strip it draws unproven stays so
    at most PROOF_REST calls; a new view forgets it (the next call draws what a fresh one
    does).
    """
    from hair_sim.render.culling import PROOF_REST
    sim = HairSimulator(load_hairstyle(paths.shipped_style('thesis_long')))
    kept = HairRenderer.for_simulator(sim)
    eye = [0.8, 0.0, 0.0]
    unproven = {}                                # strip: calls in a row drawn beyond fresh
    longest = 0
    for i in range(150):
        _shake_step(sim, i)
        R, p = sim.head_pose
        mine = set(kept.visible(sim.pos, R, p, eye).tolist())
        fresh = set(HairRenderer.for_simulator(sim).visible(sim.pos, R, p, eye).tolist())
        assert fresh <= mine, (i, fresh - mine)
        unproven = {s: unproven.get(s, 0) + 1 for s in mine - fresh}
        longest = max([longest] + list(unproven.values()))
    assert 0 < longest <= PROOF_REST                 # it remembered, and not for longer
    R, p = sim.head_pose
    kept.visible(sim.pos, R, p, eye)
    rested = set(np.flatnonzero(kept._proof_rest).tolist())    # drawn unproven next call
    for other in 0.8 * fibonacci_sphere(32):                   # a view that hides one
        fresh = HairRenderer.for_simulator(sim).visible(sim.pos, R, p, other)
        if rested - set(fresh.tolist()):
            break
    assert rested - set(fresh.tolist()), rested                # (the check is not vacuous)
    assert np.array_equal(kept.visible(sim.pos, R, p, other), fresh)


def test_wall_bounds_culling_uses_hold_the_projected_walls():
    """
    Culling's bounds on a wall hold the wall bottoms the projection gives.

    The bounds are wall_extents and strip_wall_reach; the bottoms, strip_wall_bottoms
    (thesis 3.2). For every simulated vertex of every shipped style mid-shake, the bottom
    is within the extent of the edge point, and on the segment from it to the reach point
    or within the fix-up length of it.
    """
    from hair_sim.render.culling import wall_extents
    from hair_sim.render.ushape import strip_wall_bottoms, strip_wall_reach
    kinds = {'fix-up': 0, 'on the segment': 0, 'extent is the fix-up': 0}
    for name in SHIPPED:
        sim = _shaken(name)
        renderer = HairRenderer.for_simulator(sim)
        R, p = sim.head_pose
        projection = renderer.projection(R, p)
        pos = sim.pos
        V = pos.shape[1]
        bottoms, reach = np.zeros_like(pos), np.zeros_like(pos)
        spans = np.zeros((projection.scalp.shape[0], 2))
        extents = np.zeros((2, V))
        for s, (a, b) in enumerate(renderer.strip_strands):
            strip_wall_bottoms(pos, renderer.strip_strands, s, renderer.sigma[s], projection,
                               (0, V - 1), bottoms, spans)
            strip_wall_reach(pos, renderer.strip_strands, s, projection, (0, V - 1), reach)
            wall_extents(pos, (a, b), np.zeros((2, V)), projection, extents)
            for q, st in enumerate((a, b)):
                wall = bottoms[st] - pos[st]
                length = np.linalg.norm(wall, axis=1)
                assert np.all(length <= extents[q] + 1e-12), (name, s, q, length, extents[q])
                seg = reach[st] - pos[st]
                ss = np.einsum('ij,ij->i', seg, seg)
                t = np.clip(np.einsum('ij,ij->i', wall, seg) / np.where(ss > 0, ss, 1.0), 0, 1)
                off = np.linalg.norm(wall - t[:, None] * seg, axis=1)
                fixed = np.abs(length - projection.fix_len) < 1e-12
                assert np.all(fixed | (off <= 1e-9)), (name, s, q, off, length)
                kinds['fix-up'] += int(fixed.sum())
                kinds['on the segment'] += int((~fixed).sum())
                kinds['extent is the fix-up'] += int(np.sum(extents[q] == projection.fix_len))
    assert min(kinds.values()) > 0, kinds        # every kind of wall and bound was checked


def test_front_view_skips_a_third(settled, renderer):
    """Seen from the front, at least a third of the sample style's strips are not drawn."""
    n = settled.strips.n_strips
    for eye in ([0.8, 0.0, 0.0], [0.6, 0.0, 0.05], [1.0, 0.0, 0.02]):
        drawn = renderer.mesh_of(settled, viewpoint=eye).n_strips
        assert n - drawn >= n / 3, (eye, drawn)
    back = renderer.mesh_of(settled, viewpoint=[-0.8, 0.0, 0.0])
    assert back.n_strips > n - n / 3                                  # back: most drawn
    assert hair_region_samples(settled.head).shape[0] > 1000


def _ray_blocked(eye, point, sphere):
    """Return True if the segment eye -> point passes through the sphere (centre, r)."""
    c, r = sphere[:3], sphere[3]
    d = point - eye
    length = np.linalg.norm(d)
    u = d / length
    m = eye - c
    b = m @ u
    disc = b * b - (m @ m - r * r)
    if disc < 0.0:
        return False
    entry = -b - np.sqrt(disc)
    return 0.0 <= entry <= length


@pytest.mark.parametrize('seed', range(4))
def test_a_ball_called_shadowed_is_hidden_from_every_ray(seed):
    """Balls culling calls shadowed: sampled points in them are all behind the sphere."""
    from hair_sim.render.culling import ball_in_shadow, shadow_cones
    rng = np.random.default_rng(seed)
    eye = rng.normal(size=3) * 0.5
    sphere = np.array([0.0, 0.0, 0.0, 0.1])
    cones = shadow_cones(eye, sphere[None, :])
    shadowed = 0
    for _ in range(3000):
        # balls around the sphere and behind it, of 0 to 3 cm
        centre = rng.normal(size=3) * 0.08 - eye * rng.uniform(0.0, 0.8)
        rho = rng.uniform(0.0, 0.03)
        if not ball_in_shadow(centre[0], centre[1], centre[2], rho, eye, cones, 0):
            continue
        shadowed += 1
        for _ in range(8):                     # points on and in the ball
            v = rng.normal(size=3)
            point = centre + rho * rng.uniform(0.5, 1.0) * v / np.linalg.norm(v)
            assert _ray_blocked(eye, point, sphere), (eye, centre, rho, point)
    assert shadowed > 100                      # the test saw shadowed balls


def test_culled_meshes_have_their_own_triangles_when_the_view_changes(settled, renderer):
    """Culled meshes from alternating viewpoints: each one's triangles are its strips'."""
    from hair_sim.render.mesh import culled_triangles
    R, p = settled.head_pose
    eyes = [[0.8, 0.0, 0.0], [0.5, 0.6, 0.0], [0.8, 0.0, 0.0], [0.5, -0.6, 0.0]]
    seen = set()
    for eye in eyes + eyes:
        mesh = renderer.mesh(settled.pos, R, p, viewpoint=eye)
        strips = mesh.strip_ids.astype(np.int64)
        seen.add(tuple(strips))
        fresh = culled_triangles(renderer._local, strips, mesh.verts_per_strip)
        assert np.array_equal(mesh.indices, fresh)
        assert mesh.indices.max() < len(mesh.vertices)
    assert len(seen) >= 3                        # the views really drew different strips


@pytest.mark.parametrize('viewpoint', [[float('nan'), 0.0, 0.0], [0.8, float('inf'), 0.0],
                                       [0.8, 0.0], [0.8, 0.0, 0.0, 1.0], 'front', [[0.8]]])
def test_a_viewpoint_that_is_no_point_is_refused_by_name(settled, renderer, viewpoint):
    # (before: a 2-vector was read past its end by the kernels, a NaN one drew every
    # strip, and neither said a word)
    R, p = settled.head_pose
    for call in (lambda: renderer.mesh_of(settled, viewpoint=viewpoint),
                 lambda: renderer.mesh(settled.pos, R, p, viewpoint),
                 lambda: renderer.visible(settled.pos, R, p, viewpoint)):
        with pytest.raises(ValueError, match='viewpoint'):
            call()
    # and the renderer goes on culling for a real eye, as a fresh one does
    eye = [0.8, 0.0, 0.0]
    fresh = HairRenderer.for_simulator(settled)
    assert renderer.mesh_of(settled, viewpoint=eye).n_strips == \
        fresh.mesh_of(settled, viewpoint=eye).n_strips < renderer.n_strips
