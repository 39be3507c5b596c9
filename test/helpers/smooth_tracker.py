"""
A live head tracker in its own process: a smooth turn, until killed.

Each pose is stamped with the time it describes and sent at once, as a tracker's are.
argv: rate_hz. The head yaws 0.8 sin(2 pi 0.7 t) rad (t the pose's stamp, s).
"""

import math
import sys
import time

import rclpy
from rclpy.executors import ExternalShutdownException
from rclpy.qos import qos_profile_sensor_data


def yaw(t):
    """Return the head's turn (rad) at stamp `t` (s)."""
    return 0.8 * math.sin(2.0 * math.pi * 0.7 * t)


def main():
    """Publish the turning head's poses at the rate asked for."""
    from geometry_msgs.msg import PoseStamped

    period = 1.0 / float(sys.argv[1])
    rclpy.init()
    node = rclpy.create_node('smooth_tracker')
    pub = node.create_publisher(PoseStamped, 'head_pose', qos_profile_sensor_data)
    msg = PoseStamped()
    msg.header.frame_id = 'world'
    start = time.monotonic()
    k = 0
    try:
        while rclpy.ok():
            k += 1
            time.sleep(max(0.0, start + k * period - time.monotonic()))
            now = node.get_clock().now()
            msg.header.stamp = now.to_msg()
            half = 0.5 * yaw(now.nanoseconds * 1e-9)
            msg.pose.orientation.z, msg.pose.orientation.w = math.sin(half), math.cos(half)
            pub.publish(msg)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        node.destroy_node()
        rclpy.try_shutdown()


if __name__ == '__main__':
    main()
