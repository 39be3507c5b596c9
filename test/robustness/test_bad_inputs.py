"""Bad poses, winds and a 2 kHz flood from another process: refused, counted, no harm."""

import os
import subprocess
import sys
import time

import numpy as np
import psutil

from helpers.ros import spin_until

HERE = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def test_bad_inputs_and_a_flood_are_survived(node_env):
    """Each bad input is refused/normalised/clamped and counted; memory stays flat."""
    from diagnostic_msgs.msg import DiagnosticArray
    from hair_sim_msgs.msg import HairState
    _, ex, node, client = node_env
    diags, states = [], []
    client.create_subscription(DiagnosticArray, '/diagnostics', diags.append, 10)
    client.create_subscription(HairState, 'hair_state', states.append, 10)
    proc = subprocess.Popen([sys.executable, os.path.join(HERE, 'helpers', 'bad_inputs.py'),
                             '4.0'], env=dict(os.environ, PYTHONPATH=HERE),
                            stdout=subprocess.PIPE, text=True)
    rss = []
    try:
        deadline = time.monotonic() + 60
        while proc.poll() is None and time.monotonic() < deadline:
            ex.spin_once(timeout_sec=0.01)
            if node.counts['poses'] > 50:
                rss.append(psutil.Process().memory_info().rss)
        out = proc.communicate(timeout=20)[0]
    finally:
        if proc.poll() is None:
            proc.kill()
    assert 'flooded' in out
    spin_until(ex, lambda: False, 1.5)
    m, c = node.sim.motion.counts, node.counts
    assert m['invalid'] >= 3 and m['normalised'] >= 1
    assert m['repeated'] + m['out_of_order'] >= 1
    assert m['teleport'] >= 1 and m['clock_jump'] >= 1
    assert c['wrong_frame'] >= 1
    assert c['wind_rejected'] >= 2 and c['wind_clamped'] >= 1
    assert np.linalg.norm(node.sim.wind.velocity) <= node.sim.params.max_wind_speed
    assert c['poses'] > 1000                                 # the flood got through
    assert np.all(np.isfinite(node.sim.pos))
    assert len(node.sim.motion.samples) <= 32               # bounded history
    grow = (max(rss[len(rss) // 2:]) - rss[len(rss) // 4]) / 2 ** 20
    assert grow < 20, 'memory grew by %.1f MiB during the flood' % grow
    assert spin_until(ex, lambda: states and diags, 5.0)
    assert np.all(np.isfinite(np.asarray(states[-1].positions)))
    keys = {kv.key: kv.value for kv in diags[-1].status[0].values}
    assert int(keys['pose_invalid']) >= 3 and int(keys['wind_clamped']) >= 1
    assert int(keys['wrong_frame']) >= 1
