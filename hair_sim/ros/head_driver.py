"""
hair_sim_head_driver: a scripted head tracker, as its own process (the demo's driver).

Publishes PoseStamped on head_pose at --rate Hz (nods, turns, a walking bob; stamped with
the time of the pose) and Wind gusts on wind every few seconds, like a real tracker and
weather source would. Accepts --ros-args (namespace, remaps) like any ROS 2 program.

    python -m hair_sim.ros.head_driver [--rate HZ] [--frame FRAME] [--ros-args ...]
"""

import argparse
import os
import sys

from geometry_msgs.msg import PoseStamped
from hair_sim_msgs.msg import Wind
import rclpy
from rclpy.clock import Clock, ClockType
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from rclpy.qos import qos_profile_sensor_data
from rclpy.utilities import remove_ros_args

from hair_sim.arguments import rate_hz
from hair_sim.bench.scenarios import demo as demo_motion, demo_gust, GUST_PERIOD
from hair_sim.ros.clock_step import ClockStepWaker
from hair_sim.ros.ros_init import init_ros


class HeadDriver(Node):
    """Publish the scripted demo head motion and a gust every few seconds."""

    def __init__(self, rate=100.0, frame='world', parent_pid=None, **kwargs):
        super().__init__('hair_sim_head_driver', **kwargs)
        self.frame = frame
        self.parent_pid = parent_pid
        self.pose_pub = self.create_publisher(PoseStamped, 'head_pose', qos_profile_sensor_data)
        self.wind_pub = self.create_publisher(Wind, 'wind', 10)
        # Paced on a steady clock unless on sim time (as hair_sim_node is): timers on the
        # system clock stopped for as long as the clock stepped back; the poses are
        # stamped with the ROS clock, as a tracker's are.
        pacing = self.get_clock() if self.get_parameter('use_sim_time').value else \
            Clock(clock_type=ClockType.STEADY_TIME)
        self._pacing = pacing
        self.t0 = pacing.now().nanoseconds * 1e-9
        self.sent = 0
        self.create_timer(1.0 / rate, self._pose, clock=pacing)
        self.create_timer(GUST_PERIOD, self._wind, clock=pacing)
        self.clock_steps = ClockStepWaker(self)
        self._gust = 0

    def destroy_node(self):
        """Stop watching the system clock, then destroy the node."""
        self.clock_steps.stop()
        super().destroy_node()

    def _pose(self):
        if self.parent_pid is not None and os.getppid() != self.parent_pid:
            raise SystemExit(0)                 # the demo that started us is gone
        now = self.get_clock().now()
        t = self._pacing.now().nanoseconds * 1e-9 - self.t0
        p, q = demo_motion(t)
        msg = PoseStamped()
        msg.header.stamp = now.to_msg()
        msg.header.frame_id = self.frame
        msg.pose.position.x, msg.pose.position.y, msg.pose.position.z = map(float, p)
        (msg.pose.orientation.x, msg.pose.orientation.y, msg.pose.orientation.z,
         msg.pose.orientation.w) = map(float, q)
        self.pose_pub.publish(msg)
        self.sent += 1

    def _wind(self):
        self._gust += 1
        w = Wind()
        w.header.stamp = self.get_clock().now().to_msg()
        w.header.frame_id = self.frame
        velocity, w.turbulence, w.seed = demo_gust(self._gust)
        w.velocity.x, w.velocity.y, w.velocity.z = map(float, velocity)
        self.wind_pub.publish(w)


def main(argv=None):
    """Run the driver until Ctrl-C, shutdown or the parent process (--parent-pid) ends."""
    argv = sys.argv if argv is None else argv
    parser = argparse.ArgumentParser(prog='hair_sim_head_driver', description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('--rate', type=rate_hz, default=100.0, help='poses per second')
    parser.add_argument('--frame', default='world', help='frame id of poses and wind')
    parser.add_argument('--parent-pid', type=int, default=None, help=argparse.SUPPRESS)
    try:
        own = remove_ros_args(argv)[1:]
        args = parser.parse_args(own)
        init_ros(argv)
    except RuntimeError as exc:     # rcl cannot parse them: a params file missing, not YAML
        print('hair_sim_head_driver: %s' % exc, file=sys.stderr)
        return 1
    try:
        rclpy.spin(HeadDriver(args.rate, args.frame, args.parent_pid))
    except (KeyboardInterrupt, ExternalShutdownException, SystemExit):
        pass
    except Exception:                   # noqa: B902
        # Ctrl-C or SIGTERM shuts the context down while a timer publishes: rclpy then
        # raises from publish ("publisher's context is invalid"). That is a stop, not a
        # fault (6 of 10 stops at 2000 poses/s printed its traceback and exited 1)
        if rclpy.ok():
            raise
    finally:
        rclpy.try_shutdown()            # the process ends with it; the node goes too
    return 0


if __name__ == '__main__':
    sys.exit(main())
