"""hair_sim_node as a separate process, and a client in this process that talks to it."""

import os
import subprocess
import sys
import threading
import time

from hair_sim import paths

VENV_BIN = os.path.dirname(sys.executable)
TEST_DIR = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def start_helper(script, *args, stdout=subprocess.PIPE):
    """Start test/helpers/<script> with args in its own process; its stdout a pipe."""
    return subprocess.Popen([sys.executable, os.path.join(TEST_DIR, 'helpers', script),
                             *map(str, args)],
                            env=dict(os.environ, PYTHONPATH=TEST_DIR), stdout=stdout,
                            text=True)


class NodeProcess:
    """Run `hair_sim_node` (the installed script) with the shipped params plus `args`."""

    def __init__(self, tmp_path, args=(), namespace=None, log_name='node.log'):
        params = os.path.join(paths.config_dir(), 'hair_sim.yaml')
        cmd = [os.path.join(VENV_BIN, 'hair_sim_node'), '--ros-args', '--params-file', params,
               '-p', 'hairstyle_dirs:=["", "%s"]' % tmp_path]
        if namespace:
            cmd += ['-r', '__ns:=%s' % namespace]
        cmd += list(args)
        self.log_path = os.path.join(str(tmp_path), log_name)
        self.log = open(self.log_path, 'w')
        self.proc = subprocess.Popen(cmd, stdout=self.log, stderr=subprocess.STDOUT)

    def alive(self):
        """Return True while the process runs."""
        return self.proc.poll() is None

    def output(self):
        """Return what the node printed so far."""
        self.log.flush()
        with open(self.log_path) as f:
            return f.read()

    def stop(self):
        """Stop the node (SIGINT, then kill); return its exit code."""
        if self.proc.poll() is None:
            self.proc.send_signal(2)
            try:
                self.proc.wait(timeout=15)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait(timeout=5)
        self.log.close()
        return self.proc.returncode


class Client:
    """An rclpy node spun on a background thread: service calls, parameters, subscriptions."""

    def __init__(self, name='hair_sim_test_pipeline'):
        import rclpy
        from rclpy.context import Context
        from rclpy.executors import MultiThreadedExecutor
        self.context = Context()
        rclpy.init(context=self.context)
        self.node = rclpy.create_node(name, context=self.context)
        self.executor = MultiThreadedExecutor(num_threads=4, context=self.context)
        self.executor.add_node(self.node)
        self._clients = {}
        self._lock = threading.Lock()
        self._thread = threading.Thread(target=self.executor.spin, daemon=True)
        self._thread.start()

    def call(self, srv_type, name, request, timeout=30.0):
        """Call a service; return the response, or None when it does not answer in time."""
        with self._lock:
            cli = self._clients.get(name)
            if cli is None:
                cli = self._clients[name] = self.node.create_client(srv_type, name)
        if not cli.wait_for_service(timeout_sec=20.0):
            return None
        future = cli.call_async(request)
        end = time.monotonic() + timeout
        while not future.done() and time.monotonic() < end:
            time.sleep(0.01)
        return future.result() if future.done() else None

    def set_parameters(self, node_name, values, atomically=False):
        """Set parameters {name: value} of node `node_name`; return the result(s)."""
        from rcl_interfaces.srv import SetParameters, SetParametersAtomically
        from rclpy.parameter import Parameter
        params = [Parameter(k, value=v).to_parameter_msg() for k, v in values.items()]
        if atomically:
            r = self.call(SetParametersAtomically, node_name + '/set_parameters_atomically',
                          SetParametersAtomically.Request(parameters=params))
            return None if r is None else r.result
        r = self.call(SetParameters, node_name + '/set_parameters',
                      SetParameters.Request(parameters=params))
        return None if r is None else r.results

    def get_parameters(self, node_name, names):
        """Return {name: value} of node `node_name`."""
        from rcl_interfaces.srv import GetParameters
        from rclpy.parameter import parameter_value_to_python
        r = self.call(GetParameters, node_name + '/get_parameters',
                      GetParameters.Request(names=list(names)))
        return {n: parameter_value_to_python(v) for n, v in zip(names, r.values)}

    def record(self, msg_type, topic, qos=10, raw=False):
        """Subscribe; return the list (time.monotonic(), message) arrivals are appended to."""
        out = []
        self.node.create_subscription(msg_type, topic,
                                      lambda m: out.append((time.monotonic(), m)), qos,
                                      raw=raw)
        return out

    def close(self):
        """
        Shut the client down: the executor, then its spinning thread, then node and context.

        The spin thread is joined before the context goes: shut down under a thread still
        waiting in it, rclpy's executor spun hot on the dead wait set and starved the test's
        main thread of the GIL for minutes (seen in CI, in a module teardown).
        """
        import rclpy
        self.executor.shutdown(timeout_sec=10.0)
        self._thread.join(timeout=10.0)
        self.node.destroy_node()
        rclpy.try_shutdown(context=self.context)


def read_until(proc, found, timeout, what):
    """
    Read a text-mode proc's stdout line by line until found(line); return the lines read.

    The last line returned is the one found. Fails naming `what`, with the output, when the
    timeout passes or the process ends first.
    """
    end = time.monotonic() + timeout
    seen = []
    while time.monotonic() < end:
        seen.append(proc.stdout.readline())
        if found(seen[-1]):
            return seen
        if not seen[-1] and proc.poll() is not None:
            break
    raise AssertionError('%s: not seen\n%s' % (what, ''.join(seen)[-3000:]))


def process_running(pid):
    """Return whether process pid runs (an orphan that ended may stay a zombie of pid 1)."""
    try:
        with open('/proc/%d/stat' % pid) as f:
            return f.read().rsplit(')', 1)[1].split()[0] != 'Z'
    except FileNotFoundError:
        return False


def wait_for(predicate, timeout):
    """Poll predicate() until true or timeout; return its last value."""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if predicate():
            return True
        time.sleep(0.05)
    return predicate()


class ProbeProcess:
    """
    hair_sim.bench.probe running beside a test: started, then waited for while it records.

    The probe subscribes raw in its own process: what any subscriber gets, not what this
    test process's executor finds time to take in (after a storm of service calls it has
    been seen taking in 15 Hz of a topic the probe got at 30.0). It waits for its first
    messages (discovery), then `warmup` s, then records for `duration` s.
    """

    def __init__(self, duration, namespaces=('/',), topics=('hair_state',), warmup=0.2):
        self.duration = duration
        self.proc = subprocess.Popen([sys.executable, '-m', 'hair_sim.bench.probe',
                                      '--duration', str(duration), '--warmup', str(warmup),
                                      '--namespaces', *namespaces, '--topics', *topics],
                                     stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        # it says so on stderr when the window opens (after its discovery)
        for line in self.proc.stderr:
            if 'recording' in line:
                break

    def report(self):
        """Wait for the probe; return its JSON report."""
        import json
        out, err = self.proc.communicate(timeout=60.0 + self.duration)
        assert self.proc.returncode == 0, err[-2000:]
        return json.loads(out.strip().splitlines()[-1])


def probe_rates(window, namespaces=('/',), topics=('hair_state',)):
    """Return {namespace: {topic: Hz}} measured by a ProbeProcess over `window` s."""
    report = ProbeProcess(max(window, 0.5), namespaces, topics, warmup=0.5).report()
    return {ns: {t: report[ns][t]['rate_hz'] for t in topics} for ns in namespaces}


class RateWatch:
    """
    test/helpers/rate_watch.py kept running beside a test module: a topic's arrivals, raw.

    Started once, after the node publishes; `span(start, end)` then reports any span of
    this process's time.monotonic() without a probe process starting (1.6 s a check).
    """

    def __init__(self, topic='hair_state', timeout=60.0):
        self.proc = subprocess.Popen(
            [sys.executable, os.path.join(TEST_DIR, 'helpers', 'rate_watch.py'), topic],
            env=dict(os.environ, PYTHONPATH=TEST_DIR), stdin=subprocess.PIPE,
            stdout=subprocess.PIPE, text=True)
        read_until(self.proc, lambda line: 'watching' in line, timeout,
                   'the rate watch\'s first %s' % topic)

    def span(self, start, end):
        """Return the messages and rate_hz of the arrivals within [start, end]."""
        import json
        assert self.proc.poll() is None, 'the rate watch ended'
        self.proc.stdin.write('%r %r\n' % (start, end))
        self.proc.stdin.flush()
        return json.loads(self.proc.stdout.readline())

    def close(self):
        """End the watch (its stdin closed) and wait for it."""
        try:
            self.proc.stdin.close()
            self.proc.wait(timeout=15)
        except (OSError, subprocess.TimeoutExpired):
            self.proc.kill()
            self.proc.wait(timeout=5)


def rate(arrivals, since):
    """Return how many records per second arrived after `since` (records: time, message)."""
    t = [a for a, _ in arrivals if a >= since]
    return (len(t) - 1) / (t[-1] - t[0]) if len(t) > 2 else 0.0


def diagnostics_values(arrivals, fqn='/hair_sim'):
    """Return the newest /diagnostics values {key: str} of the node named fqn."""
    for _, msg in reversed(arrivals):
        for st in msg.status:
            if st.name == 'hair_sim: %s' % fqn:
                return {kv.key: kv.value for kv in st.values}
    return {}
