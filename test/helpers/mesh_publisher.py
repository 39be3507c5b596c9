"""
Publish a deterministic HairMesh and HairMeshTopology until killed (cross-process tests).

On `hair_mesh_probe` and `hair_mesh_topology_probe`.
"""

import sys
import time

import numpy as np
import rclpy
from rclpy.executors import ExternalShutdownException


def probe_mesh(n_vertices, seed):
    """Return the deterministic arrays (vertices, uvs, indices, offsets) a probe mesh carries."""
    rng = np.random.default_rng(seed)
    vertices = rng.uniform(-1.0, 1.0, size=3 * n_vertices).astype(np.float32)
    uvs = rng.uniform(0.0, 1.0, size=2 * n_vertices).astype(np.float32)
    indices = rng.integers(0, n_vertices, size=3 * (2 * n_vertices)).astype(np.uint32)
    offsets = np.arange(0, 2 * n_vertices + 1, 64, dtype=np.uint32)
    return vertices, uvs, indices, offsets


def main():
    """Publish the probe mesh at 10 Hz."""
    from hair_sim_msgs.msg import HairMesh, HairMeshTopology

    n_vertices, seed = int(sys.argv[1]), int(sys.argv[2])
    vertices, uvs, indices, offsets = probe_mesh(n_vertices, seed)
    rclpy.init()
    node = rclpy.create_node('hair_mesh_probe_publisher')
    pub = node.create_publisher(HairMesh, 'hair_mesh_probe', 10)
    pub_topology = node.create_publisher(HairMeshTopology, 'hair_mesh_topology_probe', 10)
    msg = HairMesh()
    msg.header.frame_id = 'head'
    msg.topology_id = seed
    msg.strip_ids = np.arange(len(offsets) - 1, dtype=np.uint32)
    msg.vertices = vertices
    topology = HairMeshTopology()
    topology.topology_id = seed
    topology.n_strips = len(offsets) - 1
    topology.uvs = uvs
    topology.indices = indices
    topology.strip_offsets = offsets
    topology.texture_id = 'probe-%d' % seed
    topology.texture_png = bytes(range(256))
    try:
        while rclpy.ok():
            pub.publish(msg)
            pub_topology.publish(topology)
            time.sleep(0.1)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        node.destroy_node()
        rclpy.try_shutdown()


if __name__ == '__main__':
    main()
