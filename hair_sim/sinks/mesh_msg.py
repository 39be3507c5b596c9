"""hair_sim_msgs/HairMesh and HairState as CDR bytes (numpy), with slow-path references."""

import numpy as np

from hair_sim.sinks.cdr import CdrWriter


def hair_mesh_cdr(mesh, vertices, frame_id, sec, nanosec, with_texture=True,
                  with_padding=False):
    """Serialize a HairMesh message of `mesh` with `vertices` (N, 3) in frame_id."""
    w = CdrWriter()
    w.header(sec, nanosec, frame_id)
    w.array(np.asarray(vertices, dtype='<f4').reshape(-1), 4)
    w.array(np.asarray(mesh.uvs, dtype='<f4').reshape(-1), 4)
    w.array(np.asarray(mesh.indices, dtype='<u4').reshape(-1), 4)
    w.array(np.asarray(mesh.strip_offsets, dtype='<u4'), 4)
    w.array(np.asarray(mesh.strip_ids, dtype='<u4'), 4)
    w.string(mesh.texture_id)
    w.octets(mesh.texture_png if with_texture else b'')
    return w.bytes() if not with_padding else (w.bytes(), w.padding)


def build_hair_mesh(mesh, vertices, frame_id, sec, nanosec, with_texture=True):
    """Build the same HairMesh with the message class (slow path; reference)."""
    from hair_sim_msgs.msg import HairMesh

    m = HairMesh()
    m.header.stamp.sec, m.header.stamp.nanosec = sec, nanosec
    m.header.frame_id = frame_id
    m.vertices = np.asarray(vertices, dtype=np.float32).reshape(-1)
    m.uvs = np.asarray(mesh.uvs, dtype=np.float32).reshape(-1)
    m.indices = np.asarray(mesh.indices, dtype=np.uint32).reshape(-1)
    m.strip_offsets = np.asarray(mesh.strip_offsets, dtype=np.uint32)
    m.strip_ids = np.asarray(mesh.strip_ids, dtype=np.uint32)
    m.texture_id = mesh.texture_id
    m.texture_png = bytes(mesh.texture_png) if with_texture else b''
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
