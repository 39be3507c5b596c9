"""
hair_sim_demo: the node with the sample style, a scripted head and wind, and meshcat.

The head driver publishes PoseStamped on head_pose (nods, turns, a walking bob) and Wind
gusts on wind; everything goes through real topics.

    hair_sim_demo [--duration S] [--style NAME] [--no-meshcat]
"""

import argparse
import math
import os
import sys
import time

from geometry_msgs.msg import PoseStamped
from hair_sim_msgs.msg import Wind
import rclpy
from rclpy.executors import ExternalShutdownException, MultiThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import qos_profile_sensor_data

from hair_sim.physics.scripts import demo as demo_motion
from hair_sim.ros.node import HairSimNode


class HeadDriver(Node):
    """Publish the scripted demo head motion at 100 Hz and a gust every few seconds."""

    def __init__(self, frame='world', **kwargs):
        super().__init__('hair_sim_demo_driver', **kwargs)
        self.frame = frame
        self.pose_pub = self.create_publisher(PoseStamped, 'head_pose', qos_profile_sensor_data)
        self.wind_pub = self.create_publisher(Wind, 'wind', 10)
        self.t0 = self.get_clock().now().nanoseconds * 1e-9
        self.create_timer(0.01, self._pose)
        self.create_timer(2.0, self._wind)
        self._gust = 0

    def _pose(self):
        now = self.get_clock().now()
        t = now.nanoseconds * 1e-9 - self.t0
        p, q = demo_motion(t)
        msg = PoseStamped()
        msg.header.stamp = now.to_msg()
        msg.header.frame_id = self.frame
        msg.pose.position.x, msg.pose.position.y, msg.pose.position.z = map(float, p)
        (msg.pose.orientation.x, msg.pose.orientation.y, msg.pose.orientation.z,
         msg.pose.orientation.w) = map(float, q)
        self.pose_pub.publish(msg)

    def _wind(self):
        self._gust += 1
        w = Wind()
        w.header.stamp = self.get_clock().now().to_msg()
        w.header.frame_id = self.frame
        speed = 0.0 if self._gust % 3 == 0 else 1.5 + 2.5 * abs(math.sin(self._gust))
        angle = 0.7 * self._gust
        w.velocity.x, w.velocity.y = speed * math.cos(angle), speed * math.sin(angle)
        w.turbulence = 0.3
        w.seed = self._gust
        self.wind_pub.publish(w)


def main(argv=None):
    """Run the demo until Ctrl-C or --duration seconds."""
    parser = argparse.ArgumentParser(prog='hair_sim_demo', description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('--duration', type=float, default=0.0, help='seconds (0: until Ctrl-C)')
    parser.add_argument('--style', default='thesis_long', help='hairstyle name')
    parser.add_argument('--no-meshcat', action='store_true', help='ROS topics only')
    args = parser.parse_args(argv)
    os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    rclpy.init()
    node = driver = None
    try:
        overrides = [Parameter('hairstyle', value=args.style),
                     Parameter('meshcat.enabled', value=not args.no_meshcat)]
        node = HairSimNode(parameter_overrides=overrides)
        driver = HeadDriver()
        executor = MultiThreadedExecutor(num_threads=2)
        executor.add_node(node)
        executor.add_node(driver)
        start = time.monotonic()
        printed = False
        while rclpy.ok():
            executor.spin_once(timeout_sec=0.05)
            if not printed and node.meshcat_url:
                print('URL %s' % node.meshcat_url, flush=True)
                printed = True
            if args.duration and time.monotonic() - start > args.duration:
                break
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        for n in (driver, node):
            if n is not None:
                n.destroy_node()
        rclpy.try_shutdown()
    return 0


if __name__ == '__main__':
    sys.exit(main())
