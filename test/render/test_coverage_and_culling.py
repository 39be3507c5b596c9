"""Coverage of the scalp by the U-shape (64 viewpoints) and conservative visibility culling."""

import numpy as np

from hair_sim.render import HairRenderer
from hair_sim.render.coverage import coverage, hair_region_samples
from hair_sim.render.raster import Camera, fibonacci_sphere, visible_strip_ids


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


def test_front_view_skips_a_third(settled, renderer):
    """Seen from the front, at least a third of the sample style's strips are not drawn."""
    n = settled.strips.n_strips
    for eye in ([0.8, 0.0, 0.0], [0.6, 0.0, 0.05], [1.0, 0.0, 0.02]):
        drawn = renderer.mesh_of(settled, viewpoint=eye).n_strips
        assert n - drawn >= n / 3, (eye, drawn)
    back = renderer.mesh_of(settled, viewpoint=[-0.8, 0.0, 0.0])
    assert back.n_strips > n - n / 3                                  # back: most drawn
    assert hair_region_samples(settled.head).shape[0] > 1000
