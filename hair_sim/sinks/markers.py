"""
MarkerArray sink: textured TRIANGLE_LIST markers, written straight to CDR bytes.

Building geometry_msgs/Point objects costs about a microsecond each (DESIGN.md); the fast
path writes the serialized MarkerArray with numpy (rclpy's Publisher.publish takes bytes)
and `build_marker_array` builds the same message the slow way, for tests and reference.

Jazzy rules followed: one UV per point, under 65 000 points per marker, a constant
triangle count per (ns, id) while the LOD is unchanged (strips are grouped into markers
once; a culled strip's triangles collapse onto its root instead of disappearing), an
embedded PNG texture (texture_resource 'embedded://...', format 'png'), head frame id.
"""

import numpy as np

from hair_sim.sinks.cdr import CdrWriter

TRIANGLE_LIST = 11
MAX_POINTS = 65000
NAMESPACE = 'hair'


class MarkerLayout:
    """Which strips go into which marker, fixed for a style and render LOD."""

    def __init__(self, n_strips, tris_per_strip, max_points=MAX_POINTS):
        per = max(1, (max_points - 1) // (3 * tris_per_strip))
        self.groups = [np.arange(i, min(i + per, n_strips)) for i in range(0, n_strips, per)]
        self.tris_per_strip = tris_per_strip


def marker_geometry(mesh, R, p, layout):
    """
    Return per marker (points (n, 3) float64 head frame, uvs (n, 2) float32).

    Strips absent from `mesh` (culled) keep their slots with every point at the first
    vertex of a drawn strip's root (zero-area triangles), so the counts stay constant.
    """
    verts = (mesh.vertices.astype(np.float64) - p) @ R           # world -> head frame
    nt = layout.tris_per_strip
    tri = mesh.indices.reshape(-1, nt, 3)
    slot = {int(s): k for k, s in enumerate(mesh.strip_ids)}
    out = []
    for group in layout.groups:
        points = np.zeros((len(group), nt * 3, 3))
        uvs = np.zeros((len(group), nt * 3, 2), dtype=np.float32)
        for g, s in enumerate(group):
            k = slot.get(int(s))
            if k is None:
                if len(verts):
                    points[g] = verts[0]
                continue
            idx = tri[k].reshape(-1)
            points[g] = verts[idx]
            uvs[g] = mesh.uvs[idx]
        out.append((points.reshape(-1, 3), uvs.reshape(-1, 2)))
    return out


def marker_array_cdr(geometry, texture_id, texture_png, frame_id, sec, nanosec,
                     with_padding=False):
    """Return the serialized MarkerArray of `geometry` (and its padding ranges if asked)."""
    w = CdrWriter()
    w.uint32(len(geometry))
    resource = 'embedded://%s.png' % texture_id
    for mid, (points, uvs) in enumerate(geometry):
        w.header(sec, nanosec, frame_id)
        w.string(NAMESPACE)
        w.int32(mid)
        w.int32(TRIANGLE_LIST)
        w.int32(0)                                   # ADD
        for v in (0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0):  # pose: identity
            w.float64(v)
        for v in (1.0, 1.0, 1.0):                    # scale
            w.float64(v)
        for v in (1.0, 1.0, 1.0, 1.0):               # color: texture as it is
            w.float32(v)
        w.time(0, 0)                                 # lifetime: for ever
        w.boolean(False)                             # frame_locked
        w.array(np.asarray(points, dtype='<f8'), 8)  # geometry_msgs/Point[]
        w.uint32(0)                                  # colors[]
        w.string(resource)
        w.header(sec, nanosec, frame_id)             # texture: sensor_msgs/CompressedImage
        w.string('png')
        w.octets(texture_png)
        w.array(np.asarray(uvs, dtype='<f4'), 4)     # UVCoordinate[]
        w.string('')                                 # text
        w.string('')                                 # mesh_resource
        w.string('')                                 # mesh_file.filename
        w.uint32(0)                                  # mesh_file.data
        w.boolean(False)                             # mesh_use_embedded_materials
    return w.bytes() if not with_padding else (w.bytes(), w.padding)


def build_marker_array(geometry, texture_id, texture_png, frame_id, sec, nanosec):
    """Build the same MarkerArray with message objects (slow path; reference for tests)."""
    from geometry_msgs.msg import Point
    from visualization_msgs.msg import Marker, MarkerArray, UVCoordinate

    arr = MarkerArray()
    for mid, (points, uvs) in enumerate(geometry):
        m = Marker()
        m.header.stamp.sec, m.header.stamp.nanosec = sec, nanosec
        m.header.frame_id = frame_id
        m.ns = NAMESPACE
        m.id = mid
        m.type = Marker.TRIANGLE_LIST
        m.action = Marker.ADD
        m.pose.orientation.w = 1.0
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
