"""
A small software ray caster / rasterizer in numba, for tests, coverage and pictures.

Rays go through pixel centres of a pinhole camera. Triangles are rasterized with a
z-buffer (depth along the ray, perspective-correct barycentrics); spheres are intersected
per pixel. With a texture, a triangle's pixel counts only where the texture's alpha at the
interpolated uv is at least `alpha_cut` (cut-out transparency).
"""

from math import sqrt, tan

from numba import njit
import numpy as np


def look_at(eye, target, up=(0.0, 0.0, 1.0)):
    """Return the camera rotation rows (right, down, forward) looking from eye at target."""
    eye = np.asarray(eye, dtype=np.float64)
    f = np.asarray(target, dtype=np.float64) - eye
    f /= np.linalg.norm(f)
    r = np.cross(f, up)
    if np.linalg.norm(r) < 1e-9:
        r = np.cross(f, (1.0, 0.0, 0.0))
    r /= np.linalg.norm(r)
    d = np.cross(f, r)
    return np.stack([r, d, f])


@njit(cache=True)
def _raster(verts_cam, tris, uvs, tex, view, depth, tri_id, bary):
    """Rasterize triangles (camera coordinates) into depth, triangle id and barycentrics."""
    width, height, focal, alpha_cut = view
    for t in range(tris.shape[0]):
        i0, i1, i2 = tris[t, 0], tris[t, 1], tris[t, 2]
        z0, z1, z2 = verts_cam[i0, 2], verts_cam[i1, 2], verts_cam[i2, 2]
        if z0 < 1e-3 or z1 < 1e-3 or z2 < 1e-3:
            continue
        x0 = focal * verts_cam[i0, 0] / z0 + 0.5 * width
        y0 = focal * verts_cam[i0, 1] / z0 + 0.5 * height
        x1 = focal * verts_cam[i1, 0] / z1 + 0.5 * width
        y1 = focal * verts_cam[i1, 1] / z1 + 0.5 * height
        x2 = focal * verts_cam[i2, 0] / z2 + 0.5 * width
        y2 = focal * verts_cam[i2, 1] / z2 + 0.5 * height
        area = (x1 - x0) * (y2 - y0) - (x2 - x0) * (y1 - y0)
        if abs(area) < 1e-12:
            continue
        xmin = max(int(min(x0, x1, x2)), 0)
        xmax = min(int(max(x0, x1, x2)) + 1, width - 1)
        ymin = max(int(min(y0, y1, y2)), 0)
        ymax = min(int(max(y0, y1, y2)) + 1, height - 1)
        for py in range(ymin, ymax + 1):
            cy = py + 0.5
            for px in range(xmin, xmax + 1):
                cx = px + 0.5
                w0 = ((x1 - cx) * (y2 - cy) - (x2 - cx) * (y1 - cy)) / area
                w1 = ((x2 - cx) * (y0 - cy) - (x0 - cx) * (y2 - cy)) / area
                w2 = 1.0 - w0 - w1
                if w0 < 0.0 or w1 < 0.0 or w2 < 0.0:
                    continue
                # perspective-correct barycentrics
                q0, q1, q2 = w0 / z0, w1 / z1, w2 / z2
                qs = q0 + q1 + q2
                z = 1.0 / qs
                if z >= depth[py, px]:
                    continue
                b0, b1 = q0 * z, q1 * z
                if tex.shape[0] > 0:
                    u = b0 * uvs[i0, 0] + b1 * uvs[i1, 0] + (1 - b0 - b1) * uvs[i2, 0]
                    v = b0 * uvs[i0, 1] + b1 * uvs[i1, 1] + (1 - b0 - b1) * uvs[i2, 1]
                    tx = min(max(int(u * tex.shape[1]), 0), tex.shape[1] - 1)
                    ty = min(max(int(v * tex.shape[0]), 0), tex.shape[0] - 1)
                    if tex[ty, tx, 3] < alpha_cut:
                        continue
                depth[py, px] = z
                tri_id[py, px] = t
                bary[py, px, 0] = b0
                bary[py, px, 1] = b1


@njit(cache=True)
def _spheres(eye, rot, spheres, width, height, focal, depth, sid):
    for py in range(height):
        for px in range(width):
            dx = (px + 0.5 - 0.5 * width) / focal
            dy = (py + 0.5 - 0.5 * height) / focal
            # ray direction in world; depth measured along the camera's forward axis
            wx = rot[0, 0] * dx + rot[1, 0] * dy + rot[2, 0]
            wy = rot[0, 1] * dx + rot[1, 1] * dy + rot[2, 1]
            wz = rot[0, 2] * dx + rot[1, 2] * dy + rot[2, 2]
            for k in range(spheres.shape[0]):
                ox, oy, oz = eye[0] - spheres[k, 0], eye[1] - spheres[k, 1], eye[2] - spheres[k, 2]
                a = wx * wx + wy * wy + wz * wz
                b = 2.0 * (ox * wx + oy * wy + oz * wz)
                c = ox * ox + oy * oy + oz * oz - spheres[k, 3] * spheres[k, 3]
                disc = b * b - 4 * a * c
                if disc < 0.0:
                    continue
                t = (-b - sqrt(disc)) / (2 * a)
                if t > 1e-6 and t < depth[py, px]:
                    depth[py, px] = t
                    sid[py, px] = k


class Camera:
    """A pinhole camera: eye, target, vertical field of view (degrees) and image size."""

    def __init__(self, eye, target=(0.0, 0.0, 0.0), fov_deg=35.0, width=256, height=256):
        self.eye = np.asarray(eye, dtype=np.float64)
        self.rot = look_at(self.eye, target)
        self.width, self.height = int(width), int(height)
        self.focal = 0.5 * self.height / tan(np.radians(fov_deg) / 2)

    def to_camera(self, points):
        """Return points (n, 3) in camera coordinates (x right, y down, z forward)."""
        return (np.asarray(points, dtype=np.float64) - self.eye) @ self.rot.T

    def project(self, points):
        """Return (pixel x, pixel y, depth) of points (n, 3)."""
        c = self.to_camera(points)
        return (self.focal * c[:, 0] / c[:, 2] + 0.5 * self.width,
                self.focal * c[:, 1] / c[:, 2] + 0.5 * self.height, c[:, 2])

    def render_mesh(self, vertices, indices, uvs=None, texture=None, alpha_cut=128):
        """Return (depth, triangle id, barycentrics) images of a triangle mesh (-1: none)."""
        depth = np.full((self.height, self.width), np.inf)
        tri_id = np.full((self.height, self.width), -1, dtype=np.int64)
        bary = np.zeros((self.height, self.width, 2))
        tex = np.zeros((0, 0, 4), np.uint8) if texture is None else texture
        uv = np.zeros((len(vertices), 2)) if uvs is None else np.asarray(uvs, np.float64)
        view = (self.width, self.height, float(self.focal), alpha_cut)
        _raster(self.to_camera(vertices), np.asarray(indices, np.int64), uv, tex, view, depth,
                tri_id, bary)
        return depth, tri_id, bary

    def render_spheres(self, spheres):
        """Return (depth, sphere id) images of spheres (k, 4); depth along the forward axis."""
        depth = np.full((self.height, self.width), np.inf)
        sid = np.full((self.height, self.width), -1, dtype=np.int64)
        _spheres(self.eye, self.rot, np.asarray(spheres, np.float64), self.width, self.height,
                 self.focal, depth, sid)
        return depth, sid


def fibonacci_sphere(n):
    """Return n unit vectors spread evenly over the sphere."""
    i = np.arange(n) + 0.5
    z = 1 - 2 * i / n
    r = np.sqrt(1 - z * z)
    a = np.pi * (1 + 5 ** 0.5) * i
    return np.stack([r * np.cos(a), r * np.sin(a), z], axis=1)


def visible_strip_ids(mesh, spheres, camera):
    """Return the set of strip ids that some pixel's ray hits before any sphere."""
    depth, tri, _ = camera.render_mesh(mesh.vertices, mesh.indices)
    sdepth, _ = camera.render_spheres(spheres)
    hit = (tri >= 0) & (depth < sdepth)
    strip_of_tri = np.repeat(mesh.strip_ids, np.diff(mesh.strip_offsets))
    return set(int(s) for s in np.unique(strip_of_tri[tri[hit]]))
