"""
Publish head poses at 100 Hz whose stamps jump back, like a looping bag (separate process).

argv: jump_back_s before_s after_s x_after [clock]
It says 'publishing' once the node's subscription is seen, and 'done' at the end. For
before_s seconds poses at the origin stamped now; then the stamps jump back by
jump_back_s and keep running from there, with the head moved to (x_after, 0, 0). With
`clock`, the same time goes out on /clock too, as `ros2 bag play --clock --loop` sends it
to nodes on use_sim_time.
"""

import sys
import time

import rclpy
from rclpy.qos import qos_profile_sensor_data


def main():
    """Publish, jump the clock back, publish on."""
    from geometry_msgs.msg import PoseStamped

    from rosgraph_msgs.msg import Clock

    jump, before, after, x_after = (float(v) for v in sys.argv[1:5])
    rclpy.init()
    node = rclpy.create_node('looping_clock_publisher')
    pub = node.create_publisher(PoseStamped, 'head_pose', qos_profile_sensor_data)
    clock = node.create_publisher(Clock, '/clock', 10) if sys.argv[5:6] == ['clock'] else None
    deadline = time.monotonic() + 20.0
    while pub.get_subscription_count() == 0 and time.monotonic() < deadline:
        time.sleep(0.05)
    print('publishing', flush=True)       # (a test may start measuring from here)
    msg = PoseStamped()
    msg.header.frame_id = 'world'
    msg.pose.orientation.w = 1.0
    start = time.monotonic()
    while time.monotonic() - start < before + after:
        elapsed = time.monotonic() - start
        t = time.time()
        if elapsed >= before:
            t -= jump
            msg.pose.position.x = x_after
        msg.header.stamp.sec = int(t)
        msg.header.stamp.nanosec = int((t - int(t)) * 1e9)
        if clock is not None:
            clock.publish(Clock(clock=msg.header.stamp))
        pub.publish(msg)
        time.sleep(0.01)
    print('done', flush=True)
    node.destroy_node()
    rclpy.try_shutdown()


if __name__ == '__main__':
    main()
