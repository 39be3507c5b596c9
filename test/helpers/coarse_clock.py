"""
Publish /clock at a given rate and speed, as a simulator or `ros2 bag play -r` does (process).

argv: rate_hz speed duration_s [jitter [lead_s]]
Once a /clock subscriber is seen, the clock starts at the wall time and advances speed / rate_hz
s every 1 / rate_hz s of wall time, for duration_s; then it says how far it went from its start
and 'done'. With jitter, each tick goes out up to jitter / rate_hz s early or late (seeded), as a
loaded simulator's do; the time each carries stays regular. With lead_s, the clock first stands
at its start for lead_s s of wall time (a tick every 1 / rate_hz s), as a simulator's that starts
paused: a subscriber that missed the first ticks (its side of the discovery not done yet, or its
process not scheduled) still sees where the clock started.
"""

import random
import sys
import time

import rclpy


def main():
    """Publish the clock."""
    from rosgraph_msgs.msg import Clock

    rate, speed, duration = (float(v) for v in sys.argv[1:4])
    jitter = float(sys.argv[4]) if len(sys.argv) > 4 else 0.0
    lead = float(sys.argv[5]) if len(sys.argv) > 5 else 0.0
    rng = random.Random(21)
    rclpy.init()
    node = rclpy.create_node('coarse_clock_publisher')
    pub = node.create_publisher(Clock, '/clock', 10)
    deadline = time.monotonic() + 20.0
    while pub.get_subscription_count() == 0 and time.monotonic() < deadline:
        time.sleep(0.05)
    t = t0 = time.time()
    msg = Clock()
    msg.clock.sec, msg.clock.nanosec = int(t), int((t - int(t)) * 1e9)
    stand = time.monotonic()
    while time.monotonic() - stand < lead:
        pub.publish(msg)
        time.sleep(1.0 / rate)
    start = time.monotonic()
    ticks = 0
    while time.monotonic() - start < duration:
        msg = Clock()
        msg.clock.sec, msg.clock.nanosec = int(t), int((t - int(t)) * 1e9)
        pub.publish(msg)
        ticks += 1
        t = t0 + ticks * speed / rate
        due = start + (ticks + rng.uniform(-jitter, jitter)) / rate
        time.sleep(max(0.0, due - time.monotonic()))
    time.sleep(0.5)                   # (the last tick reaches the node before we go)
    print('advanced %.3f' % (t - t0 - speed / rate), flush=True)
    print('done', flush=True)
    node.destroy_node()
    rclpy.try_shutdown()


if __name__ == '__main__':
    main()
