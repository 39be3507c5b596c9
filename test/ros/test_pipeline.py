"""
The node as a pipeline meets it.

The demo measured from another process, discovery left to the user, and two avatars in two
namespaces without cross-talk.

Rates here are functional floors (>= 80 % of the configured rate catches a collapse such
as the 2 Hz demo); the speed claims live in `hair_sim_bench node`.
"""

import json
import os
import subprocess
import sys
import time

import numpy as np
import psutil
import pytest

from helpers.node_process import (Client, diagnostics_values, NodeProcess, probe_rates,
                                  process_running, read_until, wait_for)

HERE = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
BIN = os.path.dirname(sys.executable)


def read_url(proc, timeout):
    """Read the demo's stdout until its 'URL ...' line."""
    line = read_until(proc, lambda line: line.startswith('URL '), timeout, 'the demo\'s URL')[-1]
    return line.split()[1]


@pytest.mark.parametrize('model, sim_rate', [('anjyo', 240.0), ('articulated', 60.0)])
def test_make_demo_publishes_at_its_configured_rates(model, sim_rate):
    """
    hair_sim_demo as `make demo` runs it; a raw subscriber in another process measures.

    With the default (thesis) model, and with the exact chain at one step per frame as the
    README tells users to run it (DEMO_ARGS="--ros-args -p physics.model:=articulated -p
    sim_rate:=60.0"); the node's diagnostics say which model and rate ran.
    """
    args = [] if model == 'anjyo' else ['--ros-args', '-p', 'physics.model:=%s' % model,
                                        '-p', 'sim_rate:=%r' % sim_rate]
    demo = subprocess.Popen([os.path.join(BIN, 'hair_sim_demo'), '--duration', '60'] + args,
                            stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
    try:
        url = read_url(demo, 90.0)
        out = subprocess.run([sys.executable, '-m', 'hair_sim.bench.probe', '--duration', '6',
                              '--warmup', '3', '--meshcat-url', url],
                             capture_output=True, text=True, timeout=120)
        assert demo.poll() is None, 'the demo ended early'
    finally:
        demo.terminate()
        demo.wait(timeout=30)
    report = json.loads(out.stdout)
    node = report['/']
    # shipped rates: publish_rate 30 (hair_mesh, hair_state), marker_rate 10, meshcat 20
    for topic, hz in (('hair_mesh', 30.0), ('hair_state', 30.0), ('hair_markers', 10.0)):
        assert node[topic]['rate_hz'] >= 0.8 * hz, (topic, node[topic])
    assert node['poses_sent_hz'] >= 80.0, node                 # the driver's 100 Hz arrive
    assert node['poses_accepted_share'] >= 0.95, node
    assert report['meshcat']['rate_hz'] >= 0.8 * 20.0, report['meshcat']
    assert (node['model'], node['sim_rate']) == (model, sim_rate), node


def test_neither_program_changes_the_discovery_range(monkeypatch):
    """hair_sim_node and hair_sim_demo leave ROS_AUTOMATIC_DISCOVERY_RANGE to the user."""
    import rclpy
    from hair_sim.ros import demo, node
    seen = []

    class Recorder:
        def __init__(self, *args, **kwargs):
            seen.append(os.environ.get('ROS_AUTOMATIC_DISCOVERY_RANGE', '<unset>'))
            raise KeyboardInterrupt

    for value in (None, 'SUBNET'):
        if value is None:
            monkeypatch.delenv('ROS_AUTOMATIC_DISCOVERY_RANGE', raising=False)
        else:
            monkeypatch.setenv('ROS_AUTOMATIC_DISCOVERY_RANGE', value)
        monkeypatch.setattr(node, 'HairSimNode', Recorder)
        monkeypatch.setattr(rclpy, 'init', lambda *a, **k: None)
        monkeypatch.setattr(rclpy, 'try_shutdown', lambda *a, **k: None)
        node.main([])
        monkeypatch.setattr('hair_sim.ros.node.HairSimNode', Recorder)
        demo.main(['--no-meshcat'])
        expected = '<unset>' if value is None else value
        assert seen[-2:] == [expected, expected]
        assert os.environ.get('ROS_AUTOMATIC_DISCOVERY_RANGE', '<unset>') == expected


def test_two_avatars_in_two_namespaces_do_not_talk_across(tmp_path):
    """
    Two node processes (/left, /right), each with its own tracker, keep to themselves.

    Own topics, services, parameters and diagnostics; each keeps its rate.
    """
    from diagnostic_msgs.msg import DiagnosticArray
    from hair_sim_msgs.msg import HairState
    from hair_sim_msgs.srv import LoadHairstyle
    nodes = {ns: NodeProcess(tmp_path, namespace='/' + ns, log_name='%s.log' % ns)
             for ns in ('left', 'right')}
    trackers = {ns: subprocess.Popen(
        [sys.executable, os.path.join(HERE, 'helpers', 'pose_publisher.py'), x, '0', '0', '0',
         'world', '--ros-args', '-r', '__ns:=/%s' % ns], env=dict(os.environ, PYTHONPATH=HERE))
        for ns, x in (('left', '0.3'), ('right', '-0.3'))}
    client = Client()
    try:
        states = {ns: client.record(HairState, '/%s/hair_state' % ns) for ns in nodes}
        diag = client.record(DiagnosticArray, '/diagnostics', 50)
        assert wait_for(lambda: all(len(s) > 30 for s in states.values()), 60.0)

        def roots(ns):
            return np.asarray(states[ns][-1][1].positions).reshape(-1, 10, 3)[:, 0]
        assert wait_for(lambda: roots('left')[:, 0].mean() > 0.2
                        and roots('right')[:, 0].mean() < -0.2, 20.0), 'poses crossed over'
        r = client.call(LoadHairstyle, '/left/hair_sim/load_hairstyle',
                        LoadHairstyle.Request(path='bob_fringe'))
        assert r.success, r.message
        res = client.set_parameters('/right/hair_sim', {'physics.damping': 5.0})
        assert res[0].successful
        assert client.get_parameters('/left/hair_sim', ['physics.damping']) == {
            'physics.damping': 12.0}
        assert wait_for(lambda: diagnostics_values(diag, '/left/hair_sim').get('hairstyle')
                        == 'bob_fringe', 10.0)
        assert diagnostics_values(diag, '/right/hair_sim').get('hairstyle') == 'thesis_long'
        hz = probe_rates(4.0, ['/left', '/right'])          # from another process
        for ns in nodes:
            assert hz['/' + ns]['hair_state'] >= 24.0, (ns, hz)
        assert roots('left').shape[0] != roots('right').shape[0]   # bob_fringe vs thesis_long
        for ns, proc in nodes.items():
            assert proc.alive(), proc.output()[-2000:]
    finally:
        client.close()
        for p in trackers.values():
            p.terminate()
            p.wait(timeout=10)
        for p in nodes.values():
            p.stop()


def test_the_shipped_launch_file_names_real_executables_and_parameters():
    """
    The shipped launch file is consistent with the package.

    config/launch/avatars.launch.xml: every node is a console script of ours, every param
    it sets is declared by the node, and every avatar has its own namespace and head frame.
    """
    import xml.etree.ElementTree as ET
    from hair_sim import paths
    from hair_sim.ros.params import all_parameters
    setup = open(os.path.join(os.path.dirname(paths.config_dir()), 'setup.py')).read()
    root = ET.parse(os.path.join(paths.config_dir(), 'launch', 'avatars.launch.xml')).getroot()
    groups = root.findall('group')
    assert len(groups) >= 2
    namespaces, frames = set(), set()
    for g in groups:
        namespaces.add(g.find('push-ros-namespace').get('namespace'))
        node = g.find('node')
        assert node.get('pkg') == 'hair_sim' and "'%s = " % node.get('exec') in setup
        for p in node.findall('param'):
            if p.get('name') is not None:
                assert p.get('name') in all_parameters(), p.get('name')
                if p.get('name') == 'head_frame':
                    frames.add(p.get('value'))
    assert len(namespaces) == len(groups) == len(frames)


def test_the_node_answers_help_and_refuses_arguments_it_does_not_take():
    """
    `hair_sim_node --help` lists every parameter; a non-ROS argument is refused, not ignored.

    Before, --help started the node, and --style bob_fringe (the demo's option, given to
    the node) ran thesis_long without a word.
    """
    from hair_sim.ros.params import all_parameters
    exe = os.path.join(os.path.dirname(sys.executable), 'hair_sim_node')
    done = subprocess.run([exe, '--help'], capture_output=True, text=True, timeout=60)
    assert done.returncode == 0, done.stderr[-2000:]
    listed = {line.split()[0] for line in done.stdout.splitlines() if ' := ' in line}
    assert listed == set(all_parameters()), set(all_parameters()) ^ listed
    done = subprocess.run([exe, '--style', 'bob_fringe', '--ros-args', '-p', 'sim_rate:=120.0'],
                          capture_output=True, text=True, timeout=60)
    assert done.returncode == 2, done.stdout[-2000:] + done.stderr[-2000:]
    assert 'unrecognized arguments: --style bob_fringe' in done.stderr, done.stderr[-2000:]


def test_a_publish_cut_short_by_a_stop_is_not_counted_as_an_error():
    """
    The node's publish callback, run after the context was shut down, is not an error.

    What a SIGTERM during a publish does, made certain: before, the RCLError was counted
    in /diagnostics and logged with its traceback as "unexpected".
    """
    import rclpy
    from rclpy.context import Context
    from hair_sim.ros.node import HairSimNode
    context = Context()
    rclpy.init(context=context, args=['hair_sim_node', '--ros-args', '-p',
                                      'meshcat.enabled:=false'])
    node = HairSimNode(context=context)
    try:
        node._on_publish()
        assert sum(node.errors.values()) == 0
        context.shutdown()
        node._on_publish()                      # publishes into a context that is gone
        assert sum(node.errors.values()) == 0, node.errors
    finally:
        node.destroy_node()
        rclpy.try_shutdown(context=context)


@pytest.mark.parametrize('program', ['head_driver', 'node'])
def test_a_stop_while_publishing_is_a_clean_exit(program):
    """
    SIGTERM (or Ctrl-C) while a timer publishes ends the program with 0 and no traceback.

    rclpy shuts the context down from its signal handler, and a publish under way then
    raises "publisher's context is invalid". Before, the head driver (2000 poses/s) printed
    that traceback and exited 1 in 6 of 10 stops, and the node (publish_rate 240) logged it
    as an unexpected error in 1 of 6: a stop looked like a crash.
    """
    import signal
    if program == 'head_driver':
        cmd, warm = [sys.executable, '-m', 'hair_sim.ros.head_driver', '--rate', '2000'], 1.5
        tries, ready, later = 5, None, 0.0
    else:
        cmd = [os.path.join(os.path.dirname(sys.executable), 'hair_sim_node'), '--ros-args',
               '-p', 'publish_rate:=240.0', '-p', 'marker_rate:=240.0']
        # the node's timers start with its 'hair_sim: <style>, ...' line: the stop lands
        # that long after it (a fixed 6 s from the start before, which on a slow machine
        # could land before the node published at all)
        warm, tries, ready, later = 0.6, 4, 'hair_sim: ', 0.3
    for k in range(tries):
        proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                                text=True)
        seen = [] if ready is None else \
            read_until(proc, lambda line: ready in line, 60.0, 'the node\'s ready line')
        time.sleep(warm + later * k)
        proc.send_signal(signal.SIGTERM)
        out = ''.join(seen) + proc.communicate(timeout=30)[0]
        assert proc.returncode == 0, out[-3000:]
        assert 'Traceback' not in out and 'unexpected' not in out, out[-3000:]


@pytest.mark.parametrize('program', ['node', 'demo'])
def test_a_second_ctrl_c_while_stopping_is_a_clean_exit_that_leaves_no_server(program):
    """
    Ctrl-C twice, as an impatient user presses it: exit 0, no traceback, no server left.

    The meshcat server runs in its own session, so only the program's cleanup stops it.
    Before, the second interrupt landed in that cleanup: the program died of the signal
    (in 5 of 5 tries), once with a KeyboardInterrupt traceback, and left the server holding
    port 7000, so the next demo's URL showed that server's stale scene.

    The server is watched by its process, found among the program's as it shows the URL
    (its port may be another program's a moment later: tests run two at a time).
    """
    import re
    import signal
    exe = os.path.join(os.path.dirname(sys.executable), 'hair_sim_' + program)
    cmd = [exe, '--ros-args', '-p', 'meshcat.enabled:=true'] if program == 'node' else \
        [exe, '--duration', '60']
    for k in range(3):
        proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                                text=True)
        url = r'http://127\.0\.0\.1:(\d+)/static'
        seen = read_until(proc, lambda line: re.search(url, line), 60.0, 'the meshcat URL')
        port = int(re.search(url, seen[-1]).group(1))
        server = [p for p in psutil.Process(proc.pid).children(recursive=True)
                  if port in [c.laddr.port for c in p.net_connections('tcp')
                              if c.status == psutil.CONN_LISTEN]]
        assert len(server) == 1, 'no process of the program listens on %d' % port
        time.sleep(1.0 + 0.5 * k)
        proc.send_signal(signal.SIGINT)
        time.sleep(0.02 * k)
        proc.send_signal(signal.SIGINT)
        out = ''.join(seen) + proc.communicate(timeout=30)[0]
        assert proc.returncode == 0 and 'Traceback' not in out, out[-3000:]
        assert 'context is invalid' not in out, out[-3000:]
        assert not process_running(server[0].pid), \
            'the server %d (port %d) outlived its program' % (server[0].pid, port)


def test_the_probe_says_when_a_topic_is_silent_and_refuses_a_window_it_cannot_take():
    """
    With nothing publishing, the probe still prints its JSON but exits 1 naming the topic.

    Before, it exited 0 with rate 0 after its connect timeout, and took --duration nan
    or -1, printing NaN, which is not JSON. Bad namespaces are refused by argparse.
    """
    probe = [sys.executable, '-m', 'hair_sim.bench.probe']
    out = subprocess.run(probe + ['--namespaces', '/nobody_here', '--topics', 'hair_state',
                                  '--duration', '0.5', '--warmup', '0',
                                  '--connect-timeout', '1'],
                         capture_output=True, text=True, timeout=120)
    assert out.returncode == 1, out.stderr[-2000:]
    assert '/nobody_here/hair_state' in out.stderr, out.stderr[-2000:]
    report = json.loads(out.stdout)
    assert report['silent'] == ['/nobody_here/hair_state']
    assert report['/nobody_here']['hair_state']['messages'] == 0
    for bad in ('nan', '-1', '0', 'inf'):
        out = subprocess.run(probe + ['--duration', bad], capture_output=True, text=True,
                             timeout=60)
        assert out.returncode == 2 and '--duration' in out.stderr, out.stderr[-2000:]
        assert out.stdout == ''
    # a namespace ROS would refuse (it ended in rclpy's InvalidTopicNameException); one
    # written without its leading slash, or with a trailing one, is taken as meant
    for bad in ('/a//b', '/1st', '/a b'):
        out = subprocess.run(probe + ['--namespaces', bad], capture_output=True, text=True,
                             timeout=60)
        assert out.returncode == 2 and 'is not a ROS namespace' in out.stderr, out.stderr
        assert 'Traceback' not in out.stderr and out.stdout == ''
    out = subprocess.run(probe + ['--namespaces', 'nobody_here/', '--topics', 'hair_state',
                                  '--duration', '0.5', '--warmup', '0',
                                  '--connect-timeout', '1'],
                         capture_output=True, text=True, timeout=120)
    assert out.returncode == 1 and '/nobody_here/hair_state' in out.stderr, out.stderr
    assert json.loads(out.stdout)['silent'] == ['/nobody_here/hair_state']


@pytest.mark.parametrize('program, option, values', [
    (['-m', 'hair_sim.ros.head_driver'], '--rate', ['0', 'nan', '-5', '1e9', 'fast']),
    (['-m', 'hair_sim.ros.demo'], '--duration', ['nan', '-1', 'inf', 'x']),
])
def test_the_programs_refuse_numbers_they_cannot_use_before_they_start(program, option,
                                                                       values):
    """
    A rate or a duration that is not a finite, sane number is refused (exit 2), by name.

    Before, the head driver died with a ZeroDivisionError at --rate 0, a ValueError at
    nan and an RCLError at -5, and at 1e9 spun a zero-period timer; the demo ran for ever
    at --duration nan and stopped at once at -1.
    """
    for value in values:
        out = subprocess.run([sys.executable] + program + [option, value],
                             capture_output=True, text=True, timeout=60)
        assert out.returncode == 2, (value, out.stderr[-2000:])
        assert option in out.stderr and 'Traceback' not in out.stderr, out.stderr[-2000:]


@pytest.mark.parametrize('style', ['', '[1, 2]', 'a: b', 'no_such_style'])
def test_the_demo_names_a_style_it_cannot_load(style):
    """
    `hair_sim_demo --style X` with no such style exits 1 with one line naming it.

    Before, an empty name or one that reads as YAML ('[1, 2]', 'a: b') ended in rcl's
    argument parser with a traceback: the name went into `-p hairstyle:=X` unquoted.
    """
    out = subprocess.run([sys.executable, '-m', 'hair_sim.ros.demo', '--style', style,
                          '--no-meshcat', '--duration', '5'],
                         capture_output=True, text=True, timeout=120)
    assert out.returncode == 1, out.stderr[-2000:]
    assert 'Traceback' not in out.stderr and 'hair_sim_demo: ' in out.stderr, out.stderr
    assert ('empty' if style == '' else style) in out.stderr, out.stderr[-2000:]


@pytest.mark.parametrize('program', [['-m', 'hair_sim.ros.node'], ['-m', 'hair_sim.ros.demo'],
                                     ['-m', 'hair_sim.ros.head_driver']])
def test_a_params_file_rcl_cannot_read_is_named_in_one_line(tmp_path, program):
    """
    --params-file naming a missing file, or one that is not YAML: exit 1, one line, no traceback.

    Before, rcl's parse error reached the user as an RCLInvalidROSArgsError traceback.
    """
    broken = tmp_path / 'broken.yaml'
    broken.write_text('hair_sim:\n  ros__parameters:\n    publish_rate: [1, 2\n')
    for params in (tmp_path / 'missing.yaml', broken):
        out = subprocess.run([sys.executable] + program + ['--ros-args', '--params-file',
                                                           str(params)],
                             capture_output=True, text=True, timeout=60)
        assert out.returncode == 1, out.stderr[-2000:]
        assert 'Traceback' not in out.stderr and str(params) in out.stderr, out.stderr[-2000:]
