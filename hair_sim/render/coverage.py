"""How much of the scalp's hair region the hair hides, by casting rays from many viewpoints."""

import numpy as np

from hair_sim.render.raster import Camera, fibonacci_sphere


def hair_region_samples(head, n=6000):
    """Return points of the scalp boundary (union of scalp spheres) in the hair region."""
    centre = head.projection_sphere[:3]
    pts = head.nearest_on_scalp(centre + 0.3 * fibonacci_sphere(n))
    keep = head.in_hair_region(pts) & (head.scalp_distance(pts) > -1e-9)
    return pts[keep]


def coverage(mesh, head, n_views=64, distance=0.6, size=320, samples=None):
    """
    Return (covered fraction, rays cast) over n_views viewpoints around the head.

    A ray goes from each viewpoint to each hair-region scalp point that the viewpoint sees
    (nearest surface of the head's spheres, facing it); it is covered when the hair mesh
    is hit first. Rays go through pixel centres of a size x size image per view.
    """
    samples = hair_region_samples(head) if samples is None else samples
    normals = samples - head.scalp[np.argmin(
        np.linalg.norm(samples[:, None] - head.scalp[None, :, :3], axis=2)
        - head.scalp[None, :, 3], axis=1), :3]
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    centre = np.array([0.0, 0.0, 0.0])
    covered = total = 0
    for eye in distance * fibonacci_sphere(n_views) + centre:
        cam = Camera(eye, centre, fov_deg=30.0, width=size, height=size)
        hd, _, _ = cam.render_mesh(mesh.vertices, mesh.indices)
        sd, _ = cam.render_spheres(head.collision)
        x, y, z = cam.project(samples)
        px, py = np.floor(x).astype(int), np.floor(y).astype(int)
        inside = (px >= 0) & (px < size) & (py >= 0) & (py < size)
        facing = ((eye - samples) * normals).sum(axis=1) > 0
        ok = inside & facing
        px, py, z = px[ok], py[ok], z[ok]
        seen = np.abs(sd[py, px] - z) < 2e-3          # the scalp point is what the ray meets
        total += int(seen.sum())
        covered += int((hd[py, px][seen] < z[seen] - 1e-4).sum())
    return covered / max(total, 1), total
