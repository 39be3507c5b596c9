"""
A pipeline's view of running hair_sim nodes, from a separate process.

Subscribes raw (CDR bytes, nothing deserialized) to each node's hair topics and measures
what really arrives: sustained rates, and pose -> hair latency from the stamps (a message
carries the stamp of the head pose it was computed for; latency = arrival wall time minus
that stamp; a node run with use_sim_time stamps with its simulated clock, so the latency
is then not a latency). It also counts the head poses a driver sends, reads the nodes'
/diagnostics (accepted poses, CPU-free counters), and can connect to a meshcat server as a
browser would (a websocket client) to count the hair frames it forwards.

    python -m hair_sim.bench.probe --namespaces /a /b --duration 10 [--meshcat-url URL]

prints one JSON object.
"""

import argparse
from collections import defaultdict
import json
import struct
import sys
import threading
import time

import numpy as np

from hair_sim.arguments import namespace, seconds

# (topic, message type, offset of header.stamp in the CDR payload)
HAIR_TOPICS = (('hair_mesh', 'hair_sim_msgs/msg/HairMesh', 4),
               ('hair_state', 'hair_sim_msgs/msg/HairState', 4),
               ('hair_markers', 'visualization_msgs/msg/MarkerArray', 8))


def _msg_type(name):
    """Return the message class of 'package/msg/Type'."""
    import importlib
    package, _, type_name = name.split('/')
    return getattr(importlib.import_module(package + '.msg'), type_name)


def stamp_of(data, offset):
    """Return header.stamp (s) at `offset` of a serialized message, or None if too short."""
    if len(data) < offset + 8:
        return None
    sec, nsec = struct.unpack_from('<iI', data, offset)
    return sec + nsec * 1e-9


class Probe:
    """Raw subscriptions on the hair topics of some namespaces, with arrival records."""

    def __init__(self, node, namespaces, topics=None):
        from rclpy.qos import qos_profile_sensor_data, QoSProfile, ReliabilityPolicy
        self.topics = [t for t in HAIR_TOPICS if topics is None or t[0] in topics]
        self.node = node
        self.arrivals = defaultdict(list)     # (ns, topic) -> [(monotonic, wall, stamp, bytes)]
        self.poses = defaultdict(list)        # ns -> [monotonic]
        self.diagnostics = defaultdict(list)  # ns -> [(monotonic, {key: value})]
        self.recording = False
        self.window = None                    # (start, end) monotonic, once recorded
        self.seen = set()                     # (ns, topic) that delivered a message at all
        reliable = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)
        for ns in namespaces:
            base = ns.rstrip('/')
            for topic, type_name, offset in self.topics:
                node.create_subscription(_msg_type(type_name), '%s/%s' % (base, topic),
                                         self._recorder(ns, topic, offset), reliable, raw=True)
            node.create_subscription(_msg_type('geometry_msgs/msg/PoseStamped'),
                                     '%s/head_pose' % base, self._pose_recorder(ns),
                                     qos_profile_sensor_data, raw=True)
        node.create_subscription(_msg_type('diagnostic_msgs/msg/DiagnosticArray'),
                                 '/diagnostics', self._on_diagnostics, 50)

    def _recorder(self, ns, topic, offset):
        def record(data):
            self.seen.add((ns, topic))
            if self.recording:
                self.arrivals[(ns, topic)].append((time.monotonic(), time.time(),
                                                   stamp_of(data, offset), len(data)))
        return record

    def _pose_recorder(self, ns):
        def record(_data):
            if self.recording:
                self.poses[ns].append(time.monotonic())
        return record

    def _on_diagnostics(self, msg):
        if not self.recording:
            return
        for st in msg.status:
            if not st.name.startswith('hair_sim: '):
                continue
            fqn = st.name[len('hair_sim: '):]
            ns = fqn.rsplit('/', 1)[0] or '/'
            values = {kv.key: kv.value for kv in st.values}
            # timed by arrival, not by its stamp: a node with use_sim_time stamps it with
            # the simulated clock (a bag's --clock, which can loop back)
            self.diagnostics[ns].append((time.monotonic(), values))

    def _longest_gap_ms(self, arrivals):
        """
        Return the longest time (ms) in the window with no arrival, its edges included.

        Between arrivals only, a stall that began as the window opened went unseen: a
        probe started just before a gale's onset saw 53-68 ms where the node had stopped
        publishing for 222-326 ms, its window's first message the one after the stall
        (2026-11-30).
        """
        start, end = self.window
        return float(1e3 * np.diff([start] + list(arrivals) + [end]).max())

    def report(self, namespaces, window):
        """Return per namespace: topic rates and latencies, poses, accepted share."""
        out = {}
        for ns in namespaces:
            rec = {}
            for topic, _, _ in self.topics:
                a = self.arrivals.get((ns, topic), [])
                lat = [1e3 * (wall - st) for _, wall, st, _ in a if st]
                rec[topic] = {
                    'messages': len(a),
                    'rate_hz': (len(a) - 1) / (a[-1][0] - a[0][0]) if len(a) > 2 else 0.0,
                    'latency_ms_p50': float(np.percentile(lat, 50)) if lat else None,
                    'latency_ms_p95': float(np.percentile(lat, 95)) if lat else None,
                    'latency_ms_max': float(np.max(lat)) if lat else None,
                    'bytes_mean': float(np.mean([n for *_, n in a])) if a else None,
                    'gap_ms_max': self._longest_gap_ms([m for m, *_ in a])}
            poses = self.poses.get(ns, [])
            rec['poses_sent_hz'] = (len(poses) - 1) / (poses[-1] - poses[0]) \
                if len(poses) > 2 else 0.0
            diag = self.diagnostics.get(_diag_ns(ns), [])
            if len(diag) >= 2:
                (t0, d0), (t1, d1) = diag[0], diag[-1]
                accepted = int(d1.get('pose_accepted', 0)) - int(d0.get('pose_accepted', 0))
                rec['poses_accepted_hz'] = accepted / max(t1 - t0, 1e-9)
                rec['poses_accepted_share'] = rec['poses_accepted_hz'] / rec['poses_sent_hz'] \
                    if rec['poses_sent_hz'] else None
                rec['refused_total'] = int(d1.get('refused_total', 0))
                rec['overruns'] = int(d1.get('overruns', 0)) - int(d0.get('overruns', 0))
                # simulated time the node dropped to keep its outputs at rate (its solver
                # over max_physics_share of the wall time), in the window
                rec['time_dropped_s'] = (_float(d1.get('time_dropped_s')) or 0.0) - \
                    (_float(d0.get('time_dropped_s')) or 0.0)
                rec['segment_substep_us'] = _float(d1.get('segment_substep_us'))
                rec['node_latency_ms_p95'] = _float(d1.get('latency_ms_p95'))
                rec['model'], rec['sim_rate'] = d1.get('model'), _float(d1.get('sim_rate'))
            out[ns] = rec
        out['window_s'] = window
        return out


def _diag_ns(ns):
    return '/' + ns.strip('/') if ns.strip('/') else '/'


def _float(text):
    try:
        return float(text)
    except (TypeError, ValueError):
        return None


class MeshcatWatcher:
    """Count the hair frames a meshcat server forwards to a websocket client (a browser)."""

    def __init__(self, web_url, path='/hair_sim/hair'):
        self.ws_url = web_url.replace('http://', 'ws://').split('/static')[0] + '/'
        self.path = path
        self._path = path.encode()
        self.frames = []                       # monotonic arrival of each hair frame
        self.recording = False
        self.error = None
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)

    def start(self):
        """Connect and start counting on a thread."""
        self._thread.start()
        return self

    def stop(self):
        """Stop counting."""
        self._stop.set()
        self._thread.join(timeout=5.0)

    def _run(self):
        from websockets.sync.client import connect
        try:
            with connect(self.ws_url, max_size=None, open_timeout=10) as ws:
                while not self._stop.is_set():
                    try:
                        data = ws.recv(timeout=0.5)
                    except TimeoutError:
                        continue
                    if not isinstance(data, bytes) or not self.recording:
                        continue
                    # the command's type comes first and its path last: no need to unpack
                    if b'set_object' in data[:64] and self._path in data[-128:]:
                        self.frames.append(time.monotonic())
        except Exception as exc:                      # noqa: B902 - reported, not raised
            self.error = '%s: %s' % (type(exc).__name__, exc)

    def rate(self):
        """Return the hair frames per second received while recording."""
        f = self.frames
        return (len(f) - 1) / (f[-1] - f[0]) if len(f) > 2 else 0.0


def measure(namespaces, duration, warmup=2.0, meshcat_url=None, context=None, topics=None,
            connect_timeout=10.0):
    """
    Subscribe, wait for a first message, wait `warmup`, record for `duration` s; return the report.

    The first message of every topic (up to connect_timeout s) is waited for before the
    warm-up: discovery of a new process has taken over two seconds on a loaded machine,
    and a window that opens before it would measure the discovery, not the node.

    topics: the hair topics to subscribe to (default all). A subscriber of the 1 MB
    MarkerArray receives the other topics later while it takes one in (head-of-line in
    the subscriber's DDS); a pipeline's renderer and its RViz are separate processes.
    """
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    node = rclpy.create_node('hair_sim_probe', context=context)
    probe = Probe(node, namespaces, topics)
    watcher = MeshcatWatcher(meshcat_url).start() if meshcat_url else None
    ex = SingleThreadedExecutor(context=context)
    ex.add_node(node)
    try:
        wanted = {(ns, t[0]) for ns in namespaces for t in probe.topics}
        start = time.monotonic()
        while not wanted <= probe.seen and time.monotonic() < start + connect_timeout:
            ex.spin_once(timeout_sec=0.05)
        connect_s = time.monotonic() - start
        end = time.monotonic() + warmup
        while time.monotonic() < end:
            ex.spin_once(timeout_sec=0.05)
        probe.recording = True
        opened = time.monotonic()
        if watcher is not None:
            watcher.recording = True
        print('hair_sim.bench.probe: recording', file=sys.stderr, flush=True)
        end = time.monotonic() + duration
        while time.monotonic() < end:
            ex.spin_once(timeout_sec=0.05)
        probe.recording = False
        probe.window = (opened, time.monotonic())
        report = probe.report(namespaces, duration)
        report['connect_s'] = connect_s
        # topics that never delivered a message (no node, a wrong namespace, a topic off)
        report['silent'] = sorted('%s%s' % (ns.rstrip('/') + '/', topic)
                                  for ns, topic in wanted - probe.seen)
        if watcher is not None:
            report['meshcat'] = {'frames': len(watcher.frames), 'rate_hz': watcher.rate(),
                                 'error': watcher.error}
        return report
    finally:
        if watcher is not None:
            watcher.stop()
        ex.shutdown()
        node.destroy_node()


def main(argv=None):
    """Measure and print one JSON object; exit 1 when a topic delivered no message at all."""
    import rclpy

    from hair_sim.ros.ros_init import init_ros
    parser = argparse.ArgumentParser(prog='hair_sim.bench.probe', description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('--namespaces', nargs='+', type=namespace, default=['/'])
    parser.add_argument('--duration', type=seconds, default=10.0)
    parser.add_argument('--warmup', type=seconds, default=2.0,
                        help='s to wait after the first message of every topic')
    parser.add_argument('--connect-timeout', type=seconds, default=10.0,
                        help='s to wait at most for the first messages')
    parser.add_argument('--meshcat-url', default=None)
    parser.add_argument('--topics', nargs='*', default=None,
                        choices=[t[0] for t in HAIR_TOPICS], help='default: all')
    args = parser.parse_args(argv)
    if args.duration <= 0.0:
        parser.error('--duration must be more than 0 s')
    init_ros()
    try:
        report = measure(args.namespaces, args.duration, args.warmup, args.meshcat_url,
                         topics=args.topics, connect_timeout=args.connect_timeout)
    finally:
        rclpy.try_shutdown()
    print(json.dumps(report), flush=True)
    if report['silent']:
        print('hair_sim.bench.probe: no message at all on %s (is the node running, in that '
              'namespace, with the topic on?)' % ', '.join(report['silent']),
              file=sys.stderr, flush=True)
        return 1
    return 0


if __name__ == '__main__':
    sys.exit(main())
