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

from hair_sim.modeling import fields
from hair_sim.modeling.errors import HairstyleError
from hair_sim.modeling.yamlio import read_yaml
from hair_sim.vecmath import nearest_on_spheres_many


@dataclass
class HeadModel:
    """Spheres of one head, in the head frame; each sphere is a row (cx, cy, cz, r)."""

    name: str
    frame_id: str
    scalp: np.ndarray
    body: np.ndarray
    projection_sphere: np.ndarray
    hairline: dict
    mesh: str = ''                     # optional display mesh (file name next to the head file)
    path: str = ''
    # the display mesh as first read: ((vertices, triangles) or None, the error or None)
    _display: tuple = field(default=None, init=False, repr=False, compare=False)

    def display_mesh(self):
        """
        Return (vertices (n, 3), triangles (m, 3)) of the head's display mesh, or None.

        The mesh is a file in the head file's own directory: a symlink leading out of it is
        refused (ValueError), as the hairstyle directories refuse one, and so is anything
        but a regular file (OSError; a FIFO would stall its reader for ever). It is read
        once (load once, display per frame): later calls return the same read-only arrays,
        or raise the same error, without touching the disk. The node reads it where it
        builds a scene, so its publishing thread never does.
        """
        if self._display is None:
            try:
                self._display = (self._read_display_mesh(), None)
            except (OSError, ValueError) as exc:           # GlbError is a ValueError
                self._display = (None, exc)
        mesh, error = self._display
        if error is not None:
            raise error
        return mesh

    def _read_display_mesh(self):
        if not self.mesh:
            return None
        from hair_sim.modeling.glb import GlbError, read_glb
        folder = os.path.dirname(os.path.realpath(self.path))
        real = os.path.realpath(os.path.join(folder, self.mesh))
        if os.path.dirname(real) != folder:
            raise GlbError('%s leads out of %s (symlink)' % (self.mesh, folder))
        vertices, triangles = read_glb(real)
        vertices.flags.writeable = False
        triangles.flags.writeable = False
        return vertices, triangles

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
        flat = np.ascontiguousarray(p.reshape(-1, 3))
        out = nearest_on_spheres_many(flat, np.ascontiguousarray(self.scalp),
                                      np.empty_like(flat))
        return out.reshape(p.shape)

    def hairline_z(self, x):
        """Height of the hairline at head-frame x (linear from back to front, clamped)."""
        h = self.hairline
        s = np.clip((np.asarray(x) - h['back_x']) / (h['front_x'] - h['back_x']), 0.0, 1.0)
        return h['back_z'] + s * (h['front_z'] - h['back_z'])

    def in_hair_region(self, points):
        """Return True for points (..., 3) above the hairline (where hair should be)."""
        p = np.asarray(points, dtype=np.float64)
        return p[..., 2] >= self.hairline_z(p[..., 0])


MAX_SPHERES = 63               # collision spheres in all (a 64-bit mask per strand)
MAX_EXTENT = 2.0              # m: centres and hairline within this of the head origin
MAX_RADIUS = 1.0              # m
HEAD_KEYS = {'name', 'frame_id', 'scalp_spheres', 'collision_spheres', 'projection_sphere',
             'hairline', 'mesh'}


def _sphere_list(data, key, path, required):
    items = data.get(key)
    where = 'head file %s' % path
    if items is None:
        if required:
            raise HairstyleError('%s: missing "%s"' % (where, key))
        return np.zeros((0, 4))
    if not isinstance(items, list) or (required and not items):
        raise HairstyleError('%s: "%s" must be a non-empty list of spheres' % (where, key))
    if len(items) > MAX_SPHERES:
        raise HairstyleError('%s: %d %s is over the limit of %d spheres'
                             % (where, len(items), key, MAX_SPHERES))
    rows = [_sphere(s, path, '%s[%d]' % (key, i)) for i, s in enumerate(items)]
    return np.array(rows, dtype=np.float64).reshape(-1, 4)


def _sphere(s, path, name):
    where = 'head file %s: %s' % (path, name)
    if not isinstance(s, dict) or 'center' not in s or 'radius' not in s:
        raise HairstyleError('%s must be a mapping with center and radius' % where)
    fields.require_mapping(s, 'the sphere', where, {'name', 'center', 'radius'})
    if 'name' in s:
        fields.string(s['name'], 'name', where, 64)
    c = fields.numeric_array(s['center'], 'center', where, 1, MAX_EXTENT, (3,))
    r = fields.number(s['radius'], 'radius', 0.0, MAX_RADIUS, where)
    if r <= 0.0:
        raise HairstyleError('%s: radius must be positive' % where)
    return [c[0], c[1], c[2], r]


def load_head(path):
    """Load and validate a head file; raise HairstyleError with the reason if it is bad."""
    path = os.path.abspath(path)
    data = read_yaml(path, 'head')
    where = 'head file %s' % path
    fields.require_mapping(data, 'the head', where, HEAD_KEYS)
    scalp = _sphere_list(data, 'scalp_spheres', path, True)
    body = _sphere_list(data, 'collision_spheres', path, False)
    if len(scalp) + len(body) > MAX_SPHERES:
        raise HairstyleError('%s: %d collision spheres in all is over the limit of %d'
                             % (where, len(scalp) + len(body), MAX_SPHERES))
    if 'projection_sphere' not in data:
        raise HairstyleError('%s: missing "projection_sphere"' % where)
    proj = np.array(_sphere(data['projection_sphere'], path, 'projection_sphere'))
    if np.min(np.linalg.norm(proj[:3] - scalp[:, :3], axis=1) + proj[3] - scalp[:, 3]) > 0:
        raise HairstyleError('%s: the projection sphere must lie inside a scalp sphere '
                             '(thesis 3.2)' % where)
    hl = data.get('hairline')
    keys = ('front_x', 'front_z', 'back_x', 'back_z')
    if not isinstance(hl, dict) or any(k not in hl for k in keys):
        raise HairstyleError('%s: "hairline" needs numeric front_x, front_z, back_x, back_z'
                             % where)
    fields.require_mapping(hl, 'hairline', where, set(keys))
    hairline = {k: fields.number(hl[k], 'hairline.' + k, -MAX_EXTENT, MAX_EXTENT, where)
                for k in keys}
    if hairline['front_x'] <= hairline['back_x']:
        raise HairstyleError('%s: hairline needs front_x > back_x' % where)
    name = fields.string(data.get('name', os.path.splitext(os.path.basename(path))[0]),
                         'name', where, 64)
    frame = fields.frame_id(data.get('frame_id', 'head'), 'frame_id', where)
    mesh = fields.string(data['mesh'], 'mesh', where, 200) if 'mesh' in data else ''
    if mesh:
        # a display mesh: a GLB file next to the head file (no paths: nothing else is read)
        if os.path.basename(mesh) != mesh or mesh.startswith('.') \
                or not mesh.lower().endswith('.glb'):
            raise HairstyleError('%s: mesh must be the name of a .glb file next to the head '
                                 'file, not %r' % (where, mesh))
        # (a missing file is not an error here: the mesh is only drawn; the viewer falls
        # back to the spheres and says why)
    return HeadModel(name=name, frame_id=frame, scalp=scalp, body=body,
                     projection_sphere=proj, hairline=hairline, mesh=mesh, path=path)
