"""
Send a catalogue of bad head poses and winds, then a 2 kHz pose flood (separate process).

argv: flood_seconds
"""

import math
import sys
import time

import rclpy
from rclpy.qos import qos_profile_sensor_data


def main():
    """Publish the bad inputs, then flood head_pose at 2 kHz."""
    from geometry_msgs.msg import PoseStamped
    from hair_sim_msgs.msg import Wind

    flood = float(sys.argv[1])
    rclpy.init()
    node = rclpy.create_node('bad_input_publisher')
    pose_pub = node.create_publisher(PoseStamped, 'head_pose', qos_profile_sensor_data)
    wind_pub = node.create_publisher(Wind, 'wind', 10)
    deadline = time.monotonic() + 20.0                      # wait until discovery matched
    while (pose_pub.get_subscription_count() == 0 or wind_pub.get_subscription_count() == 0) \
            and time.monotonic() < deadline:
        time.sleep(0.05)
    time.sleep(0.2)

    def now():
        return node.get_clock().now().nanoseconds * 1e-9

    def pose(t, xyz=(0.0, 0.0, 0.0), q=(0.0, 0.0, 0.0, 1.0), frame='world'):
        m = PoseStamped()
        m.header.frame_id = frame
        m.header.stamp.sec = int(t)
        m.header.stamp.nanosec = int((t - int(t)) * 1e9)
        m.pose.position.x, m.pose.position.y, m.pose.position.z = xyz
        (m.pose.orientation.x, m.pose.orientation.y, m.pose.orientation.z,
         m.pose.orientation.w) = q
        pose_pub.publish(m)
        time.sleep(0.05)

    t = now()
    pose(t)
    pose(t + 0.01, (math.nan, 0.0, 0.0))                         # NaN position
    pose(t + 0.02, (0.0, math.inf, 0.0))                         # inf position
    pose(t + 0.03, q=(0.0, 0.0, 0.0, 0.0))                       # zero quaternion
    pose(t + 0.04, q=(0.0, 0.0, math.nan, 1.0))                  # NaN quaternion
    pose(t + 0.05, q=(0.0, 0.0, 0.0, 5.0))                       # not unit: normalised
    pose(t + 0.05)                                               # repeated stamp
    pose(t + 0.01)                                               # backwards
    pose(t + 0.06, frame='camera')                               # wrong frame id
    pose(t + 0.07, (100.0, 0.0, 0.0))                            # a 100 m jump
    pose(t + 3.0e7, (100.0, 0.0, 0.0))                           # a stamp years ahead
    for v in ((math.nan, 0.0, 0.0), (0.0, math.inf, 0.0), (500.0, 0.0, 0.0)):
        w = Wind()
        w.header.frame_id = 'world'
        w.velocity.x, w.velocity.y, w.velocity.z = v
        w.turbulence = 0.5
        wind_pub.publish(w)
        time.sleep(0.05)
    end = time.monotonic() + flood
    k = 0
    while time.monotonic() < end:                                # 2 kHz flood
        k += 1
        m = PoseStamped()
        m.header.stamp = node.get_clock().now().to_msg()
        m.header.frame_id = 'world'
        m.pose.position.x = 100.0 + 0.01 * math.sin(k * 0.01)
        m.pose.orientation.w = 1.0
        pose_pub.publish(m)
        time.sleep(0.0005)
    print('flooded %d poses' % k, flush=True)
    node.destroy_node()
    rclpy.try_shutdown()


if __name__ == '__main__':
    main()
