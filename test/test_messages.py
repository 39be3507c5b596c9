"""hair_sim_msgs round trips: in-process pub/sub, serialisation and a second process."""

import os
import subprocess
import sys

import numpy as np
from rclpy.executors import SingleThreadedExecutor
from rclpy.serialization import deserialize_message, serialize_message

from helpers.mesh_publisher import probe_mesh
from helpers.ros import spin_until

HERE = os.path.dirname(os.path.abspath(__file__))


def test_wind_in_process_round_trip(ros_context):
    """A Wind published in-process arrives with every field intact."""
    import rclpy
    from hair_sim_msgs.msg import Wind

    node = rclpy.create_node('wind_round_trip', context=ros_context)
    executor = SingleThreadedExecutor(context=ros_context)
    executor.add_node(node)
    received = []
    node.create_subscription(Wind, 'wind_probe', received.append, 10)
    pub = node.create_publisher(Wind, 'wind_probe', 10)
    msg = Wind()
    msg.header.frame_id = 'world'
    msg.header.stamp.sec = 12
    msg.velocity.x, msg.velocity.y, msg.velocity.z = 3.5, -1.25, 0.5
    msg.turbulence = 0.3
    msg.seed = 4242

    def got_one():
        if not received:
            pub.publish(msg)
        return bool(received)

    assert spin_until(executor, got_one, 10.0)
    got = received[0]
    assert got.header.frame_id == 'world' and got.header.stamp.sec == 12
    assert (got.velocity.x, got.velocity.y, got.velocity.z) == (3.5, -1.25, 0.5)
    assert got.turbulence == 0.3 and got.seed == 4242
    executor.shutdown()
    node.destroy_node()


def test_services_have_the_documented_fields():
    """The three hairstyle services carry their request fields and answer success/message."""
    from hair_sim_msgs.srv import EditControlPoint, LoadHairstyle, SaveHairstyle

    for srv in (LoadHairstyle, SaveHairstyle, EditControlPoint):
        resp = srv.Response(success=True, message='ok')
        back = deserialize_message(serialize_message(resp), srv.Response)
        assert back.success and back.message == 'ok'
    req = EditControlPoint.Request(patch=1, control_hair=2, control_point=3)
    req.position.x = 0.05
    back = deserialize_message(serialize_message(req), EditControlPoint.Request)
    assert (back.patch, back.control_hair, back.control_point, back.position.x) == (1, 2, 3, 0.05)
    assert LoadHairstyle.Request(path='a.yaml').path == 'a.yaml'


def test_hair_mesh_cross_process_round_trip(ros_context):
    """A HairMesh and its topology (3000 vertices) from another process arrive exactly."""
    import rclpy
    from hair_sim_msgs.msg import HairMesh, HairMeshTopology

    n_vertices, seed = 3000, 17
    proc = subprocess.Popen([sys.executable, os.path.join(HERE, 'helpers', 'mesh_publisher.py'),
                             str(n_vertices), str(seed)],
                            env=dict(os.environ, PYTHONPATH=HERE))
    node = rclpy.create_node('hair_mesh_receiver', context=ros_context)
    executor = SingleThreadedExecutor(context=ros_context)
    executor.add_node(node)
    received, topologies = [], []
    node.create_subscription(HairMesh, 'hair_mesh_probe', received.append, 10)
    node.create_subscription(HairMeshTopology, 'hair_mesh_topology_probe', topologies.append,
                             10)
    try:
        assert spin_until(executor, lambda: bool(received and topologies), 30.0), \
            'no HairMesh or HairMeshTopology from the publisher'
    finally:
        proc.terminate()
        proc.wait(timeout=10)
        executor.shutdown()
        node.destroy_node()
    vertices, uvs, indices, offsets = probe_mesh(n_vertices, seed)
    got, top = received[0], topologies[0]
    np.testing.assert_array_equal(np.asarray(got.vertices, dtype=np.float32), vertices)
    np.testing.assert_array_equal(np.asarray(got.strip_ids, dtype=np.uint32),
                                  np.arange(len(offsets) - 1))
    np.testing.assert_array_equal(np.asarray(top.uvs, dtype=np.float32), uvs)
    np.testing.assert_array_equal(np.asarray(top.indices, dtype=np.uint32), indices)
    np.testing.assert_array_equal(np.asarray(top.strip_offsets, dtype=np.uint32), offsets)
    assert bytes(top.texture_png) == bytes(range(256))
    assert top.texture_id == 'probe-%d' % seed and got.header.frame_id == 'head'
    assert got.topology_id == top.topology_id == seed
