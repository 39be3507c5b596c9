"""Shared fixtures: a private rclpy context per test, DDS kept on loopback."""

import os
import random

import pytest

from hair_sim import paths

# Keep DDS discovery on this machine and away from any other ROS graph running here.
os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
os.environ.setdefault('ROS_DOMAIN_ID', str(random.Random(os.getpid()).randint(100, 200)))


@pytest.fixture
def ros_context():
    """Yield an initialised private rclpy context, shut down after the test."""
    import rclpy
    from rclpy.context import Context

    context = Context()
    rclpy.init(context=context)
    try:
        yield context
    finally:
        rclpy.try_shutdown(context=context)


@pytest.fixture
def node_env(tmp_path):
    """Yield (context, executor, node, client node) with the shipped params file loaded."""
    from helpers.ros import RunningNode

    params = os.path.join(paths.config_dir(), 'hair_sim.yaml')
    run = RunningNode(['--params-file', params, '-p', 'hairstyle_dirs:=["", "%s"]' % tmp_path])
    try:
        yield run.context, run.executor, run.node, run.client
    finally:
        run.close()
