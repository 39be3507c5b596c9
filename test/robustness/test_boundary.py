"""
The node never dies: each class of attack that ended or corrupted it, from another process.

hair_sim_node runs as its own process; this test process is the careless or hostile
pipeline. After every attack the node must be alive, publishing finite state at its rate,
and every refusal must come with a reason (and be counted in /diagnostics).
"""

import copy
import json
import math
import os
import subprocess
import sys
import threading
import time

import numpy as np
import pytest
import yaml

from hair_sim import budget, paths
from hair_sim.modeling import load_hairstyle
from helpers.glb_bytes import glb_json, glb_with_json
from helpers.node_process import (Client, diagnostics_values, NodeProcess, probe_rates,
                                  ProbeProcess, RateWatch, start_helper, wait_for)

HERE = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
BASE = yaml.safe_load(open(paths.shipped_style('bob_fringe')))
HEAD = yaml.safe_load(open(paths.shipped_head('default_adult')))
NODE = '/hair_sim'


class Live:
    """A running node process and a client recording its state and diagnostics."""

    def __init__(self, tmp):
        from diagnostic_msgs.msg import DiagnosticArray
        from hair_sim_msgs.msg import HairState
        self.tmp = tmp
        self.node = NodeProcess(tmp)
        self.client = Client()
        self.states = self.client.record(HairState, 'hair_state')
        self.diag = self.client.record(DiagnosticArray, '/diagnostics')
        assert wait_for(lambda: len(self.states) > 5, 60.0), self.node.output()[-2000:]
        self.watch = RateWatch('hair_state')

    def load(self, path, timeout=30.0):
        from hair_sim_msgs.srv import LoadHairstyle
        return self.client.call(LoadHairstyle, NODE + '/load_hairstyle',
                                LoadHairstyle.Request(path=path), timeout)

    def edit(self, patch, hair, point, xyz, timeout=30.0):
        from hair_sim_msgs.srv import EditControlPoint
        req = EditControlPoint.Request(patch=patch, control_hair=hair, control_point=point)
        req.position.x, req.position.y, req.position.z = (float(v) for v in xyz)
        return self.client.call(EditControlPoint, NODE + '/edit_control_point', req, timeout)

    def save(self, path, timeout=30.0, overwrite=True):
        from hair_sim_msgs.srv import SaveHairstyle
        return self.client.call(SaveHairstyle, NODE + '/save_hairstyle',
                                SaveHairstyle.Request(path=path, overwrite=overwrite),
                                timeout)

    def reset(self):
        from std_srvs.srv import Trigger
        return self.client.call(Trigger, NODE + '/reset', Trigger.Request())

    def values(self):
        """Return the newest diagnostics of the node."""
        return diagnostics_values(self.diag, NODE)

    def values_since(self, since, timeout=15.0):
        """
        Return the node's diagnostics from the second tick to arrive after `since` (monotonic).

        The first tick to arrive after a change can have been sent before it: under CI load
        the tick taken 1.5 s after use_sim_time came on was one sent before the switch, and
        the node's last second on the steady clock (0.88 s simulated) was put down to the
        /clock that followed (test 21 failed: 12.805 s in the books for 11.925 s of clock).
        """
        assert wait_for(lambda: sum(1 for t, _ in list(self.diag) if t > since) >= 2,
                        timeout), 'no diagnostics in %.0f s' % timeout
        return self.values()

    def write(self, name, data):
        """Write a style (mapping or text) into the node's hairstyle directory."""
        text = data if isinstance(data, str) else yaml.safe_dump(data)
        (self.tmp / name).write_text(text)
        return name

    def assert_healthy(self, window=2.0):
        """
        Alive, publishing at >= 80 % of 30 Hz for the `window` s from now, finite state.

        The rate is taken in another process (a RateWatch), so one scheduling stall of a
        loaded 2-core machine counts against it: a 0.5 s window failed once at 12.7 Hz (a
        ~0.27 s gap after a refused alias bomb, passing 3 of 3 alone); over 2 s the same
        gap clears the floor, and a node that stopped publishing still fails it.
        """
        assert self.node.alive(), self.node.output()[-3000:]
        start = time.monotonic()
        time.sleep(window)
        got = self.watch.span(start, time.monotonic())          # from another process
        assert got['rate_hz'] >= 24.0, (got, self.node.output()[-2000:])
        assert self.node.alive(), self.node.output()[-3000:]
        assert np.all(np.isfinite(np.asarray(self.states[-1][1].positions)))

    def close(self):
        self.watch.close()
        self.client.close()
        return self.node.stop()


def run_helper(script, *args):
    """Run test/helpers/<script> with args to its end ('done'); return what it printed."""
    proc = start_helper(script, *args)
    try:
        out = proc.communicate(timeout=60)[0]
        assert 'done' in out, out
        return out
    finally:
        if proc.poll() is None:
            proc.kill()


def live_session(tmp_path_factory, name):
    """Yield one node process for a test module; it must be healthy at the end."""
    run = Live(tmp_path_factory.mktemp(name))
    try:
        yield run
        run.assert_healthy()
    finally:
        run.close()


@pytest.fixture(scope='module')
def live(tmp_path_factory):
    """One node process for the module; every test leaves it healthy."""
    yield from live_session(tmp_path_factory, 'boundary')


def refused(response, *fragments):
    """Assert a service answered with success false and a reason holding the fragments."""
    assert response is not None, 'no answer'
    assert not response.success and response.message, response.message
    assert len(response.message) < 600, 'long message: %d chars' % len(response.message)
    for f in fragments:
        assert f in response.message, response.message


def style_with(mutate):
    """Return a copy of bob_fringe (as a mapping) with `mutate` applied."""
    d = copy.deepcopy(BASE)
    mutate(d)
    return d


# 1 ---------------------------------------------------------------------------------
def test_1_an_unexpected_error_in_any_callback_is_counted_and_the_node_goes_on(node_env):
    """An exception inside the publisher or a subscription is caught, counted, logged."""
    from geometry_msgs.msg import PoseStamped
    from helpers.ros import spin_until
    from rclpy.qos import qos_profile_sensor_data
    _, ex, node, client = node_env

    class Broken:
        n_strips = node.scene.renderer.n_strips

        def mesh(self, *args, **kwargs):
            raise RuntimeError('injected renderer failure')

    renderer, node.scene.renderer = node.scene.renderer, Broken()
    set_pose = node.sim.set_head_pose
    node.sim.set_head_pose = lambda *a: 1 / 0
    pub = client.create_publisher(PoseStamped, 'head_pose', qos_profile_sensor_data)
    msg = PoseStamped()
    msg.header.frame_id = 'world'
    msg.pose.orientation.w = 1.0

    def poke():
        msg.header.stamp = client.get_clock().now().to_msg()
        pub.publish(msg)
        return node.errors['publish'] >= 3 and node.errors['head_pose'] >= 3
    assert spin_until(ex, poke, 20.0), dict(node.errors)   # spin_once never raised
    node.scene.renderer = renderer
    node.sim.set_head_pose = set_pose
    published = node.counts['published']
    assert spin_until(ex, lambda: node.counts['published'] > published + 5, 10.0)


# 2 ---------------------------------------------------------------------------------
def test_2_style_switches_race_the_publisher_and_each_other(live):
    """40 loads a second from one client, then five clients at once while poses stream."""
    from hair_sim_msgs.srv import LoadHairstyle
    names = ['thesis_long', 'bob_fringe', 'thesis_short', 'side_swept_long']
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    cli = live.client.node.create_client(   # fires without waiting: its answers need room
        LoadHairstyle, NODE + '/load_hairstyle',
        qos_profile=QoSProfile(depth=400, reliability=ReliabilityPolicy.RELIABLE))
    assert cli.wait_for_service(timeout_sec=20.0)
    futures = []
    end = time.monotonic() + 8.0
    k = 0
    while time.monotonic() < end:                     # 40 a second, not waiting for answers
        futures.append(cli.call_async(LoadHairstyle.Request(path=names[k % 4])))
        k += 1
        time.sleep(0.025)
    assert wait_for(lambda: all(f.done() for f in futures), 60.0), (
        '%d of %d loads left unanswered' % (sum(not f.done() for f in futures), len(futures)),
        live.node.output()[-2000:])
    answers = [f.result() for f in futures]
    assert all(a.message for a in answers)
    assert sum(a.success for a in answers) >= len(answers) // 2, [a.message for a in answers]
    assert all(a.success or 'busy' in a.message for a in answers), [
        a.message for a in answers if not a.success][:3]
    live.assert_healthy(1.0)
    poses = subprocess.Popen([sys.executable, os.path.join(HERE, 'helpers', 'pose_publisher.py'),
                              '0.02', '0.0', '0.01', '20'], env=dict(os.environ, PYTHONPATH=HERE))
    results = []

    def worker(i):
        for j in range(12):
            kind = (i + j) % 4
            if kind == 0:
                r = live.load(names[(i + j) % 4])
            elif kind == 1:
                r = live.edit(0, (i + j) % 3, 2, [0.0, 0.01 * i, 0.12])
            elif kind == 2:
                r = live.save('race_%d.yaml' % i)
            else:
                r = live.reset()
            results.append((kind, r))
    try:
        threads = [threading.Thread(target=worker, args=(i,)) for i in range(5)]
        for t in threads:
            t.start()
        for t in threads:
            t.join(timeout=120)
        live.assert_healthy()
    finally:
        poses.terminate()
        poses.wait(timeout=10)
    assert len(results) == 60 and all(r is not None and r.message for _, r in results)
    for i in range(5):                                # every save that succeeded loads back
        if (live.tmp / ('race_%d.yaml' % i)).exists():
            load_hairstyle(str(live.tmp / ('race_%d.yaml' % i)))


# 3 ---------------------------------------------------------------------------------
@pytest.mark.parametrize('field, value', [
    ('width', 'abc'), ('width', 0), ('width', 10 ** 7), ('width', 1e7), ('height', -5),
    ('seed', -1), ('streaks', 10 ** 7), ('streaks', '1e7'), ('edge_fade', float('nan')),
    ('tip_fade', [1, 2])])
def test_3_every_material_value_is_checked_where_it_enters(live, field, value):
    """A bad texture value is refused at load, naming the field; nothing reaches a publish."""
    name = live.write('tex_%s.yaml' % field, style_with(
        lambda d: d['material']['texture'].__setitem__(field, value)))
    t0 = time.monotonic()
    refused(live.load(name), 'material.texture.%s' % field)
    assert time.monotonic() - t0 < 5.0
    live.assert_healthy()


# 4 ---------------------------------------------------------------------------------
BIG = 10 ** 400


def _alias_bomb(levels):
    text = 'a0: &a0 ["lol", "lol", "lol", "lol", "lol", "lol", "lol", "lol", "lol"]\n'
    for i in range(1, levels + 1):
        text += 'a%d: &a%d [%s]\n' % (i, i, ', '.join(['*a%d' % (i - 1)] * 9))
    return text + 'patches: *a%d\n' % levels


@pytest.mark.parametrize('case', ['deep', 'coordinate', 'colour', 'weights', 'knots',
                                  'bomb', 'head_radius', 'hairline'])
def test_4_parse_errors_of_every_kind_are_refused_quickly(live, case):
    """Deep nesting, 400-digit numbers anywhere, alias bombs: refused in well under 5 s."""
    files = {
        'deep': lambda: 'name: deep\npatches: ' + '[' * 1000 + ']' * 1000 + '\n',
        'coordinate': lambda: yaml.safe_dump(style_with(
            lambda d: d['patches'][0]['control_hairs'][1][2].__setitem__(0, BIG))),
        'colour': lambda: yaml.safe_dump(style_with(
            lambda d: d['material'].__setitem__('color', [BIG, 0, 0]))),
        'weights': lambda: yaml.safe_dump(style_with(lambda d: d['patches'][0].__setitem__(
            'weights', [[BIG] * len(h) for h in d['patches'][0]['control_hairs']]))),
        'knots': lambda: yaml.safe_dump(style_with(lambda d: d['patches'][0].__setitem__(
            'knots_along', [0, 0, 0, 0, BIG, BIG, BIG, BIG]))),
        'bomb': lambda: _alias_bomb(8),
    }
    if case in ('head_radius', 'hairline'):
        head = copy.deepcopy(HEAD)
        if case == 'head_radius':
            head['scalp_spheres'][0]['radius'] = BIG
        else:
            head['hairline']['front_z'] = -BIG
        (live.tmp / 'heads').mkdir(exist_ok=True)
        (live.tmp / 'heads' / ('%s.yaml' % case)).write_text(yaml.safe_dump(head))
        text = yaml.safe_dump(style_with(lambda d: d.__setitem__('head', case)))
    else:
        text = files[case]()
    name = live.write('parse_%s.yaml' % case, text)
    t0 = time.monotonic()
    refused(live.load(name))
    assert time.monotonic() - t0 < 5.0
    # the same file through the hairstyle parameter: refused with a reason, changes nothing
    result = live.client.set_parameters(NODE, {'hairstyle': name})
    assert result is not None and not result[0].successful and result[0].reason
    assert live.client.get_parameters(NODE, ['hairstyle'])['hairstyle'] != name
    live.assert_healthy()


# 5 ---------------------------------------------------------------------------------
def test_5_changes_are_all_or_nothing(live):
    """A 72-sphere head is refused before anything swaps; a refused set changes nothing."""
    head = copy.deepcopy(HEAD)
    head['collision_spheres'] = [dict(s, name='s%d' % i) for i, s in enumerate(
        head['collision_spheres'] * 7)][:70]
    (live.tmp / 'heads').mkdir(exist_ok=True)
    (live.tmp / 'heads' / 'many.yaml').write_text(yaml.safe_dump(head))
    before = live.values().get('hairstyle')
    refused(live.load(live.write('many_spheres.yaml', style_with(
        lambda d: d.__setitem__('head', 'many')))), '63')
    live.assert_healthy(1.0)
    assert live.values().get('hairstyle') == before
    res = live.client.set_parameters(NODE, {'physics.max_wind_speed': 5.0,
                                            'hairstyle': 'no_such_style'}, atomically=True)
    assert res is not None and not res.successful and 'no_such_style' in res.reason
    assert live.client.get_parameters(NODE, ['physics.max_wind_speed']) == {
        'physics.max_wind_speed': 40.0}
    from hair_sim_msgs.msg import Wind
    pub = live.client.node.create_publisher(Wind, 'wind', 10)
    clamped = int(live.values().get('wind_clamped', 0))
    assert wait_for(lambda: pub.get_subscription_count() > 0, 10.0)
    w = Wind()
    w.header.frame_id = 'world'
    w.velocity.x = 20.0                                # under 40: not clamped
    pub.publish(w)
    time.sleep(2.5)
    assert int(live.values().get('wind_clamped', 0)) == clamped
    w.velocity.x = 0.0
    pub.publish(w)


# 6 ---------------------------------------------------------------------------------
def test_6_edits_have_the_same_bounds_as_files(live):
    """Edits far away or non-finite are refused; an accepted, saved edit loads back."""
    assert live.load('bob_fringe').success
    for xyz in ([1e300, 1e300, 1e300], [1e30, 0.0, 0.0], [float('nan'), 0.0, 0.1],
                [float('inf'), 0.0, 0.0], [3.0, 0.0, 0.0]):
        refused(live.edit(0, 1, 3, xyz))
    refused(live.edit(2 ** 32 - 1, 0, 0, [0, 0, 0.1]), 'no patch')
    refused(live.edit(0, 2 ** 31, 0, [0, 0, 0.1]), 'no control hair')
    ok = live.edit(0, 1, 3, [0.0, 0.02, 0.13])
    assert ok.success, ok.message
    saved = live.save('edited.yaml')
    assert saved.success, saved.message
    style = load_hairstyle(str(live.tmp / 'edited.yaml'))
    assert np.allclose(style.patches[0].points[1, 3], [0.0, 0.02, 0.13])
    assert live.load('edited').success


# 7 ---------------------------------------------------------------------------------
def test_7_sizes_follow_the_budget_and_loads_do_not_stop_publishing(live):
    """
    Over-budget styles are refused before building, with the numbers.

    The largest style that fits loads in the background while hair_state keeps coming.
    """
    huge = style_with(lambda d: (d['lod'].update(vertices=64, render_rows=256,
                                                 render_columns=16),
                                 [p.update(strips=1000) for p in d['patches']]))
    t0 = time.monotonic()
    refused(live.load(live.write('huge.yaml', huge)), 'budget', 'simulated vertices')
    assert time.monotonic() - t0 < 5.0
    lod = style_with(lambda d: d['lod'].update(render_rows=256, render_columns=16))
    lod['patches'][0]['strips'] = 200
    refused(live.load(live.write('lod.yaml', lod)), 'budget')
    # the largest thesis_long that fits: loads while hair_state keeps its rate
    data = yaml.safe_load(open(paths.shipped_style('thesis_long')))
    n = 46
    while budget.core_share(2 * (n + 10) * 10, (n + 10) * 7 * 30) < budget.CPU_SHARE:
        n += 10
    data['patches'][0]['strips'] = n
    name = live.write('largest.yaml', data)
    # a probe process records hair_state over the load and a second or more after it (a
    # quick load, e.g. with its texture made before, can be over between two messages)
    probe = ProbeProcess(3.0)
    r = live.load(name)
    assert r.success, r.message
    got = probe.report()['/']['hair_state']
    assert got['messages'] > 30, got
    assert got['gap_ms_max'] < 500.0, 'publishing stopped for %.0f ms during the load' % (
        got['gap_ms_max'])
    assert live.load('bob_fringe').success


# 8 ---------------------------------------------------------------------------------
def test_8_pose_stamps_that_loop_back_re_anchor_the_clock(live):
    """Stamps jumping back 60 s (a looping bag): re-anchored, and the hair follows again."""
    from hair_sim_msgs.msg import HairState
    assert live.load('thesis_long').success
    jumps = int(live.values().get('pose_clock_jump', 0))
    states = live.client.record(HairState, 'hair_state')
    run_helper('looping_clock.py', 60, 2, 4, 0.3)
    assert int(live.values_since(time.monotonic()).get('pose_clock_jump', 0)) > jumps
    roots = np.asarray(states[-1][1].positions).reshape(-1, 10, 3)[:, 0]
    head = load_hairstyle(paths.shipped_style('thesis_long'))
    from hair_sim.modeling.strips import build_strips
    rest_roots = build_strips(head).rest[:, 0]
    assert np.abs(roots - rest_roots - [0.3, 0.0, 0.0]).max() < 1e-3, 'the hair did not follow'


# 9 ---------------------------------------------------------------------------------
def test_9_the_smaller_ones(live):
    """
    The smaller ones.

    A viewpoint as a ROS array, wind in an unknown frame, stability on every route, head
    files outside the directories.
    """
    from hair_sim_msgs.msg import Wind
    res = live.client.set_parameters(NODE, {'viewpoint': [0.5, 0.1, 0.2]})
    assert res[0].successful, res[0].reason
    res = live.client.set_parameters(NODE, {'viewpoint': [0.5, 0.1]})
    assert not res[0].successful and 'viewpoint' in res[0].reason
    # an empty world frame: every head pose (frame 'world') would be refused as in the
    # wrong frame, and the output stamped with no frame
    res = live.client.set_parameters(NODE, {'world_frame': ''})
    assert not res[0].successful and 'world_frame' in res[0].reason, res[0].reason
    pub = live.client.node.create_publisher(Wind, 'wind', 10)
    assert wait_for(lambda: pub.get_subscription_count() > 0, 10.0)
    w = Wind()
    w.header.frame_id = 'camera_optical'
    w.velocity.x = 3.0
    pub.publish(w)
    assert wait_for(lambda: int(live.values().get('refused_wind_wrong_frame', 0)) >= 1, 5.0)
    assert live.load('thesis_long').success
    res = live.client.set_parameters(NODE, {'physics.integrator': 'explicit'})
    assert res[0].successful, res[0].reason
    refused(live.load('bob_fringe'), 'unstable')
    res = live.client.set_parameters(NODE, {'physics.damping': 12.0})
    assert res[0].successful, res[0].reason
    res = live.client.set_parameters(NODE, {'physics.integrator': 'implicit'})
    assert res[0].successful, res[0].reason
    outside = live.tmp.parent / ('outside_%s' % live.tmp.name)
    outside.mkdir(exist_ok=True)
    (outside / 'head.yaml').write_text(yaml.safe_dump(HEAD))
    for ref in (str(outside / 'head.yaml'), '../%s/head.yaml' % outside.name,
                '/etc/missing_head.yaml'):
        r = live.load(live.write('outside_head.yaml', style_with(
            lambda d: d.__setitem__('head', ref))))
        refused(r, 'not found')
        assert str(outside) not in r.message and '/etc' not in r.message, r.message


@pytest.mark.parametrize('args, fragment', [
    (['-p', 'use_viewpoint:=true', '-p', 'viewpoint:=[.nan, 0.0, 0.0]'], 'viewpoint'),
    (['-p', "world_frame:=''"], 'world_frame'),
    (['-p', 'head_frame:=1bad'], 'head_frame'),
    (['-p', 'head_frame:=world'], "head_frame 'world' is world_frame"),
    (['-p', 'world_frame:=head'], "frame_id 'head' is world_frame"),   # (the head file's)
    (['-p', 'meshcat.zmq_url:=http://localhost:6000'], 'meshcat.zmq_url'),
    (['-p', "hairstyle_dirs:=['/nonexistent/styles']"], 'hairstyle_dirs'),
    (['-p', 'meshcat.view:=top'], 'meshcat.view'),
    (['-p', 'publish_rate:=.nan'], 'publish_rate'),
    (['-p', 'publish_rate:=fast'], 'publish_rate'),
    (['-p', 'physics.damping:=-1.0'], 'physics.damping'),
])
def test_10_a_node_started_with_a_value_it_would_refuse_exits_and_says_which(args, fragment):
    """
    What --ros-args -p gives is checked as a SetParameters call is.

    Before, only the physics and meshcat.view were: a NaN viewpoint, an empty world frame
    or a missing hairstyle directory started a node that then culled, refused every head
    pose or loaded from nowhere without a word, and a value out of its declared range or
    of the wrong type ended it with rclpy's traceback. Now the node exits 1 at once with
    one line naming the parameter, as `hair_sim_node --ros-args -p ...` is typed.
    """
    cmd = [os.path.join(os.path.dirname(sys.executable), 'hair_sim_node'), '--ros-args']
    done = subprocess.run(cmd + args, capture_output=True, text=True, timeout=60)
    out = done.stdout + done.stderr
    assert done.returncode == 1, out[-2000:]
    assert fragment in out and 'Traceback' not in out, out[-2000:]
    assert out.strip().startswith('hair_sim_node: '), out[-2000:]


def test_11_a_parameter_the_node_does_not_have_is_named_in_a_warning(tmp_path):
    """
    A mistyped name (physics.dampin) is ignored by rclpy without a word: the node says so.

    It still starts and publishes (ROS ignores overrides a node does not declare), and
    its log names what it ignored, once.
    """
    node = NodeProcess(tmp_path, ['-p', 'physics.dampin:=3.0'])
    try:
        assert wait_for(lambda: 'hair_sim: ' in node.output(), 60.0), node.output()[-2000:]
        out = node.output()
        assert node.alive(), out[-2000:]
        assert out.count('physics.dampin') == 1 and 'ignored' in out, out[-2000:]
        assert 'physics.damping' not in out, out[-2000:]
    finally:
        node.stop()


# 12 --------------------------------------------------------------------------------
def test_12_a_gale_the_solver_cannot_keep_up_with_does_not_stop_publishing(live):
    """
    The exact chain in the strongest wind the node accepts: hair_state keeps its rate.

    A wind of max_wind_speed (40 m/s) with full turbulence whips the articulated model's
    tips at hundreds of rad/s, so a 1/60 s step takes 50-400 ms of substeps (measured
    in-process: 3.7 s of wall per simulated second). The node used to step on regardless:
    hair_state came at 0.7 Hz from another process and head poses went unread. The solver
    now gets its share of the wall time (max_physics_share) and the simulated time beyond
    it is dropped, counted and said in the log. Once the gale has passed, no more time is
    dropped: the hair runs in real time again. The probe's window opens before the wind
    starts, so the onset is in it: there the hair outruns its first step, and the step
    taken again stopped the outputs for 271 ms in this test until retries were cut to the
    bound too (80-104 ms since; 2026-11-30, a machine running 2.5x slow). The 500 ms bound
    is the floor "publishing does not stop", not that measurement.
    """
    from hair_sim_msgs.msg import Wind
    assert live.load('thesis_long').success
    res = live.client.set_parameters(NODE, {'physics.model': 'articulated', 'sim_rate': 60.0})
    assert all(r.successful for r in res), [r.reason for r in res]
    over = int(live.values().get('physics_over_share', 0))
    pub = live.client.node.create_publisher(Wind, 'wind', 10)
    assert wait_for(lambda: pub.get_subscription_count() > 0, 10.0)
    w = Wind()
    w.velocity.x, w.velocity.y, w.turbulence, w.seed = 40.0, 5.0, 1.0, 3
    try:
        probe = ProbeProcess(4.0)                         # from another process
        pub.publish(w)
        got = probe.report()['/']['hair_state']
        assert got['rate_hz'] >= 24.0, (got, live.node.output()[-2000:])
        assert got['gap_ms_max'] < 500.0, 'publishing stopped for %.0f ms in the gale' % (
            got['gap_ms_max'])
        assert wait_for(lambda: int(live.values().get('physics_over_share', 0)) > over, 5.0)
        assert 'simulated time dropped' in live.node.output()
        w.velocity.x, w.velocity.y, w.turbulence = 0.0, 0.0, 0.0
        pub.publish(w)

        def dropping():
            before = float(live.values().get('time_dropped_s', 0))
            time.sleep(2.0)
            return float(live.values().get('time_dropped_s', 0)) > before
        assert wait_for(lambda: not dropping(), 20.0), live.values()
    finally:
        w.velocity.x, w.velocity.y, w.turbulence = 0.0, 0.0, 0.0
        pub.publish(w)
        res = live.client.set_parameters(NODE, {'physics.model': 'anjyo', 'sim_rate': 240.0})
        assert all(r.successful for r in res), [r.reason for r in res]
    assert np.all(np.isfinite(np.asarray(live.states[-1][1].positions)))


# 13 --------------------------------------------------------------------------------
def test_13_a_head_mesh_that_is_no_file_here_is_drawn_as_spheres_and_nothing_waits(live):
    """
    A style's head whose display mesh is a FIFO, or a symlink out of its folder.

    The node read the display mesh on its publishing thread (for head_markers) after the
    load. A FIFO there made that thread wait for a writer for ever: nothing more was
    published (hair_state stopped for the rest of a 12 s window) and in this test the
    load's own answer never came (2026-11-30). Each is now refused when opened (on the
    builder's thread, where the mesh is now read), counted and said in the log, and the
    spheres are drawn.
    """
    heads = live.tmp / 'heads'
    heads.mkdir(exist_ok=True)
    outside = live.tmp.parent / ('outside_mesh_%s' % live.tmp.name)
    outside.mkdir(exist_ok=True)
    shipped_mesh = os.path.join(os.path.dirname(paths.shipped_head('default_adult')),
                                HEAD['mesh'])
    (outside / 'real.glb').write_bytes(open(shipped_mesh, 'rb').read())
    os.mkfifo(heads / 'fifo.glb')
    os.symlink(outside / 'real.glb', heads / 'out.glb')
    # a GLB whose JSON says a count of Infinity, and one nested 100000 deep: read_glb
    # raised OverflowError and RecursionError, which no reader of it caught
    with open(shipped_mesh, 'rb') as f:
        gltf = json.loads(glb_json(f.read()))
    gltf['accessors'][0]['count'] = math.inf
    (heads / 'count_inf.glb').write_bytes(glb_with_json(json.dumps(gltf).encode()))
    (heads / 'deep_json.glb').write_bytes(glb_with_json(b'[' * 100000 + b']' * 100000))
    try:                       # (devices and symlinks to a FIFO: test/modeling/test_head_mesh)
        for i, mesh in enumerate(('fifo.glb', 'out.glb', 'count_inf.glb', 'deep_json.glb')):
            unreadable = int(live.values().get('head_mesh_unreadable', 0))
            (heads / ('mesh%d.yaml' % i)).write_text(yaml.safe_dump(dict(
                HEAD, name='mesh%d' % i, mesh=mesh)))
            name = live.write('mesh%d_style.yaml' % i, style_with(
                lambda d: d.__setitem__('head', 'mesh%d' % i)))
            probe = ProbeProcess(2.0)                     # from another process
            r = live.load(name)
            assert r.success, r.message
            got = probe.report()['/']['hair_state']
            assert got['messages'] > 40 and got['gap_ms_max'] < 500.0, (mesh, got)
            assert wait_for(lambda: int(live.values().get(
                'head_mesh_unreadable', 0)) > unreadable, 5.0), mesh
        out = live.node.output()
        assert 'not a regular file' in out and 'leads out of' in out, out[-2000:]
        assert 'count_inf.glb' in out and 'deep_json.glb' in out, out[-2000:]
        assert 'error_' not in ' '.join(live.values()), live.values()
    finally:
        # a reader the old code left waiting on the FIFO gets its end of file
        try:
            os.close(os.open(heads / 'fifo.glb', os.O_WRONLY | os.O_NONBLOCK))
        except OSError:
            pass
    assert live.load('bob_fringe').success


# 14 --------------------------------------------------------------------------------
def test_14_a_simulated_clock_that_loops_back_re_anchors_and_publishing_goes_on(live):
    """
    use_sim_time under a /clock that jumps back 60 s, as a looping bag's --clock does.

    The node's timers and stepping then run on the simulated clock: it must keep its rate
    across the jump, re-anchor the pose clock and follow the head again.
    """
    from hair_sim_msgs.msg import HairState
    assert live.load('thesis_long').success
    jumps = int(live.values().get('pose_clock_jump', 0))
    res = live.client.set_parameters(NODE, {'use_sim_time': True})
    assert res[0].successful, res[0].reason
    seen = len(live.diag)
    # recorded from before the clock starts: once it stops, so does the node (its time
    # stands still), and a subscription made late may get nothing
    states = live.client.record(HairState, 'hair_state')
    try:
        proc = start_helper('looping_clock.py', 60, 2.5, 60, -0.2, 'clock')
        try:
            # measured once the clock runs: before it, the node sends its hair once a second
            # (a probe that caught one of those saw a 1 s gap); and while it runs, to the
            # probe's end (see test 20)
            assert 'publishing' in proc.stdout.readline()
            probe = ProbeProcess(4.0)                     # from another process
            got = probe.report()['/']['hair_state']
            assert proc.poll() is None, 'the clock stopped before the probe was done'
        finally:
            if proc.poll() is None:
                proc.kill()
        assert got['rate_hz'] >= 24.0 and got['gap_ms_max'] < 500.0, got
        values = live.values()
        assert int(values.get('pose_clock_jump', 0)) > jumps, {
            k: values.get(k) for k in ('poses', 'pose_accepted', 'pose_clock_jump',
                                       'pose_out_of_order', 'pose_invalid', 'sim_time',
                                       'sleeping', 'overruns')}
        # the node ran on the simulated clock: its diagnostics' stamps went 60 s back
        stamps = [m.header.stamp.sec for _, m in live.diag[seen:]]
        assert any(b < a - 30 for a, b in zip(stamps, stamps[1:])), stamps
        roots = np.asarray(states[-1][1].positions).reshape(-1, 10, 3)[:, 0]
        from hair_sim.modeling.strips import build_strips
        rest = build_strips(load_hairstyle(paths.shipped_style('thesis_long'))).rest[:, 0]
        assert np.abs(roots - rest - [-0.2, 0.0, 0.0]).max() < 1e-3, 'the hair did not follow'
    finally:
        res = live.client.set_parameters(NODE, {'use_sim_time': False})
        assert res[0].successful, res[0].reason
    live.assert_healthy()


# 15 --------------------------------------------------------------------------------
def test_15_a_second_node_of_the_same_name_is_said(live):
    """
    Another node named /hair_sim (a second `make demo` without a namespace) is warned of.

    ROS starts it without a word, and the two nodes then mix their topics and poses.
    """
    import rclpy
    impostor = rclpy.create_node('hair_sim', context=live.client.context)
    try:
        assert wait_for(lambda: live.values().get('nodes_with_this_name') == '2', 15.0), \
            live.values().get('nodes_with_this_name')
        assert 'another node named /hair_sim in the graph' in live.node.output()
    finally:
        impostor.destroy_node()
    assert wait_for(lambda: live.values().get('nodes_with_this_name') == '1', 15.0)
    assert '0 other node(s) named /hair_sim left' in live.node.output()


# 16 --------------------------------------------------------------------------------
CLOCK_STEP = 3.0        # s the system clock is stepped back, and put forward again after


def _step_system_clock(seconds):
    time.clock_settime(time.CLOCK_REALTIME, time.time() + seconds)


def test_16_a_system_clock_stepped_back_stops_neither_the_node_nor_the_demo_driver(live):
    """
    The system clock stepped back (an NTP correction, `date -s`), for real, then put back.

    rcl timed the node's timers on the system clock, and the Jazzy wheels' rmw times its
    waits on it too: a step back of 60 s stopped hair_state (and the demo's head driver)
    for 60 s. This machine's clock is stepped back CLOCK_STEP s and forward again after
    CLOCK_STEP s, so a node that stands still shows a gap of CLOCK_STEP s. Root only (the
    CI machine runs as root; where the clock cannot be stepped it is skipped, saying why).
    """
    try:
        _step_system_clock(0.0)
    except OSError as exc:                     # EPERM without CAP_SYS_TIME, or a sandbox
        pytest.skip('this machine does not let its clock be stepped (%s)' % exc)
    steps = int(live.values().get('system_clock_steps', 0))
    driver = subprocess.Popen([sys.executable, '-m', 'hair_sim.ros.head_driver'],
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        probe = ProbeProcess(3.0 * CLOCK_STEP, topics=('hair_state',))
        time.sleep(CLOCK_STEP)
        _step_system_clock(-CLOCK_STEP)
        try:
            time.sleep(CLOCK_STEP)
        finally:
            _step_system_clock(CLOCK_STEP)
        got = probe.report()['/']
    finally:
        driver.terminate()
        driver.wait(timeout=15)
    assert got['hair_state']['rate_hz'] >= 24.0, got
    assert got['hair_state']['gap_ms_max'] < 500.0, got
    assert got['poses_sent_hz'] >= 80.0, got           # the driver sends 100 a second
    assert wait_for(lambda: int(live.values().get('system_clock_steps', 0)) >= steps + 2,
                    5.0), live.values().get('system_clock_steps')
    assert 'the system clock stepped -3.0' in live.node.output()
    live.assert_healthy()


# 17 --------------------------------------------------------------------------------
@pytest.mark.parametrize('program', ['hair_sim_node', 'hair_sim_head_driver'])
def test_17_a_log_folder_ros_cannot_make_costs_the_log_files_only(tmp_path, program):
    """
    HOME where ~/.ros/log cannot be made (read-only, as under a service manager; /proc here).

    rclpy.init raised "failed to initialize logging", and the node ended at start with a
    traceback. It now starts without ROS's log files, says so in one line, and publishes.
    """
    env = {k: v for k, v in os.environ.items() if k not in ('ROS_LOG_DIR', 'ROS_HOME')}
    env['HOME'] = '/proc'                      # not even root can make /proc/.ros
    log = open(tmp_path / 'out.log', 'w')
    proc = subprocess.Popen([os.path.join(os.path.dirname(sys.executable), program)],
                            stdout=log, stderr=subprocess.STDOUT, env=env)
    try:
        topic = 'hair_state' if program == 'hair_sim_node' else 'head_pose'
        if topic == 'hair_state':
            assert probe_rates(2.0)['/']['hair_state'] >= 24.0
        else:
            from geometry_msgs.msg import PoseStamped
            from rclpy.qos import qos_profile_sensor_data
            client = Client('hair_sim_test_log_folder')
            try:
                poses = client.record(PoseStamped, 'head_pose', qos_profile_sensor_data)
                assert wait_for(lambda: len(poses) > 50, 30.0), len(poses)
            finally:
                client.close()
        assert proc.poll() is None
    finally:
        proc.terminate()
        proc.wait(timeout=15)
        log.close()
    out = (tmp_path / 'out.log').read_text()
    assert 'ROS log files are off' in out and 'ROS_LOG_DIR' in out, out[-2000:]
    assert 'Traceback' not in out, out[-2000:]


def test_17_the_warmup_runs_where_the_log_folder_cannot_be_made():
    """
    `python -m hair_sim.warmup` (make setup; a service user's first run) under such a HOME.

    It gave rclpy a Context of its own, which rclpy keeps as initialised when its logging
    fails: the retry without log files ended in "Context.init() must only be called once"
    (a root-owned install warmed up as nobody, 2026-12-01).
    """
    env = {k: v for k, v in os.environ.items() if k not in ('ROS_LOG_DIR', 'ROS_HOME')}
    env['HOME'] = '/proc'
    run = subprocess.run([sys.executable, '-m', 'hair_sim.warmup'], env=env,
                         capture_output=True, text=True, timeout=600)
    assert run.returncode == 0, run.stderr[-2000:]
    assert 'ROS log files are off' in run.stderr, run.stderr[-2000:]
    assert 'numba kernels compiled and cached' in run.stdout, run.stdout[-2000:]
    assert 'Traceback' not in run.stderr, run.stderr[-2000:]


# 18 --------------------------------------------------------------------------------
def test_18_use_sim_time_with_no_clock_is_said_and_the_clock_s_start_too(live):
    """
    use_sim_time on, and no /clock (no bag playing, the simulator not started or gone).

    The node then steps nothing, rightly: its time stands still. It published nothing
    either, without a word and without a diagnostic (12 s tried from outside). Its
    diagnostics now run on a steady clock: they go on, warn, and the log says why; the hair
    goes out once a second as it stands; loads are answered (a finished build waited for a
    frame tick, which never came) and a loaded style is sent at once; a /clock that then
    runs brings the hair back, and that is said too.
    """
    from diagnostic_msgs.msg import DiagnosticStatus
    from hair_sim.modeling.strips import build_strips
    from hair_sim_msgs.msg import HairState

    def newest_status():
        for _, msg in reversed(live.diag):
            for st in msg.status:
                if st.name == 'hair_sim: %s' % NODE:
                    return st
        return None

    states = live.client.record(HairState, 'hair_state')
    said = len(live.node.output())
    res = live.client.set_parameters(NODE, {'use_sim_time': True})
    assert res[0].successful, res[0].reason
    try:
        assert wait_for(lambda: float(live.values().get('sim_clock_still_s', 0)) >= 4.0,
                        15.0), live.values()
        st = newest_status()
        assert st.level == DiagnosticStatus.WARN and 'use_sim_time' in st.message, st
        out = live.node.output()[said:]
        assert 'no /clock has arrived' in out or '(/clock) has not moved' in out, out
        held = len(states)
        time.sleep(2.5)
        assert 1 <= len(states) - held <= 4, 'not once a second: %d' % (len(states) - held)
        # loads are answered all the same (they waited for a frame tick: for ever)
        r = live.load('no_such_style', timeout=10.0)
        assert r is not None and not r.success and 'no_such_style' in r.message, r
        r = live.load('thesis_short', timeout=10.0)
        assert r is not None and r.success, r
        # and the new hair is sent at once (a style tuned against a paused frame)
        size = build_strips(load_hairstyle(paths.shipped_style('thesis_short'))).rest.size
        assert len(states[-1][1].positions) == size or wait_for(
            lambda: len(states[-1][1].positions) == size, 0.5), 'the loaded style was not sent'
        held = len(states)
        run_helper('looping_clock.py', 0, 4, 0, 0, 'clock')
        assert len(states) > held + 30, 'no hair on a running /clock'
        out = live.node.output()[said:]
        assert 'the simulated clock (/clock) arrived after' in out or \
            'the simulated clock (/clock) runs again after' in out, out
    finally:
        res = live.client.set_parameters(NODE, {'use_sim_time': False})
        assert res[0].successful, res[0].reason
    assert wait_for(lambda: 'sim_clock_still_s' not in live.values(), 5.0)
    assert newest_status().level == DiagnosticStatus.OK, newest_status()
    live.assert_healthy()


# 19 --------------------------------------------------------------------------------
@pytest.mark.parametrize('program', ['hair_sim_node', 'hair_sim_demo', 'hair_sim_head_driver'])
@pytest.mark.parametrize('domain, reason', [
    ('abc', 'failed to initialize rcl: ROS_DOMAIN_ID is not an integral number'),
    ('233', 'ROS_DOMAIN_ID is 233; rmw_fastrtps_cpp (Fast DDS) takes 0 to 232, the domains '
            'whose UDP ports are under 65536, and ROS 2 advises 0 to 101'),
    ('9' * 400, 'ROS_DOMAIN_ID is %s...; rmw_fastrtps_cpp (Fast DDS) takes 0 to 232, the '
                'domains whose UDP ports are under 65536, and ROS 2 advises 0 to 101'
                % ('9' * 20))])
def test_19_a_ros_that_cannot_start_is_said_in_one_line(program, domain, reason):
    """
    ROS_DOMAIN_ID=abc (a typo in a shell profile), or a domain over 232: ROS cannot start.

    Each program ended with rclpy's traceback, rcl's reason on its last line; on a domain
    over 232, Fast DDS ended it from inside the node's creation with its own "Calculated
    port number is too high" and no word of the program or the setting. It now ends with
    one line naming the program and the reason, and exit code 1.
    """
    env = dict(os.environ, ROS_DOMAIN_ID=domain)
    done = subprocess.run([os.path.join(os.path.dirname(sys.executable), program)],
                          env=env, capture_output=True, text=True, timeout=60)
    assert done.returncode == 1, done
    said = '%s: ROS could not start: %s' % (program, reason)
    assert done.stderr.strip().splitlines() == [said], done.stderr


def test_19_a_domain_over_232_is_fast_dds_s_to_judge_where_a_profile_moves_its_ports(
        tmp_path):
    """
    A Fast DDS XML profile that lowers domainIDGain: domain 233's ports are under 65536.

    The check of test 19 would have refused a node that runs (measured: hair_state at 30 Hz
    to a probe on the same profile). Where a profile is given, Fast DDS judges the domain.
    (7400 + 200 x 233 = 54000, between the default gain's domains 186 and 187, so no
    other test's domain shares its ports.)
    """
    profile = tmp_path / 'ports.xml'
    profile.write_text(
        '<?xml version="1.0" encoding="UTF-8" ?>\n'
        '<profiles xmlns="http://www.eprosima.com/XMLSchemas/fastRTPS_Profiles">\n'
        '  <participant profile_name="small_gain" is_default_profile="true">\n'
        '    <rtps><port><domainIDGain>200</domainIDGain></port></rtps>\n'
        '  </participant>\n'
        '</profiles>\n')
    env = dict(os.environ, ROS_DOMAIN_ID='233', FASTRTPS_DEFAULT_PROFILES_FILE=str(profile))
    log = open(tmp_path / 'node.log', 'w')
    node = subprocess.Popen([os.path.join(os.path.dirname(sys.executable), 'hair_sim_node'),
                             '--ros-args', '-p', 'meshcat.enabled:=false'],
                            stdout=log, stderr=subprocess.STDOUT, env=env)
    try:
        probe = subprocess.run([sys.executable, '-m', 'hair_sim.bench.probe', '--duration',
                                '2', '--topics', 'hair_state'], env=env, capture_output=True,
                               text=True, timeout=120)
        assert node.poll() is None, (tmp_path / 'node.log').read_text()[-2000:]
    finally:
        node.terminate()
        node.wait(timeout=15)
        log.close()
    assert probe.returncode == 0, probe.stderr[-2000:]
    report = json.loads(probe.stdout.strip().splitlines()[-1])
    assert report['/']['hair_state']['rate_hz'] >= 24.0, report
    assert 'could not start' not in (tmp_path / 'node.log').read_text()


# 20 --------------------------------------------------------------------------------
def test_20_a_node_started_on_a_clock_that_stands_still_sends_its_hair(tmp_path):
    """
    hair_sim_node started with use_sim_time and no /clock (a bag paused, to tune against).

    Its publish timer never fires, so a browser showed the head without hair and a
    renderer got nothing. The hair as it stands now goes out once a second (from the
    diagnostics' steady tick), so a subscriber that comes later gets it too. When the
    /clock then starts (at the wall time here), that is no elapsed time: nothing dropped.
    """
    from diagnostic_msgs.msg import DiagnosticArray
    from hair_sim_msgs.msg import HairState
    node = NodeProcess(tmp_path, ['-p', 'use_sim_time:=true'], namespace='/paused')
    client = Client('hair_sim_test_paused')
    try:
        states = client.record(HairState, '/paused/hair_state')
        diag = client.record(DiagnosticArray, '/diagnostics')
        assert wait_for(lambda: len(states) >= 1, 30.0), node.output()[-2000:]
        seen = len(states)
        time.sleep(3.0)
        assert 2 <= len(states) - seen <= 5, len(states) - seen
        assert 'no /clock has arrived' in node.output()
        # the clock runs; the hair's rate on it is counted over 3 s by a subscriber in
        # another process (this one's executor, beside the node's output pipe, took in 35
        # of ~90). The clock runs until the count is in: a clock of 6 s stopped within the
        # probe's window when the probe came up late under CI load (its 3 s then held 42
        # messages, one gap of 0.68 s in another run: the hair of a stopped clock)
        proc = start_helper('looping_clock.py', 0, 60, 0, 0, 'clock',
                            '--ros-args', '-r', '__ns:=/paused')
        try:
            assert 'publishing' in proc.stdout.readline()
            got = ProbeProcess(3.0, namespaces=('/paused',)).report()['/paused']['hair_state']
            assert proc.poll() is None, 'the clock stopped before the probe was done'
        finally:
            if proc.poll() is None:
                proc.kill()
        assert got['rate_hz'] >= 24.0 and got['gap_ms_max'] < 500.0, (
            'no hair on a running /clock', got)
        assert wait_for(lambda: 'arrived after' in node.output(), 5.0), node.output()[-2000:]
        # (anchored at ROS time 0, the first /clock came as 1.8e9 s elapsed, an overrun that
        # dropped them all; a frame the loaded machine runs late is an overrun too, of ms)
        values = diagnostics_values(diag, '/paused/hair_sim')
        assert float(values['overrun_dropped_s']) < 1.0, values
        assert node.alive()
    finally:
        client.close()
        node.stop()


# 21 --------------------------------------------------------------------------------
@pytest.mark.parametrize('rate, speed, jitter', [(10.0, 1.0, 0.0), (40.0, 3.0, 0.6)])
def test_21_a_coarse_or_fast_simulated_clock_is_simulated_not_dropped(
        live, rate, speed, jitter):
    """
    use_sim_time under a /clock of 10 Hz (a simulator's), or a bag played at 3x (40 Hz).

    The frame timer then fires once a clock tick, and each tick moves more time than
    max_steps_per_frame (16 of 1/240 s) covers: a third of the 10 Hz clock's time, and a
    ninth of the fast bag's, was dropped as overruns, without a word, and the hair swung in
    slow motion. The cap now holds per frame tick of wall time, as a budget: the fast clock's
    ticks here come up to 60 % of a period early or late, and a cap on the wall time since
    the last tick alone dropped 4.5 % of its time (0.53 of 11.9 s, 53 overruns) in the ticks
    that came early.

    use_sim_time comes on again here, after earlier tests' clocks: the ROS time is then the
    last /clock of those, and the node anchored its stepping there (a publish of the held
    scene, within the 1.5 s waited), so the new clock's start came as elapsed time, dropped
    (6.6 s in a CI run). No time to anchor to until the clock moves.
    """
    advanced, before, values = run_sim_clock(live, rate, speed, jitter)
    lost = float(values['overrun_dropped_s']) - float(before.get('overrun_dropped_s', 0.0))
    assert lost < 0.01 * advanced, (lost, advanced, values.get('overruns'))
    assert_books_balance(before, values, advanced)
    live.assert_healthy()


CLOCK_LEAD_S = 2.0     # s a test's /clock stands at its start before it moves


def run_sim_clock(live, rate, speed, jitter):
    """
    Run coarse_clock.py on a node set to use_sim_time; return (advanced, before, after).

    advanced is how far the clock moved (s); before and after, the diagnostics before it
    runs (the node clock stands: no /clock yet) and after it stopped. The clock stands at
    its start for CLOCK_LEAD_S first, so that the node has seen where it started when it
    moves (see assert_books_balance).
    """
    res = live.client.set_parameters(NODE, {'use_sim_time': True})
    assert res[0].successful, res[0].reason
    try:
        before = live.values_since(time.monotonic())
        out = run_helper('coarse_clock.py', rate, speed, 4, jitter, CLOCK_LEAD_S)
        advanced = float(out.split('advanced ')[1].split()[0])
        return advanced, before, live.values_since(time.monotonic())
    finally:
        res = live.client.set_parameters(NODE, {'use_sim_time': False})
        assert res[0].successful, res[0].reason


def clock_books(values):
    """
    Return the node-clock time the diagnostics account for (s).

    Each second of it is simulated (sim_time) or dropped and counted: beyond the steps a
    frame may take (overrun_dropped_s), or beyond the solver's share of the wall time
    (time_dropped_s). (A slew of the pose clock, pose_clock_slewed_ms, moves the head's
    poses against the simulator's clock, not the simulator's clock: it is no part of it.)
    """
    return (float(values['sim_time']) + float(values['overrun_dropped_s'])
            + float(values['time_dropped_s']))


def assert_books_balance(before, after, advanced):
    """
    Assert the clock's `advanced` s are in the books (clock_books) between the two values.

    Within 10 ms (the values' rounding, the step not yet due). The node anchors on the
    first /clock its frame sees; the time before that is none of its clock's. A clock that
    moved at once lost its first ticks there whenever the node saw them late: one tick (75
    ms at 3x) when its executor took the second tick first, and 4 and 13 ticks (0.3 and
    0.98 s) in a CI run under load (which way not caught: rclpy's /clock subscription keeps
    the newest tick only, and a subscriber process here, under load, missed the first tick
    of the discovery's end). Hence the clock's lead (CLOCK_LEAD_S) standing at its start:
    anchored there, the node is to account for every tick.
    """
    books = clock_books(after) - clock_books(before)
    assert advanced - 0.01 <= books <= advanced + 0.01, (books, advanced, after)


# 22 --------------------------------------------------------------------------------
def test_22_time_the_solver_has_no_share_of_the_wall_time_for_is_counted(live):
    """
    Every second of the node clock is simulated or counted, when the solver is starved too.

    The articulated model on a 3x /clock with max_physics_share at its floor (0.05) cannot
    take every step. The steps its share of the wall time did not pay for were dropped
    uncounted (only physics_over_share counted the frames): an articulated node fell 1.7 s
    behind such a clock with time_dropped_s at 0.14. They are in time_dropped_s now.
    """
    from hair_sim_msgs.msg import Wind
    res = live.client.set_parameters(NODE, {'physics.model': 'articulated',
                                            'max_physics_share': 0.05})
    assert all(r.successful for r in res), [r.reason for r in res]
    # a turbulent wind keeps the hair awake: still, it sleeps, its steps cost next to
    # nothing and little is dropped (0.3-0.45 s of the 12 s on a fast day, where the test
    # asks for more than 1 s)
    wind = live.client.node.create_publisher(Wind, 'wind', 10)
    gust = Wind(turbulence=1.0, seed=3)
    gust.header.frame_id = 'world'
    gust.velocity.x = 10.0
    winds = int(live.values()['wind'])
    try:
        assert wait_for(lambda: wind.get_subscription_count() > 0, 10.0)
        wind.publish(gust)
        assert wait_for(lambda: int(live.values()['wind']) > winds, 5.0), live.values()
        advanced, before, values = run_sim_clock(live, 40.0, 3.0, 0.0)
        assert float(values['time_dropped_s']) > float(before['time_dropped_s']) + 1.0
        assert_books_balance(before, values, advanced)
    finally:
        wind.publish(Wind())
        res = live.client.set_parameters(NODE, {'physics.model': 'anjyo',
                                                'max_physics_share': 0.6})
        assert all(r.successful for r in res), [r.reason for r in res]
    live.assert_healthy()


# 23 --------------------------------------------------------------------------------
def test_23_two_publishers_on_the_clock_are_said(live):
    """
    use_sim_time with two publishers on /clock: a bag played with --clock and a simulator.

    The ROS time then jumps between their clocks at every message (60 s apart here). The
    node said only that the clock moved 59 s beyond its steps, as if the machine were
    slow. It now names the publishers once, in the log and in /diagnostics, and says when
    they are gone.
    """
    res = live.client.set_parameters(NODE, {'use_sim_time': True})
    assert res[0].successful, res[0].reason
    procs = [start_helper('looping_clock.py', 0, 10, 0, 0, 'clock'),
             start_helper('looping_clock.py', 60, 0, 10, 0, 'clock')]
    try:
        for proc in procs:
            assert 'publishing' in proc.stdout.readline()
        assert wait_for(lambda: '2 publishers on /clock' in live.node.output(), 8.0), \
            live.node.output()[-2000:]
        assert '_UNKNOWN_' not in live.node.output()     # (a node discovery has not named)
        assert wait_for(lambda: live.values().get('clock_publishers') == '2', 3.0), \
            live.values()
        assert live.node.output().count('publishers on /clock') == 1      # said once
        for proc in procs:
            assert 'done' in proc.communicate(timeout=60)[0]
        assert wait_for(lambda: 'no longer jumps between clocks' in live.node.output(), 5.0), \
            live.node.output()[-2000:]
    finally:
        for proc in procs:
            if proc.poll() is None:
                proc.kill()
        res = live.client.set_parameters(NODE, {'use_sim_time': False})
        assert res[0].successful, res[0].reason
    live.assert_healthy()
