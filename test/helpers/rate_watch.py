"""
Record when hair_state arrives, raw, in a process of its own; report any span asked for.

A test module's node is checked for health after every attack: over a starting probe
process (hair_sim.bench.probe) each check cost 1.6 s more than its window (its start and
discovery: 3.6 s for a 2 s window), some thirty times a suite. This one is started once
and keeps recording; its arrivals are on the machine's monotonic clock, the test's.

argv: topic. Prints 'watching' once the first message came. Then each stdin line
"start end" (time.monotonic() s) is answered on stdout with one JSON line: messages and
rate_hz in that span.
"""

import json
import sys
import threading
import time

import rclpy
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.qos import QoSProfile, ReliabilityPolicy


def span_report(arrivals, start, end):
    """Return the messages and their rate (Hz, as the probe takes it) within [start, end]."""
    inside = [a for a in arrivals if start <= a <= end]
    return {'messages': len(inside),
            'rate_hz': (len(inside) - 1) / (inside[-1] - inside[0]) if len(inside) > 2 else 0.0}


def main():
    """Subscribe, say when the first message came, answer spans until stdin closes."""
    from hair_sim_msgs.msg import HairState
    rclpy.init()
    node = rclpy.create_node('hair_sim_rate_watch')
    arrivals = []
    node.create_subscription(HairState, sys.argv[1], lambda _: arrivals.append(time.monotonic()),
                             QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE),
                             raw=True)
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    spinner = threading.Thread(target=executor.spin, daemon=True)
    spinner.start()
    try:
        while not arrivals:
            time.sleep(0.01)
        print('watching', flush=True)
        for line in sys.stdin:
            start, end = (float(v) for v in line.split())
            print(json.dumps(span_report(list(arrivals), start, end)), flush=True)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        executor.shutdown(timeout_sec=5.0)
        spinner.join(timeout=5.0)
        node.destroy_node()
        rclpy.try_shutdown()


if __name__ == '__main__':
    main()
