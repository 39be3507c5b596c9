"""Publish a deterministic HairMesh on `hair_mesh_probe` until killed (cross-process tests)."""

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
    from hair_sim_msgs.msg import HairMesh

    n_vertices, seed = int(sys.argv[1]), int(sys.argv[2])
    vertices, uvs, indices, offsets = probe_mesh(n_vertices, seed)
    rclpy.init()
    node = rclpy.create_node('hair_mesh_probe_publisher')
    pub = node.create_publisher(HairMesh, 'hair_mesh_probe', 10)
    msg = HairMesh()
    msg.header.frame_id = 'head'
    msg.vertices = vertices
    msg.uvs = uvs
    msg.indices = indices
    msg.strip_offsets = offsets
    msg.texture_id = 'probe-%d' % seed
    try:
        while rclpy.ok():
            pub.publish(msg)
            time.sleep(0.1)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        node.destroy_node()
        rclpy.try_shutdown()


if __name__ == '__main__':
    main()
