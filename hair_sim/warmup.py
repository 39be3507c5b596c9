"""
Compile the node's per-frame kernels into numba's on-disk cache before a first run.

numba compiles a kernel at its first call; cache=True keeps the machine code on disk (in
the package's __pycache__) for every later process. Without this, a fresh install's first
`make demo` compiled for seconds: measured from a subscriber in another process, its
first hair_state came 5.5 s after it started, then none for 10.4 s while the physics
compiled (30 Hz from 16.9 s); with the cache warm, 30 Hz from 0.8 s. The node's first
switch to the articulated model compiled for about 11 s more, in the middle of a run.
`make setup` runs this once (and again when a source file changes).

It runs the node itself, in a ROS domain of its own with meshcat off, and calls its
callbacks as its timers would, for both strand models: head poses, frames, publishing
(hair_mesh, hair_state, markers, head markers, culled and whole meshes), diagnostics. The
same code as the node, so the same kernels with the same argument types. Nothing spins,
so no message is taken in; the node lives for the seconds of the build in a ROS domain of
its own (100-200, as the tests pick), so a running RViz does not show its frames. The
discovery range stays the user's setting. Then a few strands of the hanging-hair scene,
which no spring joins, under a still head: the kernels a library user's from_strands
scene adds (_strands_apart).

    python -m hair_sim.warmup
"""

import os
import random
import sys
import time


def _pose(t, t0):
    """Return a PoseStamped of the demo's head motion at t - t0, stamped t (s)."""
    from geometry_msgs.msg import PoseStamped

    from hair_sim.bench.scenarios import demo
    from hair_sim.ros.node import _stamp
    msg = PoseStamped()
    msg.header.frame_id = 'world'
    msg.header.stamp.sec, msg.header.stamp.nanosec = _stamp(t)
    p, q = demo(t - t0)
    msg.pose.position.x, msg.pose.position.y, msg.pose.position.z = map(float, p)
    (msg.pose.orientation.x, msg.pose.orientation.y, msg.pose.orientation.z,
     msg.pose.orientation.w) = map(float, q)
    return msg


def _drive(node, t0, frames):
    """Call the node's callbacks as its timers would, for frames `frames` from t0 (s)."""
    from hair_sim_msgs.msg import Wind
    wind = Wind()
    wind.velocity.x, wind.velocity.y, wind.turbulence, wind.seed = 3.0, 1.0, 0.5, 3
    node._on_wind(wind)
    for i in frames:
        t = t0 + i / 60.0
        node._on_pose(_pose(t, t0))
        node._on_frame()
        node._clock_last -= 1.0 / 60.0            # a frame's time has passed, as if waited
        node._on_publish()
        node._markers_due = 0.0                   # markers with every publish
    node._on_diagnostics()


def _strands_apart():
    """
    Step a few strands that no spring joins, under a still head in still air.

    There a strand whose swing outran its substeps has its energy checked
    (strand_energies, keep_strands_clear_of_spheres: the simulator's _gained_energy); the
    node's styles join their strands, so its frames never call those (a from_strands
    scene's first step compiled them for 0.85 s). The hanging-hair scene, 20 strands.
    """
    from hair_sim.bench.hanging import head_model, rest_strands, scene_params
    from hair_sim.physics.simulator import HairSimulator
    sim = HairSimulator.from_strands(rest_strands(20, 10), head_model(),
                                     **scene_params('articulated'))
    sim.set_head_pose(0.0, [0.0, 0.0, 0.0], [0.0, 0.0, 0.0, 1.0])
    for _ in range(30):
        sim.step(1.0 / 60.0)


def main():
    """Run the node's frames for both strand models and culled meshes; print the time."""
    import rclpy
    from rclpy.logging import LoggingSeverity, set_logger_level
    from rclpy.parameter import Parameter

    from hair_sim.ros.node import HairSimNode
    from hair_sim.ros.ros_init import init_ros

    start = time.perf_counter()
    os.environ['ROS_DOMAIN_ID'] = str(random.Random(os.getpid()).randint(100, 200))
    init_ros(['hair_sim_warmup', '--ros-args', '-p', 'meshcat.enabled:=false'])
    # its node compiles in its frames, which its clock counts: its notes of dropped time
    # ("the node clock moved 131 ms beyond 16 steps ...", in every make setup) and its
    # start line spoke of no node the user runs. Its errors still show.
    set_logger_level('hair_sim', LoggingSeverity.ERROR)
    node = None
    try:
        node = HairSimNode()
        t0 = node.get_clock().now().nanoseconds * 1e-9
        _drive(node, t0, range(0, 8))
        node.set_parameters([Parameter('use_viewpoint', value=True)])   # culled meshes
        _drive(node, t0, range(8, 12))
        node.set_parameters([Parameter('physics.model', value='articulated')])
        _drive(node, t0, range(12, 20))
        errors = sum(node.errors.values())
    finally:
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
    _strands_apart()
    print('hair_sim: numba kernels compiled and cached in %.1f s%s'
          % (time.perf_counter() - start, '' if not errors else
             ' (%d errors in the node\'s callbacks: see above)' % errors))
    return 1 if errors else 0


if __name__ == '__main__':
    sys.exit(main())
