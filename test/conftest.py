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


# Tests that start nodes, servers or subprocesses of the node and measure rates and
# latencies from outside run alone: `make test` runs them one at a time after the others,
# which share the machine's two cores (pytest-xdist, a file to a worker).
SERIAL_FOLDERS = ('ros', 'robustness', 'sinks')
SERIAL_FILES = ('test_messages.py',)


def pytest_collection_modifyitems(config, items):
    """Mark the tests of SERIAL_FOLDERS and SERIAL_FILES `serial`."""
    here = os.path.dirname(os.path.abspath(__file__))
    for item in items:
        where = os.path.relpath(str(item.path), here)
        if where.split(os.sep)[0] in SERIAL_FOLDERS or where in SERIAL_FILES:
            item.add_marker(pytest.mark.serial)
