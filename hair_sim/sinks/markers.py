"""
MarkerArray sink: textured TRIANGLE_LIST markers, written straight to CDR bytes.

Building geometry_msgs/Point objects costs about a microsecond each (230 ms for 65k
points); the fast path writes the serialized MarkerArray with numpy (rclpy's
Publisher.publish takes bytes) and `build_marker_array` builds the same message the slow
way, for tests and reference.

Jazzy rules followed: one UV per point, under 65 000 points per marker, a constant
triangle count per (ns, id) while the LOD is unchanged (strips are grouped into markers
once; a culled strip's triangles collapse onto its root instead of disappearing), an
embedded PNG texture (texture_resource 'embedded://...', format 'png'); points in the world
frame, or in the head frame with frame_locked set; DELETEALL before a new layout.
"""

import struct

import numpy as np

from hair_sim.kernels import njit_without_refcounts
from hair_sim.sinks.cdr import CdrWriter

TRIANGLE_LIST = 11
MAX_POINTS = 65000
NAMESPACE = 'hair'
HEAD_NAMESPACE = 'head'
SKIN_RGB = 0xddb49a                  # the head's colour, in meshcat too
HEAD_COLOR = tuple(((SKIN_RGB >> k) & 0xff) / 255.0 for k in (16, 8, 0)) + (1.0,)


class MarkerLayout:
    """
    Which strips go into which marker, fixed for a style and render LOD.

    The UV of every marker point depends only on the style and LOD (a culled strip keeps
    its UVs under its collapsed points), so they are taken once from a full mesh.
    """

    def __init__(self, n_strips, tris_per_strip, full_mesh=None, max_points=MAX_POINTS):
        per = max(1, (max_points - 1) // (3 * tris_per_strip))
        self.groups = [np.arange(i, min(i + per, n_strips)) for i in range(0, n_strips, per)]
        self.tris_per_strip = tris_per_strip
        self.n_strips = n_strips
        self.uv_points = None
        if full_mesh is not None:
            if full_mesh.n_strips != n_strips:
                raise ValueError('the layout needs a mesh of every strip')
            self.uv_points = np.ascontiguousarray(full_mesh.uvs[full_mesh.indices.reshape(-1)])


@njit_without_refcounts
def _gather_points(vertices, indices, slot, nt3, R, p, out):
    """
    Write head-frame points of every strip slot (slot[s] < 0: collapsed onto vertex 0).

    indices: the mesh's triangle corners, flat (any integer type).
    """
    for s in range(slot.shape[0]):
        k = slot[s]
        for q in range(nt3):
            o = s * nt3 + q
            v = 0 if k < 0 else indices[k * nt3 + q]
            x = vertices[v, 0] - p[0]
            y = vertices[v, 1] - p[1]
            z = vertices[v, 2] - p[2]
            out[o, 0] = R[0, 0] * x + R[1, 0] * y + R[2, 0] * z
            out[o, 1] = R[0, 1] * x + R[1, 1] * y + R[2, 1] * z
            out[o, 2] = R[0, 2] * x + R[1, 2] * y + R[2, 2] * z


def marker_geometry(mesh, R, p, layout):
    """
    Return per marker (points (n, 3) float64 head frame, uvs (n, 2) float32).

    Strips absent from `mesh` (culled) keep their slots with every point at the mesh's
    first vertex (zero-area triangles), so the counts stay constant.
    """
    nt3 = layout.tris_per_strip * 3
    slot = np.full(layout.n_strips, -1, dtype=np.int64)
    slot[mesh.strip_ids.astype(np.int64)] = np.arange(mesh.n_strips)
    points = np.empty((layout.n_strips * nt3, 3))
    _gather_points(mesh.vertices, mesh.indices.reshape(-1).astype(np.int64), slot, nt3,
                   np.ascontiguousarray(R, dtype=np.float64), np.asarray(p, dtype=np.float64),
                   points)
    if layout.uv_points is not None:
        uvs = layout.uv_points
    else:
        uvs = np.zeros((layout.n_strips * nt3, 2), dtype=np.float32)
        drawn = (mesh.strip_ids.astype(np.int64)[:, None] * nt3 + np.arange(nt3)).reshape(-1)
        uvs[drawn] = mesh.uvs[mesh.indices.reshape(-1)]
    return [(points[g[0] * nt3:(g[-1] + 1) * nt3], uvs[g[0] * nt3:(g[-1] + 1) * nt3])
            for g in layout.groups]


def _write_triangle_list(w, ns, mid, points, uvs, color, resource, texture_png, frame_id,
                         sec, nanosec, frame_locked):
    """
    Write one TRIANGLE_LIST visualization_msgs/Marker.

    Return ((offsets of its two stamps), offset of its points, point count).
    """
    stamps = [w.offset_of_next(4)]
    w.header(sec, nanosec, frame_id)
    w.string(ns)
    w.int32(mid)
    w.int32(TRIANGLE_LIST)
    w.int32(0)                                   # ADD
    for v in (0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0):  # pose: identity
        w.float64(v)
    for v in (1.0, 1.0, 1.0):                    # scale
        w.float64(v)
    for v in color:                              # color (white: the texture as it is)
        w.float32(v)
    w.time(0, 0)                                 # lifetime: for ever
    w.boolean(frame_locked)                      # frame_locked
    start = w.array(np.asarray(points, dtype='<f8'), 8)   # geometry_msgs/Point[]
    w.uint32(0)                                  # colors[]
    w.string(resource)
    stamps.append(w.offset_of_next(4))
    w.header(sec, nanosec, frame_id)             # texture: sensor_msgs/CompressedImage
    w.string('png' if texture_png else '')
    w.octets(texture_png)
    w.array(np.asarray(uvs, dtype='<f4'), 4)     # UVCoordinate[]
    w.string('')                                 # text
    w.string('')                                 # mesh_resource
    w.string('')                                 # mesh_file.filename
    w.uint32(0)                                  # mesh_file.data
    w.boolean(False)                             # mesh_use_embedded_materials
    return stamps, start, len(points)


def head_marker_cdr(vertices, triangles, frame_id, sec, nanosec, frame_locked=True,
                    color=HEAD_COLOR):
    """
    Return the serialized MarkerArray of a head's display mesh (skin-coloured markers).

    The vertices are in frame_id: the head frame (frame_locked, sent once per head) or the
    world frame under the current head pose (sent again when the head moves), on the same
    rules as the hair's markers.
    """
    points = np.asarray(vertices, dtype=np.float64)[np.asarray(triangles).reshape(-1)]
    per_marker = MAX_POINTS - MAX_POINTS % 3
    chunks = [points[i:i + per_marker] for i in range(0, len(points), per_marker)]
    w = CdrWriter()
    w.uint32(len(chunks))
    for mid, chunk in enumerate(chunks):
        _write_triangle_list(w, HEAD_NAMESPACE, mid, chunk, np.zeros((0, 2), np.float32),
                             color, '', b'', frame_id, sec, nanosec, frame_locked)
    return w.bytes()


def marker_array_cdr(geometry, texture_id, texture_png, frame_id, sec, nanosec,
                     with_padding=False, offsets=None, frame_locked=False):
    """
    Return the serialized MarkerArray of `geometry` (and its padding ranges if asked).

    offsets, a list, receives per marker the byte offsets of its two stamps and of its
    points, so an encoder can rewrite just those in a copy (MarkerEncoder).
    """
    w = CdrWriter()
    w.uint32(len(geometry))
    resource = 'embedded://%s.png' % texture_id
    for mid, (points, uvs) in enumerate(geometry):
        where = _write_triangle_list(w, NAMESPACE, mid, points, uvs, (1.0, 1.0, 1.0, 1.0),
                                     resource, texture_png, frame_id, sec, nanosec,
                                     frame_locked)
        if offsets is not None:
            offsets.append(where)
    return w.bytes() if not with_padding else (w.bytes(), w.padding)


class MarkerEncoder:
    """
    Serialize hair MarkerArrays fast.

    The message is laid out once per layout and texture (all constant fields, texture and
    UVs); a frame writes only its stamps and points.
    """

    def __init__(self, layout, texture_id, texture_png, frame_id, frame_locked=False):
        self.layout = layout
        self.texture_id = texture_id
        self.frame_id = frame_id
        nt3 = 3 * layout.tris_per_strip
        points = np.zeros((layout.n_strips * nt3, 3))
        uvs = layout.uv_points if layout.uv_points is not None else np.zeros(
            (len(points), 2), np.float32)
        geo = [(points[g[0] * nt3:(g[-1] + 1) * nt3], uvs[g[0] * nt3:(g[-1] + 1) * nt3])
               for g in layout.groups]
        self.offsets = []
        self.template = bytearray(marker_array_cdr(geo, texture_id, texture_png, frame_id,
                                                   0, 0, offsets=self.offsets,
                                                   frame_locked=frame_locked))
        # each marker's points, as (n, 3) float64 views of the template: a frame's points
        # are written where they are sent from, not gathered and then copied there
        self._points = [np.frombuffer(self.template, dtype='<f8', count=3 * n,
                                      offset=start).reshape(n, 3)
                        for _, start, n in self.offsets]
        self._slot = np.full(layout.n_strips, -1, dtype=np.int64)

    def encode(self, mesh, R, p, sec, nanosec):
        """Return the serialized MarkerArray of `mesh` (world) under head pose (R, p)."""
        nt3 = 3 * self.layout.tris_per_strip
        self._slot[:] = -1
        self._slot[mesh.strip_ids.astype(np.int64)] = np.arange(mesh.n_strips)
        indices = mesh.indices.reshape(-1)
        R = np.ascontiguousarray(R, dtype=np.float64)
        p = np.asarray(p, dtype=np.float64)
        buf = self.template
        for (stamps, _, _), group, points in zip(self.offsets, self.layout.groups,
                                                 self._points):
            for off in stamps:
                struct.pack_into('<iI', buf, off, sec, nanosec)
            _gather_points(mesh.vertices, indices, self._slot[group[0]:group[-1] + 1], nt3, R,
                           p, points)
        return bytes(buf)


def delete_all_markers(frame_id, sec, nanosec):
    """Return a MarkerArray that clears every marker (sent before a new layout)."""
    from visualization_msgs.msg import Marker, MarkerArray
    m = Marker()
    m.header.frame_id = frame_id
    m.header.stamp.sec, m.header.stamp.nanosec = sec, nanosec
    m.ns = NAMESPACE
    m.action = Marker.DELETEALL
    return MarkerArray(markers=[m])


def _new_marker(kind, ns, mid, frame_id, sec, nanosec, frame_locked):
    """Return a visualization_msgs/Marker to ADD, its header and identity filled in."""
    from visualization_msgs.msg import Marker
    m = Marker()
    m.header.stamp.sec, m.header.stamp.nanosec = sec, nanosec
    m.header.frame_id = frame_id
    m.ns = ns
    m.id = mid
    m.type = kind
    m.action = Marker.ADD
    m.pose.orientation.w = 1.0
    m.frame_locked = frame_locked
    return m


def head_sphere_markers(spheres, frame_id, sec, nanosec, frame_locked=True, color=HEAD_COLOR):
    """Return a MarkerArray of SPHERE markers, one per collision sphere (no display mesh)."""
    from visualization_msgs.msg import Marker, MarkerArray
    arr = MarkerArray()
    for mid, s in enumerate(spheres):
        m = _new_marker(Marker.SPHERE, HEAD_NAMESPACE, mid, frame_id, sec, nanosec,
                        frame_locked)
        m.pose.position.x, m.pose.position.y, m.pose.position.z = (float(x) for x in s[:3])
        m.scale.x = m.scale.y = m.scale.z = 2.0 * float(s[3])
        m.color.r, m.color.g, m.color.b, m.color.a = color
        arr.markers.append(m)
    return arr


def build_marker_array(geometry, texture_id, texture_png, frame_id, sec, nanosec,
                       frame_locked=False):
    """Build the same MarkerArray with message objects (slow path; reference for tests)."""
    from geometry_msgs.msg import Point
    from visualization_msgs.msg import Marker, MarkerArray, UVCoordinate

    arr = MarkerArray()
    for mid, (points, uvs) in enumerate(geometry):
        m = _new_marker(Marker.TRIANGLE_LIST, NAMESPACE, mid, frame_id, sec, nanosec,
                        frame_locked)
        m.scale.x = m.scale.y = m.scale.z = 1.0
        m.color.r = m.color.g = m.color.b = m.color.a = 1.0
        m.points = [Point(x=float(x), y=float(y), z=float(z)) for x, y, z in points]
        m.texture_resource = 'embedded://%s.png' % texture_id
        m.texture.header = m.header
        m.texture.format = 'png'
        m.texture.data = bytes(texture_png)
        m.uv_coordinates = [UVCoordinate(u=float(u), v=float(v)) for u, v in uvs]
        arr.markers.append(m)
    return arr
