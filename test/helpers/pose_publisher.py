"""
Publish head poses (world frame) at 100 Hz from a separate process, until killed.

argv: x y z yaw_deg [frame_id]
"""

import math
import sys
import time

import rclpy
from rclpy.executors import ExternalShutdownException
from rclpy.qos import qos_profile_sensor_data


def main():
    """Publish a constant pose with fresh stamps."""
    from geometry_msgs.msg import PoseStamped

    x, y, z, yaw = (float(v) for v in sys.argv[1:5])
    frame = sys.argv[5] if len(sys.argv) > 5 else 'world'
    rclpy.init()
    node = rclpy.create_node('pose_probe_publisher')
    pub = node.create_publisher(PoseStamped, 'head_pose', qos_profile_sensor_data)
    msg = PoseStamped()
    msg.header.frame_id = frame
    msg.pose.position.x, msg.pose.position.y, msg.pose.position.z = x, y, z
    msg.pose.orientation.z = math.sin(math.radians(yaw) / 2)
    msg.pose.orientation.w = math.cos(math.radians(yaw) / 2)
    try:
        while rclpy.ok():
            msg.header.stamp = node.get_clock().now().to_msg()
            pub.publish(msg)
            time.sleep(0.01)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        node.destroy_node()
        rclpy.try_shutdown()


if __name__ == '__main__':
    main()
