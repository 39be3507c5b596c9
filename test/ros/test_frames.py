"""
Frames and stamps a ROS user can display.

World markers, head-frame markers, DELETEALL, wind in the head frame, and stamps of the
head pose the hair was computed for.
"""

from dataclasses import asdict
import os

import numpy as np
import pytest
from rclpy.parameter import Parameter
from rclpy.qos import qos_profile_sensor_data

from helpers.node_process import start_helper
from helpers.ros import spin_until


def _pose_publisher(client, stamps, position=(0.0, 0.0, 0.0), yaw=0.0):
    from geometry_msgs.msg import PoseStamped
    pub = client.create_publisher(PoseStamped, 'head_pose', qos_profile_sensor_data)
    msg = PoseStamped()
    msg.header.frame_id = 'world'
    msg.pose.position.x, msg.pose.position.y, msg.pose.position.z = position
    msg.pose.orientation.z, msg.pose.orientation.w = np.sin(yaw / 2), np.cos(yaw / 2)

    def send():
        now = client.get_clock().now()
        msg.header.stamp = now.to_msg()
        stamps.append(now.nanoseconds * 1e-9)
        pub.publish(msg)
    return client.create_timer(0.01, send)


def test_markers_in_the_world_frame_by_default_and_in_the_head_frame_on_request(node_env):
    """
    Markers go in the world frame by default, in the head frame on request.

    Default: world frame, not frame-locked, points = the mesh in the world. With
    markers_in_head_frame: head_frame (a parameter), frame_locked, points in the head frame;
    every layout change is preceded by a DELETEALL.
    """
    from visualization_msgs.msg import Marker, MarkerArray
    _, ex, node, client = node_env
    stamps = []
    _pose_publisher(client, stamps, position=(0.1, 0.2, 0.0), yaw=0.5)
    arrays = []
    client.create_subscription(MarkerArray, 'hair_markers', arrays.append, 10)
    assert spin_until(ex, lambda: len(stamps) > 30 and len(arrays) > 3, 20.0)
    m = arrays[-1].markers[0]
    assert m.header.frame_id == 'world' and not m.frame_locked and m.action == Marker.ADD
    R, p = node.sim.head_pose
    assert np.allclose(p, [0.1, 0.2, 0.0], atol=1e-6)
    pts = np.array([[q.x, q.y, q.z] for q in m.points])
    mesh = node.scene.mesh()
    world = mesh.vertices[mesh.indices.reshape(-1)][:len(pts)]
    assert np.abs(pts - world).max() < 0.05          # the state moved on a little since
    res = node.set_parameters([Parameter('markers_in_head_frame', value=True),
                               Parameter('head_frame', value='avatar1/head')])
    assert all(r.successful for r in res)
    n = len(arrays)
    assert spin_until(ex, lambda: len(arrays) > n + 3, 10.0)
    first = next(i for i, a in enumerate(arrays) if a.markers[0].header.frame_id != 'world')
    assert first >= n - 10                            # (older ones may still be queued)
    assert arrays[first].markers[0].action == Marker.DELETEALL
    assert all(a.markers[0].action == Marker.ADD for a in arrays[first + 1:])
    m = arrays[-1].markers[0]
    assert m.header.frame_id == 'avatar1/head' and m.frame_locked
    pts = np.array([[q.x, q.y, q.z] for q in m.points])
    R, p = node.sim.head_pose
    mesh = node.scene.mesh()
    head = (mesh.vertices[mesh.indices.reshape(-1)][:len(pts)] - p) @ R
    assert np.abs(pts - head).max() < 0.05 and np.abs(pts).max() < 1.0
    res = node.set_parameters([Parameter('head_frame', value='not a frame!')])
    assert not res[0].successful


def test_wind_in_the_head_frame_is_rotated_into_the_world(node_env):
    """A wind message in head_frame is turned by the head's rotation; unknown frames refused."""
    from hair_sim_msgs.msg import Wind
    _, ex, node, client = node_env
    stamps = []
    _pose_publisher(client, stamps, yaw=np.pi / 2)
    assert spin_until(ex, lambda: len(stamps) > 20 and node.counts['poses'] > 10, 20.0)
    pub = client.create_publisher(Wind, 'wind', 10)
    w = Wind()
    w.header.frame_id = node.head_frame
    w.velocity.x = 2.0                                  # forward, in the head frame
    pub.publish(w)
    assert spin_until(ex, lambda: node.counts['wind'] >= 1, 10.0)
    assert np.allclose(node.sim.wind.velocity, [0.0, 2.0, 0.0], atol=1e-3)
    w.header.frame_id = 'camera'
    pub.publish(w)
    assert spin_until(ex, lambda: node.refused['wind_wrong_frame'] >= 1, 10.0)
    assert np.allclose(node.sim.wind.velocity, [0.0, 2.0, 0.0], atol=1e-3)


def test_messages_carry_the_stamp_of_the_pose_they_follow(node_env):
    """
    Each hair_state stamp is a pose stamp the node had, not the publish time.

    Never newer than the newest pose sent, and close behind it at 100 Hz poses.
    """
    from hair_sim_msgs.msg import HairMesh, HairState
    _, ex, node, client = node_env
    stamps = []
    _pose_publisher(client, stamps)
    got = []
    client.create_subscription(HairState, 'hair_state',
                               lambda m: got.append((m.header.stamp, stamps[-1])), 10)
    meshes = []
    client.create_subscription(HairMesh, 'hair_mesh', meshes.append, 10)
    assert spin_until(ex, lambda: len(got) > 60 and meshes, 20.0)
    lag = np.array([newest - (s.sec + s.nanosec * 1e-9) for s, newest in got[20:]])
    assert lag.min() >= -1e-6, lag.min()               # never ahead of the newest pose
    assert np.median(lag) < 0.05, np.median(lag)
    assert meshes[-1].header.frame_id == 'world'


def test_a_first_pose_handled_late_does_not_delay_the_hair_for_good(node_env):
    """
    A first pose the node took 0.2 s late leaves the hair 0.2 s behind only for a while.

    The first pose anchors the pose clock. One that waited before the node took it (as
    on a cold start, the node compiling kernels) used to leave every later message that
    much behind the head for as long as the node ran. The node now slews that away:
    after a few seconds the hair follows the newest pose as closely as with a prompt
    anchor, and /diagnostics says how far the clock was moved.
    """
    from geometry_msgs.msg import PoseStamped
    from hair_sim_msgs.msg import HairState
    _, ex, node, client = node_env
    pub = client.create_publisher(PoseStamped, 'head_pose', qos_profile_sensor_data)
    msg = PoseStamped()
    msg.header.frame_id = 'world'
    msg.pose.orientation.w = 1.0
    stamps = []
    got = []
    client.create_subscription(HairState, 'hair_state',
                               lambda m: got.append((m.header.stamp, stamps[-1] if stamps
                                                     else None)), 10)
    # running (kernels compiled: a cold start would stall the first frames by seconds,
    # and HeadMotion would re-anchor past the stall)
    assert spin_until(ex, lambda: len(got) > 5, 120.0)

    def send(late=0.0):
        now = client.get_clock().now().nanoseconds * 1e-9 - late
        msg.header.stamp.sec = int(now)
        msg.header.stamp.nanosec = int((now - int(now)) * 1e9)
        stamps.append(now)
        pub.publish(msg)
    send(late=0.2)
    client.create_timer(0.01, send)
    assert spin_until(ex, lambda: node.pose_lead.slewed > 0.15, 30.0), node.pose_lead.slewed
    start = len(got)
    assert spin_until(ex, lambda: len(got) > start + 30, 10.0)
    lag = np.array([newest - (s.sec + s.nanosec * 1e-9) for s, newest in got[start:]])
    assert lag.min() >= -1e-6, lag.min()               # never ahead of the newest pose
    assert np.median(lag) < 0.05, np.median(lag)       # 0.2 s and more before the slew
    # no more than needed: the 0.2 s, and how far the simulator's clock was behind the
    # node's when the anchor was taken (at most a frame, 1/60 s, and a step, 1/240 s)
    assert node.pose_lead.slewed < 0.2 + 1.0 / 60.0 + 1.0 / 240.0, node.pose_lead.slewed


def _replay_tips(style, params, moves):
    """
    Return the tips (steps, strands, 3) after each step of `moves`, replayed offline.

    `moves` is what the node's simulator did, in order: ('pose', (stamp, position,
    quaternion)) given, ('step', s simulated) and ('skip', s the pose clock moved: time
    dropped under load, or the node's slew).
    """
    from hair_sim import HairSimulator
    sim = HairSimulator(style, **asdict(params))
    tips = []
    for kind, what in moves:
        if kind == 'pose':
            sim.set_head_pose(*what)
        elif kind == 'skip':
            sim.shift_pose_clock(what)
        else:
            sim.step(what)
            tips.append(sim.strand_positions()[:, -1].copy())
    return np.array(tips)


@pytest.mark.parametrize('interpolate', [True, False])
def test_the_hair_feels_a_live_trackers_head_move_between_its_poses(node_env, interpolate):
    """
    A tracker's poses, sent as they are taken, are interpolated, not held and jumped.

    A live tracker (30 Hz, its own process, a smooth turn) stamps each pose with the time
    it describes, so the pose lands as the simulator's clock reaches it; the head was then
    held at the newest pose until the next landed: the hair felt a head that stood still
    and jumped, and its tips ended 3 mm RMS from where the same poses, interpolated, put
    them (measured from outside, 2026-12-01). With `interpolate_poses` (the default) the
    node follows the poses a pose interval later: after the slew has settled, the head is
    between two poses it has at the end of at least 3 steps in 4 (all of them on an idle
    machine, 89-100 % with eight busy processes on two cores; with the option off, or
    before it was made, 96-100 % of the steps end held). The hair it publishes is what an
    offline simulator given the same poses, steps and pose-clock moves (time dropped under
    load, the slew) computes. (This test compared the tips with a replay that gave every
    pose ahead and dropped no time: on a loaded machine, CI's, the node rightly dropped
    time and some poses landed late, and the tips were 1.5-2.6 mm off.) Without the
    option the hair follows the newest pose at once: a message carries the stamp of the
    newest pose the node had as it stamped it.
    """
    from hair_sim_msgs.msg import HairState
    _, ex, node, client = node_env
    assert node.set_parameters([Parameter('interpolate_poses', value=interpolate)])[0].successful
    sim, motion = node.sim, node.sim.motion
    stamped, got, moves, held, after = [], [], [], [], {}
    give, stamp_at, step, skip = sim.set_head_pose, sim.stamp_at, sim.step, motion.skip

    def record(stamp, position, quaternion):
        moves.append(('pose', (stamp, position, quaternion)))
        return give(stamp, position, quaternion)

    def stamp_and_newest(t=None):
        # (the newest pose as the node stamps a message: by the time this process's
        # subscription takes the message, the node may have taken the next pose)
        stamp, newest = stamp_at(t), motion.newest_stamp
        stamped.append((stamp, newest))
        if t is None and stamp is not None and stamp < newest:
            after[round(stamp, 6)] = len(held)     # (a held stamp may repeat: not kept)
        return stamp

    def skip_and_note(seconds):
        if moves:
            moves.append(('skip', seconds))
        return skip(seconds)

    def step_and_note(dt):
        k, t = len(moves), sim.time
        try:
            return step(dt)
        finally:
            if moves:   # (before the skip a cut step makes as it ends)
                moves.insert(k, ('step', sim.time - t))
                ahead = sim.time + motion.offset
                held.append((ahead, ahead > motion.newest_stamp + 1e-9))
    sim.set_head_pose, sim.stamp_at, sim.step, motion.skip = \
        record, stamp_and_newest, step_and_note, skip_and_note
    client.create_subscription(
        HairState, 'hair_state',
        lambda m: got.append((m.header.stamp.sec + 1e-9 * m.header.stamp.nanosec,
                              np.array(m.positions).reshape(m.n_strands, -1, 3)[:, -1])), 50)
    tracker = start_helper('smooth_tracker.py', 30.0, stdout=None)
    try:
        assert spin_until(ex, lambda: sum(kind == 'pose' for kind, _ in moves) > 8 * 30, 60.0)
    finally:
        tracker.kill()
        tracker.wait()
    assert node.sim.motion is motion and motion.counts['clock_jump'] == 0
    first = next(what for kind, what in moves if kind == 'pose')
    # from 3 s after the first pose on (the slew has settled; the start has died away)
    settled = first[0] + 3.0
    kept = [(s, tip) for s, tip in got if s > settled]
    assert len(kept) > 100, len(kept)
    lag = np.array([newest - s for s, newest in stamped if s is not None and s > settled])
    held_share = np.mean([h for ahead, h in held if ahead > settled])
    if not interpolate:
        assert np.median(lag) < 0.005, np.median(lag)
        assert held_share > 0.5, held_share
        return
    assert 0.0 <= np.median(lag) < 0.1, np.median(lag)       # at most MAX_BUFFER
    assert held_share < 0.25, held_share
    replayed = _replay_tips(sim.style, sim.params, moves)
    matched = [(tip, after[round(s, 6)]) for s, tip in kept if round(s, 6) in after]
    assert len(matched) > 0.5 * len(kept), (len(matched), len(kept))
    off_mm = 1e3 * np.sqrt(np.mean([((tip - replayed[n - 1]) ** 2).sum(-1).mean()
                                    for tip, n in matched]))
    assert off_mm < 1e-3, off_mm       # (float32 positions: 0.06 um at 1 m)


def test_head_transform_matches_the_pose():
    """The world -> head TransformStamped published on /tf (full installs) is the pose."""
    from geometry_msgs.msg import PoseStamped
    from hair_sim.ros.node import head_transform
    msg = PoseStamped()
    msg.header.stamp.sec, msg.header.stamp.nanosec = 12, 345
    msg.pose.position.x, msg.pose.position.z = 0.5, 1.6
    msg.pose.orientation.z, msg.pose.orientation.w = 0.6, 0.8
    tf = head_transform(msg, 'world', 'avatar1/head')
    assert (tf.header.frame_id, tf.child_frame_id) == ('world', 'avatar1/head')
    assert tf.header.stamp.sec == 12 and tf.header.stamp.nanosec == 345
    assert (tf.transform.translation.x, tf.transform.translation.z) == (0.5, 1.6)
    assert (tf.transform.rotation.z, tf.transform.rotation.w) == (0.6, 0.8)


def test_the_head_frame_is_never_the_world_frame_by_any_route(node_env, tmp_path):
    """
    A head frame that is world_frame is refused: a parameter, a world_frame, a head file.

    It was taken: wind stamped in the world was then turned with the head (as wind in the
    head frame is), head-frame markers were drawn at the world's origin, and /tf carried a
    transform from the world to itself, which tf2 refuses.
    """
    import re
    from hair_sim_msgs.msg import Wind
    from hair_sim_msgs.srv import LoadHairstyle
    from hair_sim import paths
    from helpers.ros import call_service
    _, ex, node, client = node_env
    stamps = []
    _pose_publisher(client, stamps, yaw=np.pi / 2)
    assert spin_until(ex, lambda: len(stamps) > 20 and node.counts['poses'] > 10, 20.0)
    assert node.head_frame == 'head'                     # the head file's frame_id
    for values in ({'head_frame': 'world'}, {'world_frame': 'head'},
                   {'head_frame': 'avatar', 'world_frame': 'avatar'}):
        res = node.set_parameters_atomically([Parameter(k, value=v) for k, v in values.items()])
        assert not res.successful and 'is world_frame' in res.reason, (values, res.reason)
    assert (node.get_parameter('head_frame').value, node.get_parameter('world_frame').value) \
        == ('', 'world')
    pub = client.create_publisher(Wind, 'wind', 10)
    w = Wind()
    w.header.frame_id = 'world'
    w.velocity.x = 2.0
    pub.publish(w)
    assert spin_until(ex, lambda: node.counts['wind'] >= 1, 10.0)
    assert np.allclose(node.sim.wind.velocity, [2.0, 0.0, 0.0], atol=1e-3)
    # a head file whose frame_id is the world's: its style is refused, the running one goes on
    heads = tmp_path / 'heads'
    heads.mkdir()
    shipped = paths.shipped_style('thesis_long')
    head_file = open(os.path.join(paths.heads_dir(), 'default_adult.yaml')).read()
    (heads / 'in_world.yaml').write_text(re.sub(r'(?m)^frame_id: head$', 'frame_id: world',
                                                re.sub(r'(?m)^mesh: .*$', '', head_file)))
    (tmp_path / 'mine.yaml').write_text(re.sub(r'(?m)^head: default_adult$', 'head: in_world',
                                               open(shipped).read()))
    r = call_service(ex, client, LoadHairstyle, '/hair_sim/load_hairstyle',
                     LoadHairstyle.Request(path='mine.yaml'))
    assert not r.success and "frame_id 'world' is world_frame" in r.message, r.message
    assert node.sim.head.frame_id == 'head'
    # with head_frame naming a frame of its own, that head is taken; not when head_frame is
    # emptied while it is built (checked again when it is swapped in, on the node's thread)
    assert node.set_parameters([Parameter('head_frame', value='skull')])[0].successful
    submitted = []
    submit = node.builder.submit
    node.builder.submit = lambda *args: submitted.append(args[0]) or submit(*args)
    cli = client.create_client(LoadHairstyle, '/hair_sim/load_hairstyle')
    assert cli.wait_for_service(timeout_sec=10.0)
    future = cli.call_async(LoadHairstyle.Request(path='mine.yaml'))
    assert spin_until(ex, lambda: submitted, 10.0)
    assert node.set_parameters([Parameter('head_frame', value='')])[0].successful
    assert spin_until(ex, future.done, 30.0)
    r = future.result()
    assert not r.success and "frame_id 'world' is world_frame" in r.message, r.message
    assert node.sim.head.frame_id == 'head' and node.head_frame == 'head'
    assert node.set_parameters([Parameter('head_frame', value='skull')])[0].successful
    r = call_service(ex, client, LoadHairstyle, '/hair_sim/load_hairstyle',
                     LoadHairstyle.Request(path='mine.yaml'))
    assert r.success, r.message
    assert node.sim.head.frame_id == 'world' and node.head_frame == 'skull'
    # and head_frame cannot then be emptied to give the world back
    res = node.set_parameters([Parameter('head_frame', value='')])[0]
    assert not res.successful and 'is world_frame' in res.reason, res.reason
