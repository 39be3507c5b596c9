"""Fixtures that run hair_sim_node in-process with config/hair_sim.yaml."""

import os

import pytest

from hair_sim import paths


@pytest.fixture
def node_env(tmp_path):
    """Yield (context, executor, node, client node) with the shipped params file loaded."""
    import rclpy
    from rclpy.context import Context
    from rclpy.executors import SingleThreadedExecutor

    from hair_sim.ros.node import HairSimNode

    ctx = Context()
    params = os.path.join(paths.config_dir(), 'hair_sim.yaml')
    rclpy.init(context=ctx, args=['--ros-args', '--params-file', params,
                                  '-p', 'hairstyle_dirs:=["", "%s"]' % tmp_path])
    node = HairSimNode(context=ctx)
    client = rclpy.create_node('hair_sim_test_client', context=ctx)
    ex = SingleThreadedExecutor(context=ctx)
    ex.add_node(node)
    ex.add_node(client)
    try:
        yield ctx, ex, node, client
    finally:
        ex.shutdown()
        node.destroy_node()
        client.destroy_node()
        rclpy.try_shutdown(context=ctx)
