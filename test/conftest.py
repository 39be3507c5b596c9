"""Shared fixtures: a private rclpy context per test, DDS kept on loopback."""

import os
import random

import pytest

from hair_sim import paths

# Keep DDS discovery on this machine and away from any other ROS graph running here.
os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
os.environ.setdefault('ROS_DOMAIN_ID', str(random.Random(os.getpid()).randint(100, 200)))


def _worker_domain(inherited, worker):
    """
    Return the ROS domain of pytest-xdist worker `worker` ('gw0', 'gw1', ...).

    The workers inherit the domain of the pytest that started them: two tests of two
    workers then ran nodes of the same name on one graph. Each worker takes the one after
    it (before it near the top of the range, 232).
    """
    n = int(worker[2:]) + 1
    return inherited + n if inherited + n <= 232 else inherited - n


if os.environ.get('PYTEST_XDIST_WORKER', '').startswith('gw'):
    os.environ['ROS_DOMAIN_ID'] = str(_worker_domain(int(os.environ['ROS_DOMAIN_ID']),
                                                     os.environ['PYTEST_XDIST_WORKER']))


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


# Tests that start nodes, servers or subprocesses of the node run after the others, which
# share the machine's two cores (pytest-xdist, a file to a worker): `serial`. Two files of
# them run at once (a domain to a worker), except the QUIET ones, which run alone at the
# end: they take rates, latencies, the longest gap between messages or their own frame
# times against a floor, or check that a meshcat port is free after a program ended
# (another test's server may take it). In the paired pass boundary test 20 failed once on a
# gap of 0.57 s (0.5 asked), and 21 once on a /clock's books 0.3 s short (a tick of 0.1 s
# allowed: the node saw the clock's fourth tick first); rates over 2 s passed there.
SERIAL_FOLDERS = ('ros', 'robustness', 'sinks')
SERIAL_FILES = ('test_messages.py',)
QUIET = {                                   # file: its quiet tests (none named: all)
    'robustness/test_boundary.py': (                  # publishing never stops 0.5 s
        'test_7_sizes_follow_the_budget_and_loads_do_not_stop_publishing',
        'test_12_a_gale_the_solver_cannot_keep_up_with_does_not_stop_publishing',
        'test_13_a_head_mesh_that_is_no_file_here_is_drawn_as_spheres_and_nothing_waits',
        'test_14_a_simulated_clock_that_loops_back_re_anchors_and_publishing_goes_on',
        'test_16_a_system_clock_stepped_back_stops_neither_the_node_nor_the_demo_driver',
        'test_20_a_node_started_on_a_clock_that_stands_still_sends_its_hair',
        'test_21_a_coarse_or_fast_simulated_clock_is_simulated_not_dropped',  # books to
        'test_22_time_the_solver_has_no_share_of_the_wall_time_for_is_counted'),  # a tick
    'robustness/test_soak.py': (),
    'ros/test_frames.py': (),
    'ros/test_pipeline.py': (
        'test_make_demo_publishes_at_its_configured_rates',
        'test_two_avatars_in_two_namespaces_do_not_talk_across'),
    'sinks/test_meshcat.py': (),
    'sinks/test_meshcat_server.py': (),
}


# The files that hold a worker longest, started first (`make test` passes pytest-xdist
# --no-loadscope-reorder, which keeps this order): a worker then takes the short ones while
# the other is still busy, rather than one worker finishing a long file alone at the end.
# Seconds in their pass on an idle 2-core machine (2026-12-01): 214, 132 (one fresh
# compile of the package), 95, 95; 240, 50, 27.
LONGEST_FIRST = ('physics/test_articulated.py', 'test_compiled_kernels.py',
                 'modeling/test_head_fit.py', 'bench/test_cli.py',
                 'robustness/test_boundary.py', 'ros/test_pipeline.py',
                 'robustness/test_fuzz.py')


def pytest_collection_modifyitems(config, items):
    """
    Mark the tests of SERIAL_FOLDERS and SERIAL_FILES `serial`, and QUIET's `quiet`.

    And put LONGEST_FIRST's files first, in that order (the others keep theirs).
    """
    here = os.path.dirname(os.path.abspath(__file__))
    where = {item: os.path.relpath(str(item.path), here).replace(os.sep, '/') for item in items}
    items.sort(key=lambda item: LONGEST_FIRST.index(where[item])
               if where[item] in LONGEST_FIRST else len(LONGEST_FIRST))
    for item in items:
        if where[item].split('/')[0] in SERIAL_FOLDERS or where[item] in SERIAL_FILES:
            item.add_marker(pytest.mark.serial)
        quiet = QUIET.get(where[item])
        if quiet is not None and (not quiet or item.originalname in quiet):
            item.add_marker(pytest.mark.quiet)
