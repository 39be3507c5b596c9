"""
hair_sim_bench node: the node measured the way a pipeline meets it.

For k = 1, 2, ... avatars: k `hair_sim_node` processes in namespaces /avatar_0 ...
(thesis_long, shipped parameters; the first also streams to meshcat), each driven by its
own `hair_sim_head_driver` process at 100 Hz. Two more processes subscribe raw, as a
pipeline would: a renderer (hair_mesh, hair_state) and an RViz stand-in (hair_markers).
Per node: the sustained rate of each topic, the share of poses accepted, pose -> hair
latency from the stamps (p50/p95/max), CPU of the node process; the meshcat frame rate as
a websocket client (a browser) receives it. k grows until some avatar no longer sustains
its rates (30 Hz hair_mesh/hair_state, 10 Hz markers, >= 95 % poses): the last k that did
is how many thesis_long avatars this machine runs at 30 Hz. Finally, with one avatar, the
longest gap between hair_state messages while the largest style inside the frame budget
loads.
"""

import contextlib
import json
import os
import subprocess
import sys
import tempfile
import time

import psutil
import yaml

from hair_sim import budget, paths

BIN = os.path.dirname(sys.executable)
SUSTAIN = {'hair_mesh': 30.0, 'hair_state': 30.0, 'hair_markers': 10.0}


def _node_cmd(ns, meshcat):
    params = os.path.join(paths.config_dir(), 'hair_sim.yaml')
    return [os.path.join(BIN, 'hair_sim_node'), '--ros-args', '--params-file', params,
            '-r', '__ns:=%s' % ns, '-p', 'meshcat.enabled:=%s' % str(meshcat).lower()]


def _probe(namespaces, duration, warmup, topics, meshcat_url=None, recording=False):
    """
    Start a probe process; with `recording`, return once its window is open.

    (It says so on stderr, after its discovery and warm-up.)
    """
    cmd = [sys.executable, '-m', 'hair_sim.bench.probe', '--namespaces'] + namespaces + [
        '--duration', str(duration), '--warmup', str(warmup), '--topics'] + topics
    if meshcat_url:
        cmd += ['--meshcat-url', meshcat_url]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, text=True,
                            stderr=subprocess.PIPE if recording else subprocess.DEVNULL)
    if recording:
        for line in proc.stderr:            # (the rest is read with stdout, communicate())
            if 'recording' in line:
                break
    return proc


def _meshcat_url(log_path, timeout=60.0):
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        with open(log_path) as f:
            for line in f:
                if 'meshcat URL ' in line:
                    return line.split('meshcat URL ')[1].split()[0]
        time.sleep(0.2)
    return None


def run_avatars(k, duration, workdir):
    """Run k avatars; return the per-node records and whether all sustained their rates."""
    namespaces = ['/avatar_%d' % i for i in range(k)]
    procs, logs = [], []
    try:
        for i, ns in enumerate(namespaces):
            log = os.path.join(workdir, 'node_%d.log' % i)
            logs.append(log)
            procs.append(subprocess.Popen(_node_cmd(ns, meshcat=(i == 0)),
                                          stdout=open(log, 'w'), stderr=subprocess.STDOUT))
        url = _meshcat_url(logs[0])
        drivers = [subprocess.Popen([os.path.join(BIN, 'hair_sim_head_driver'), '--ros-args',
                                     '-r', '__ns:=%s' % ns], stdout=subprocess.DEVNULL,
                                    stderr=subprocess.DEVNULL) for ns in namespaces]
        procs += drivers
        time.sleep(3.0)
        nodes = [psutil.Process(p.pid) for p in procs[:k]]
        for n in nodes:
            n.cpu_percent(None)
        warmup = 4.0
        # three subscriber processes, as a pipeline has them: a renderer, RViz, a browser
        renderer = _probe(namespaces, duration, warmup, ['hair_mesh', 'hair_state'])
        rviz = _probe(namespaces, duration, warmup, ['hair_markers'])
        browser = _probe(namespaces[:1], duration, warmup, [], url) if url else None
        time.sleep(warmup)
        for n in nodes:
            n.cpu_percent(None)
        a = json.loads(renderer.communicate(timeout=duration + 120)[0])
        b = json.loads(rviz.communicate(timeout=60)[0])
        c = json.loads(browser.communicate(timeout=60)[0]) if browser else {}
        cpu = [n.cpu_percent(None) for n in nodes]
    finally:
        _stop(procs)
    records = []
    ok = True
    for i, ns in enumerate(namespaces):
        rec = {'avatars': k, 'namespace': ns, 'cpu_percent_of_a_core': cpu[i]}
        rec.update({k2: v for k2, v in a[ns].items()})
        rec['hair_markers'] = b[ns]['hair_markers']
        for topic, hz in SUSTAIN.items():
            rec['%s_rate_hz' % topic] = rec[topic]['rate_hz']
            ok &= rec[topic]['rate_hz'] >= 0.95 * hz
        ok &= (rec.get('poses_accepted_share') or 0.0) >= 0.95
        records.append(rec)
    return records, ok, c.get('meshcat', {})


def load_gap(workdir, duration=6.0):
    """Return the longest hair_state gap (ms) while the largest in-budget style loads."""
    from hair_sim.bench.probe import Probe
    import rclpy
    from rclpy.executors import SingleThreadedExecutor

    from hair_sim.ros.ros_init import init_ros
    from hair_sim_msgs.srv import LoadHairstyle
    data = yaml.safe_load(open(paths.shipped_style('thesis_long')))
    strips = 46
    while budget.core_share(2 * (strips + 2) * 10, (strips + 2) * 7 * 30) < budget.CPU_SHARE:
        strips += 2
    data['patches'][0]['strips'] = strips
    with open(os.path.join(workdir, 'largest.yaml'), 'w') as f:
        yaml.safe_dump(data, f)
    params = os.path.join(paths.config_dir(), 'hair_sim.yaml')
    node = subprocess.Popen([os.path.join(BIN, 'hair_sim_node'), '--ros-args', '--params-file',
                             params, '-p', 'hairstyle_dirs:=["", "%s"]' % workdir],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    init_ros()
    client = rclpy.create_node('hair_sim_bench_loader')
    probe = Probe(client, ['/'], ['hair_state'])
    ex = SingleThreadedExecutor()
    ex.add_node(client)
    try:
        cli = client.create_client(LoadHairstyle, '/hair_sim/load_hairstyle')
        cli.wait_for_service(timeout_sec=60.0)
        end = time.monotonic() + 3.0
        while time.monotonic() < end:
            ex.spin_once(timeout_sec=0.05)
        probe.recording = True
        gaps = []
        for name in ('largest', 'thesis_long', 'largest'):
            t0 = time.monotonic()
            future = cli.call_async(LoadHairstyle.Request(path=name))
            while not future.done():
                ex.spin_once(timeout_sec=0.01)
            answered = time.monotonic() - t0
            end = time.monotonic() + 1.0
            while time.monotonic() < end:
                ex.spin_once(timeout_sec=0.01)
            # from the last message before the call to the window's end (a stall that
            # began with the call is then a gap, not hidden before the first message after)
            arrivals = [m for m, *_ in probe.arrivals[('/', 'hair_state')]]
            t = [m for m in arrivals if m < t0][-1:] + [m for m in arrivals if m >= t0] + \
                [time.monotonic()]
            gaps.append({'style': name, 'strips': strips if name == 'largest' else 46,
                         'success': future.result().success, 'answer_s': answered,
                         'longest_gap_ms': 1e3 * max(b - a for a, b in zip(t, t[1:]))})
        return gaps
    finally:
        ex.shutdown()
        client.destroy_node()
        rclpy.try_shutdown()
        node.send_signal(2)
        node.wait(timeout=15)


def _stop(procs):
    """Ctrl-C each of `procs` still running, then wait for them (15 s each, else kill)."""
    for p in procs:
        if p.poll() is None:
            p.send_signal(2)
    for p in procs:
        try:
            p.wait(timeout=15)
        except subprocess.TimeoutExpired:
            p.kill()


@contextlib.contextmanager
def _node_in_bench_wind(node_args, client_name):
    """
    Run a node (`node_args` after the shipped parameters, meshcat off) in a wind from here.

    Its head driver runs beside it with its gusts remapped away; yields (the node's
    process, an executor of a client node, that client's publisher on /wind), and stops
    them all.
    """
    import rclpy
    from rclpy.executors import SingleThreadedExecutor

    from hair_sim.ros.ros_init import init_ros
    from hair_sim_msgs.msg import Wind
    node = subprocess.Popen(_node_cmd('/', False) + list(node_args),
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    driver = subprocess.Popen([os.path.join(BIN, 'hair_sim_head_driver'), '--ros-args',
                               '-r', 'wind:=driver_wind'],
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    init_ros()
    client = rclpy.create_node(client_name)
    ex = SingleThreadedExecutor()
    ex.add_node(client)
    try:
        yield node, ex, client.create_publisher(Wind, '/wind', 10)
    finally:
        ex.shutdown()
        client.destroy_node()
        rclpy.try_shutdown()
        _stop((driver, node))


def gale(duration=10.0, speed=40.0, turbulence=1.0):
    """
    Measure the articulated model at 60 Hz in the strongest wind the node takes, from outside.

    One node (articulated, sim_rate 60) driven by the head driver (its gusts remapped away),
    measured by a probe process before, during and after a wind of `speed` m/s with
    `turbulence` that this process publishes at 20 Hz: the rates, the latency, the longest
    gap, the poses accepted, and the simulated time the node dropped in the probe's window
    (its solver gets max_physics_share of the wall time; a step in this gale needs up to
    0.4 s of substeps). Each phase's wind starts once the probe's window is open, so the
    gale's longest gap includes its onset: the hair at rest outruns its first step, and a
    retry not cut to the bound stopped the outputs for 155-240 ms there (2026-11-30).
    """
    from hair_sim_msgs.msg import Wind
    out = {'speed_m_s': speed, 'turbulence': turbulence, 'phases': []}
    with _node_in_bench_wind(['-p', 'physics.model:=articulated', '-p', 'sim_rate:=60.0'],
                             'hair_sim_bench_gale') as (_, ex, pub):
        time.sleep(5.0)
        for phase, wind in (('before', 0.0), ('gale', speed), ('after', 0.0)):
            w = Wind()
            w.velocity.x, w.velocity.y = wind, (5.0 if wind else 0.0)
            w.turbulence, w.seed = (turbulence if wind else 0.0), 3
            probe = _probe(['/'], duration, 1.0, ['hair_mesh', 'hair_state'],
                           recording=True)
            end = time.monotonic() + duration + 6.0
            while probe.poll() is None and time.monotonic() < end + 60.0:
                if time.monotonic() < end:
                    pub.publish(w)
                ex.spin_once(timeout_sec=0.05)
            report = json.loads(probe.communicate(timeout=60)[0])['/']
            rec = {'phase': phase, 'wind_m_s': wind}
            for topic in ('hair_mesh', 'hair_state'):
                r = report[topic]
                rec[topic] = {k: r[k] for k in ('rate_hz', 'latency_ms_p95', 'gap_ms_max')}
            # (the probe reads the node's diagnostics over its window: the time dropped)
            for key in ('poses_accepted_share', 'time_dropped_s', 'segment_substep_us'):
                rec[key] = report.get(key)
            out['phases'].append(rec)
            if phase == 'gale':                 # the wind off, and time for the hair to fall
                w.velocity.x = w.velocity.y = w.turbulence = 0.0
                end = time.monotonic() + 8.0
                while time.monotonic() < end:
                    pub.publish(w)
                    ex.spin_once(timeout_sec=0.05)
    return out


def wind_stream(duration=10.0, rates=(0.0, 60.0, 240.0)):
    """
    Measure what a stream of wind messages costs the node, from outside.

    One node (thesis_long, shipped parameters, no meshcat) and its head driver (its gusts
    remapped away); for each rate, this process publishes a changing wind (2-3 m/s, gusts
    of turbulence 0.3) at that rate (0: one such wind, at the start, that then blows on)
    while a probe process records over `duration`: the node process's CPU share over the
    window, hair_state's rate and p95 latency, the poses accepted and the time dropped.
    Until 2026-12-02 a wind change made the next step type every kernel argument again
    (0.6 ms more, at 1/240 s).
    """
    import math

    from hair_sim_msgs.msg import Wind
    out = []
    with _node_in_bench_wind([], 'hair_sim_bench_wind_stream') as (node, ex, pub):
        time.sleep(5.0)
        proc = psutil.Process(node.pid)
        for rate in rates:
            probe = _probe(['/'], duration, 1.0, ['hair_state'], recording=True)
            cpu0, wall0 = sum(proc.cpu_times()[:2]), time.monotonic()
            sent, end, cpu = 0, wall0 + duration, None
            while probe.poll() is None and time.monotonic() < end + 60.0:
                now = time.monotonic()
                if now < end and (sent < (now - wall0) * rate or not sent):
                    w = Wind()
                    w.velocity.x = 2.0 + math.sin(now)
                    w.velocity.y = math.cos(0.7 * now)
                    w.turbulence, w.seed = 0.3, 1
                    pub.publish(w)
                    sent += 1
                if now >= end and cpu is None:
                    cpu = (sum(proc.cpu_times()[:2]) - cpu0) / (now - wall0)
                ex.spin_once(timeout_sec=0.0 if rate else 0.05)
                if rate:
                    time.sleep(max(0.0, wall0 + (sent + 1) / rate - time.monotonic()))
            report = json.loads(probe.communicate(timeout=60)[0])['/']
            r = report['hair_state']
            out.append({'wind_hz': rate, 'sent': sent,
                        'node_cpu_share': None if cpu is None else round(cpu, 3),
                        'hair_state_hz': r['rate_hz'],
                        'latency_ms_p95': r['latency_ms_p95'],
                        'poses_accepted_share': report.get('poses_accepted_share'),
                        'time_dropped_s': report.get('time_dropped_s')})
    return out


def run(quick=False, max_avatars=8):
    """Measure 1, 2, ... avatars until one fails its rates; then the load gap and a gale."""
    duration = 5.0 if quick else 10.0
    out = {'runs': [], 'meshcat': None}
    sustained = 0
    with tempfile.TemporaryDirectory() as workdir:
        for k in range(1, (2 if quick else max_avatars) + 1):
            records, ok, meshcat = run_avatars(k, duration, workdir)
            out['runs'] += records
            if k == 1:
                out['meshcat'] = meshcat
            if not ok:
                break
            sustained = k
        out['avatars_sustained_at_30hz'] = sustained
        out['load_gap'] = load_gap(workdir)
    out['gale'] = gale(5.0 if quick else 10.0)
    out['wind_stream'] = wind_stream(5.0 if quick else 10.0)
    return out
