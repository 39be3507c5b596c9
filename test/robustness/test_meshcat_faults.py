"""The meshcat server missing, killed or silent: logged, ROS goes on, it reconnects."""

import socket
import subprocess
import sys
import threading
import time

import pytest
import zmq

from helpers.ros import spin_until


def free_port():
    """Return a free TCP port on loopback."""
    with socket.socket() as s:
        s.bind(('127.0.0.1', 0))
        return s.getsockname()[1]


def start_meshcat(zmq_url):
    """Start a meshcat server on zmq_url; return the process once it listens."""
    proc = subprocess.Popen([sys.executable, '-u', '-m', 'meshcat.servers.zmqserver',
                             '--zmq-url', zmq_url], stdout=subprocess.PIPE,
                            stderr=subprocess.DEVNULL, start_new_session=True)
    deadline = time.monotonic() + 20
    while time.monotonic() < deadline:
        line = proc.stdout.readline().decode()
        if 'http' in line and 'zmq' not in line:
            break
    threading.Thread(target=lambda: [None for _ in proc.stdout], daemon=True).start()
    return proc


@pytest.fixture
def meshcat_node():
    """Yield (executor, node, states list, zmq url) of a node whose meshcat is not there."""
    from hair_sim_msgs.msg import HairState
    from helpers.ros import RunningNode
    url = 'tcp://127.0.0.1:%d' % free_port()
    run = RunningNode(['-p', 'meshcat.enabled:=true', '-p', 'meshcat.zmq_url:=%s' % url,
                       '-p', 'publish_rate:=20.0'])
    states = []
    run.client.create_subscription(HairState, 'hair_state',
                                   lambda m: states.append(time.time()), 50)
    try:
        yield run.executor, run.node, states, url
    finally:
        run.close()


def published_during(ex, states, seconds):
    """Spin for `seconds`; return how many HairState messages arrived meanwhile."""
    n0 = len(states)
    spin_until(ex, lambda: False, seconds)
    return len(states) - n0


def test_missing_then_killed_then_back(meshcat_node):
    """No server: errors, ROS at rate. Server up: frames. Killed: ROS on. Back: reconnects."""
    ex, node, states, url = meshcat_node
    assert published_during(ex, states, 5.0) >= 50            # 20 Hz for 5 s, minus start-up
    assert node.meshcat.errors >= 1 and not node.meshcat.connected
    server = start_meshcat(url)
    try:
        assert spin_until(ex, lambda: node.meshcat.frames_sent > 5, 20.0)
        assert node.meshcat_url and node.meshcat.connected
    finally:
        server.kill()
        server.wait()
    errors = node.meshcat.errors
    assert published_during(ex, states, 6.0) >= 80             # ROS does not wait
    assert node.meshcat.errors > errors
    server = start_meshcat(url)
    try:
        sent = node.meshcat.frames_sent
        assert spin_until(ex, lambda: node.meshcat.frames_sent > sent + 5, 20.0)
    finally:
        server.kill()
        server.wait()


def test_a_silent_server_does_not_stall_ros(meshcat_node):
    """A server that takes requests and never answers: time-outs, ROS keeps its rate."""
    ex, node, states, url = meshcat_node
    ctx = zmq.Context.instance()
    sock = ctx.socket(zmq.REP)
    sock.bind(url)
    stop = threading.Event()

    def swallow():
        while not stop.is_set():
            if sock.poll(100):
                sock.recv_multipart()                           # and never reply
    t = threading.Thread(target=swallow, daemon=True)
    t.start()
    try:
        assert published_during(ex, states, 8.0) >= 120
        assert node.meshcat.errors >= 1 and node.meshcat.frames_sent == 0
    finally:
        stop.set()
        t.join()
        sock.close(linger=0)


def test_a_set_of_the_running_values_keeps_the_viewer_and_a_change_restarts_it():
    """
    meshcat.enabled and zmq_url set to what runs keep the sink and its server.

    (`ros2 param load` of the file the node started with does that; the server a browser
    page was connected to used to be killed and started again.) Off stops the server; on
    starts one that streams again.
    """
    from rclpy.parameter import Parameter

    from helpers.ros import RunningNode
    run = RunningNode(['-p', 'meshcat.enabled:=true'])
    try:
        ex, node = run.executor, run.node
        sink = node.meshcat
        assert spin_until(ex, lambda: sink.frames_sent > 3, 30.0)
        server = sink._server
        for params in ([Parameter('meshcat.enabled', value=True)],
                       [Parameter('meshcat.zmq_url', value='')],
                       [Parameter('meshcat.enabled', value=True),
                        Parameter('meshcat.zmq_url', value='')]):
            assert all(r.successful for r in node.set_parameters(params))
            sent = sink.frames_sent
            assert spin_until(ex, lambda: sink.frames_sent > sent + 3, 10.0)
            assert node.meshcat is sink and sink._server is server and server.poll() is None
        assert all(r.successful for r in node.set_parameters(
            [Parameter('meshcat.enabled', value=False)]))
        assert node.meshcat is None and server.poll() is not None
        assert all(r.successful for r in node.set_parameters(
            [Parameter('meshcat.enabled', value=True)]))
        assert node.meshcat is not sink
        assert spin_until(ex, lambda: node.meshcat.frames_sent > 3, 30.0)
    finally:
        run.close()
