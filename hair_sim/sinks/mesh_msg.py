"""
hair_sim_msgs/HairMesh, HairMeshTopology and HairState as CDR bytes (numpy).

With slow-path references built with the message classes (the tests compare the two).
HairMesh carries what changes every frame (the vertices and which strips they are of);
HairMeshTopology what changes only with the style, its level of detail or its material.
"""

import numpy as np

from hair_sim.sinks.cdr import CdrWriter


def hair_mesh_cdr(vertices, strip_ids, topology_id, frame_id, sec, nanosec,
                  with_padding=False):
    """Serialize a HairMesh: vertices (N, 3) of the strips strip_ids, in frame_id."""
    w = CdrWriter()
    w.header(sec, nanosec, frame_id)
    w.uint32(topology_id)
    w.array(np.asarray(strip_ids, dtype='<u4'), 4)
    w.array(np.asarray(vertices, dtype='<f4').reshape(-1), 4)
    return w.bytes() if not with_padding else (w.bytes(), w.padding)


def build_hair_mesh(vertices, strip_ids, topology_id, frame_id, sec, nanosec):
    """Build the same HairMesh with the message class (slow path; reference)."""
    from hair_sim_msgs.msg import HairMesh

    m = HairMesh()
    m.header.stamp.sec, m.header.stamp.nanosec = sec, nanosec
    m.header.frame_id = frame_id
    m.topology_id = topology_id
    m.strip_ids = np.asarray(strip_ids, dtype=np.uint32)
    m.vertices = np.asarray(vertices, dtype=np.float32).reshape(-1)
    return m


def hair_mesh_topology_cdr(topology, topology_id, frame_id, sec, nanosec, with_padding=False):
    """Serialize a HairMeshTopology of a renderer's MeshTopology (every strip of the style)."""
    w = CdrWriter()
    w.header(sec, nanosec, frame_id)
    w.uint32(topology_id)
    w.uint32(topology.n_strips)
    w.uint32(topology.verts_per_strip)
    w.uint32(topology.tris_per_strip)
    w.array(np.asarray(topology.uvs, dtype='<f4').reshape(-1), 4)
    w.array(np.asarray(topology.indices, dtype='<u4').reshape(-1), 4)
    w.array(np.asarray(topology.strip_offsets, dtype='<u4'), 4)
    w.string(topology.texture_id)
    w.octets(topology.texture_png)
    return w.bytes() if not with_padding else (w.bytes(), w.padding)


def build_hair_mesh_topology(topology, topology_id, frame_id, sec, nanosec):
    """Build the same HairMeshTopology with the message class (slow path; reference)."""
    from hair_sim_msgs.msg import HairMeshTopology

    m = HairMeshTopology()
    m.header.stamp.sec, m.header.stamp.nanosec = sec, nanosec
    m.header.frame_id = frame_id
    m.topology_id = topology_id
    m.n_strips = topology.n_strips
    m.vertices_per_strip = topology.verts_per_strip
    m.triangles_per_strip = topology.tris_per_strip
    m.uvs = np.asarray(topology.uvs, dtype=np.float32).reshape(-1)
    m.indices = np.asarray(topology.indices, dtype=np.uint32).reshape(-1)
    m.strip_offsets = np.asarray(topology.strip_offsets, dtype=np.uint32)
    m.texture_id = topology.texture_id
    m.texture_png = bytes(topology.texture_png)
    return m


def hair_state_cdr(positions, sleeping, step_time, frame_id, sec, nanosec,
                   with_padding=False):
    """Serialize a HairState message of strand positions (n_strands, n_vertices, 3)."""
    w = CdrWriter()
    w.header(sec, nanosec, frame_id)
    w.uint32(positions.shape[0])
    w.uint32(positions.shape[1])
    w.array(np.asarray(positions, dtype='<f4').reshape(-1), 4)
    w.boolean(sleeping)
    w.float64(step_time)
    return w.bytes() if not with_padding else (w.bytes(), w.padding)
