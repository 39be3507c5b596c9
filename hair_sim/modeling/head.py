"""
Head models: spheres for the scalp, for collisions and the projection centre (thesis 3, 5).

A head file (`config/heads/*.yaml`) names, in the head frame (x forward, y left, z up,
metres):

- `scalp_spheres`: the union approximating the scalp boundary (thesis 3.1); hair roots sit
  on it and the U-shape projects onto it. They are collision spheres too.
- `collision_spheres`: the rest of the body the hair must not enter (face, neck, shoulders).
- `projection_sphere`: the small sphere S inside the scalp used as projection centre (3.2).
- `hairline`: where the hair region of the scalp ends, as a height that goes linearly from
  `back_z` at `back_x` to `front_z` at `front_x`; the region is the scalp above it.
"""

from dataclasses import dataclass, field
import os

import numpy as np

from hair_sim.modeling.errors import HairstyleError
from hair_sim.modeling.yamlio import read_yaml


@dataclass
class HeadModel:
    """Spheres of one head, in the head frame; each sphere is a row (cx, cy, cz, r)."""

    name: str
    frame_id: str
    scalp: np.ndarray
    body: np.ndarray
    projection_sphere: np.ndarray
    hairline: dict
    sphere_names: list = field(default_factory=list)
    path: str = ''

    @property
    def collision(self):
        """All collision spheres: the scalp spheres first, then the body spheres."""
        return np.vstack([self.scalp, self.body]) if len(self.body) else self.scalp.copy()

    def scalp_distance(self, points):
        """Signed distance of points (..., 3) to the scalp union (exact outside, < 0 inside)."""
        p = np.asarray(points, dtype=np.float64)[..., None, :]
        d = np.linalg.norm(p - self.scalp[:, :3], axis=-1) - self.scalp[:, 3]
        return d.min(axis=-1)

    def collision_distance(self, points):
        """Signed distance of points (..., 3) to the union of all collision spheres."""
        spheres = self.collision
        p = np.asarray(points, dtype=np.float64)[..., None, :]
        return (np.linalg.norm(p - spheres[:, :3], axis=-1) - spheres[:, 3]).min(axis=-1)

    def nearest_on_scalp(self, points):
        """Radially project points (..., 3) onto the scalp sphere whose surface is nearest."""
        p = np.asarray(points, dtype=np.float64)
        rel = p[..., None, :] - self.scalp[:, :3]
        dist = np.linalg.norm(rel, axis=-1)
        k = np.argmin(dist - self.scalp[:, 3], axis=-1)
        c = self.scalp[k, :3]
        r = self.scalp[k, 3]
        d = np.take_along_axis(dist, k[..., None], axis=-1)[..., 0]
        direction = (p - c) / np.maximum(d, 1e-12)[..., None]
        return c + direction * r[..., None]

    def hairline_z(self, x):
        """Height of the hairline at head-frame x (linear from back to front, clamped)."""
        h = self.hairline
        s = np.clip((np.asarray(x) - h['back_x']) / (h['front_x'] - h['back_x']), 0.0, 1.0)
        return h['back_z'] + s * (h['front_z'] - h['back_z'])

    def in_hair_region(self, points):
        """Return True for points (..., 3) above the hairline (where hair should be)."""
        p = np.asarray(points, dtype=np.float64)
        return p[..., 2] >= self.hairline_z(p[..., 0])


def _sphere_list(data, key, path, required):
    items = data.get(key)
    if items is None:
        if required:
            raise HairstyleError('head file %s: missing "%s"' % (path, key))
        return np.zeros((0, 4)), []
    if not isinstance(items, list) or (required and not items):
        raise HairstyleError('head file %s: "%s" must be a non-empty list of spheres'
                             % (path, key))
    rows, names = [], []
    for i, s in enumerate(items):
        rows.append(_sphere(s, path, '%s[%d]' % (key, i)))
        names.append(str(s.get('name', '%s%d' % (key, i))))
    return np.array(rows, dtype=np.float64).reshape(-1, 4), names


def _sphere(s, path, where):
    if not isinstance(s, dict) or 'center' not in s or 'radius' not in s:
        raise HairstyleError('head file %s: %s must be a mapping with center and radius'
                             % (path, where))
    try:
        c = np.array(s['center'], dtype=np.float64)
        r = float(s['radius'])
    except (TypeError, ValueError):
        raise HairstyleError('head file %s: %s has a non-numeric center or radius'
                             % (path, where))
    if c.shape != (3,):
        raise HairstyleError('head file %s: %s center must have 3 coordinates' % (path, where))
    if not (np.all(np.isfinite(c)) and np.isfinite(r)):
        raise HairstyleError('head file %s: %s has a non-finite number' % (path, where))
    if not 0.0 < r < 10.0:
        raise HairstyleError('head file %s: %s radius %g m is outside (0, 10)'
                             % (path, where, r))
    if np.abs(c).max() > 10.0:
        raise HairstyleError('head file %s: %s center is over 10 m from the head origin'
                             % (path, where))
    return [c[0], c[1], c[2], r]


def load_head(path):
    """Load and validate a head file; raise HairstyleError with the reason if it is bad."""
    path = os.path.abspath(path)
    data = read_yaml(path, 'head')
    scalp, scalp_names = _sphere_list(data, 'scalp_spheres', path, True)
    body, body_names = _sphere_list(data, 'collision_spheres', path, False)
    if 'projection_sphere' not in data:
        raise HairstyleError('head file %s: missing "projection_sphere"' % path)
    proj = np.array(_sphere(data['projection_sphere'], path, 'projection_sphere'))
    if np.min(np.linalg.norm(proj[:3] - scalp[:, :3], axis=1) + proj[3] - scalp[:, 3]) > 0:
        raise HairstyleError('head file %s: the projection sphere must lie inside a scalp '
                             'sphere (thesis 3.2)' % path)
    hl = data.get('hairline', {})
    try:
        hairline = {k: float(hl[k]) for k in ('front_x', 'front_z', 'back_x', 'back_z')}
    except (KeyError, TypeError, ValueError):
        raise HairstyleError('head file %s: "hairline" needs numeric front_x, front_z, '
                             'back_x, back_z' % path)
    if not all(np.isfinite(v) for v in hairline.values()) or \
            hairline['front_x'] <= hairline['back_x']:
        raise HairstyleError('head file %s: hairline needs finite values with front_x > back_x'
                             % path)
    return HeadModel(name=str(data.get('name', os.path.splitext(os.path.basename(path))[0])),
                     frame_id=str(data.get('frame_id', 'head')), scalp=scalp, body=body,
                     projection_sphere=proj, hairline=hairline,
                     sphere_names=scalp_names + body_names, path=path)
