"""
hair_sim_bench viewer: what a browser page that cannot keep up costs the meshcat server.

For the server the node starts (hair_sim.sinks.meshcat_server) and for meshcat's own
(meshcat.servers.zmqserver), fed one hair-frame-sized set_object at the node's meshcat.rate:

- a page that stopped reading (a frozen tab, an ssh tunnel whose far end sleeps): how much
  the server grows while it lasts;
- a page that reads slower than the stream (SLOW_READS messages a second): how old the hair
  it shows gets, against a page that keeps up (the age of a frame is how long ago the page
  that keeps up had the same one).

Both also report the frames a second the page that keeps up got.
"""

import base64
import hashlib
import os
import socket
import threading
import time

SERVERS = (('hair_sim', False), ('meshcat', True))     # name, meshcat's own
FRAME_BYTES = 337_000       # a thesis_long hair frame in make demo (set_object, msgpack)
RATE = 20.0                 # the node's meshcat.rate
SLOW_READS = 10.0           # messages a second the slow page reads: half the stream


def _rss_mb(pid):
    with open('/proc/%d/status' % pid) as f:
        return int(f.read().split('VmRSS:')[1].split()[0]) / 1024.0


def _ws_url(web_url):
    return web_url.split('/static')[0].replace('http://', 'ws://') + '/'


def _stalled_page(web_url):
    """Open a websocket page on a plain socket that never reads; return the socket."""
    port = int(web_url.split(':')[2].split('/')[0])
    sock = socket.socket()
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
    sock.connect(('127.0.0.1', port))
    key = base64.b64encode(os.urandom(16)).decode()
    sock.sendall(('GET / HTTP/1.1\r\nHost: 127.0.0.1\r\nUpgrade: websocket\r\n'
                  'Connection: Upgrade\r\nSec-WebSocket-Key: %s\r\n'
                  'Sec-WebSocket-Version: 13\r\n\r\n' % key).encode())
    return sock


class _Page(threading.Thread):
    """A websocket page that records when each hair frame came; slow: SLOW_READS a second."""

    def __init__(self, web_url, slow=False):
        super().__init__(daemon=True)
        self.url = _ws_url(web_url)
        self.slow = slow
        self.seen = {}                        # digest -> when it first came
        self.frames = []                      # (time, digest) of each hair frame
        self.stop = threading.Event()
        self.error = None

    def run(self):
        from websockets.sync.client import connect
        try:
            with connect(self.url, max_size=None, max_queue=1 if self.slow else 16,
                         close_timeout=0.5) as ws:
                while not self.stop.is_set():
                    try:
                        data = ws.recv(timeout=0.2)
                    except TimeoutError:
                        continue
                    if data[:4] == b'hair':
                        digest = hashlib.blake2b(data, digest_size=16).digest()
                        now = time.monotonic()
                        self.frames.append((now, digest))
                        self.seen.setdefault(digest, now)
                    if self.slow:
                        time.sleep(1.0 / SLOW_READS)
        except Exception as exc:                      # noqa: B902 - reported, not raised
            self.error = '%s: %s' % (type(exc).__name__, exc)

    def rate(self, since):
        """Return the hair frames a second that came after `since`."""
        t = [f[0] for f in self.frames if f[0] >= since]
        return (len(t) - 1) / (t[-1] - t[0]) if len(t) > 2 else 0.0


def _feed(client, seconds, on_tick=None):
    """Send a fresh hair-sized frame at RATE for `seconds`; return how many went."""
    n = 0
    t0 = time.monotonic()
    while time.monotonic() - t0 < seconds:
        data = b'hair' + os.urandom(FRAME_BYTES - 4)
        client.request([b'set_object', b'/hair_sim/hair', data])
        n += 1
        if on_tick is not None:
            on_tick()
        time.sleep(max(0.0, t0 + n / RATE - time.monotonic()))
    return n


def measure(server, meshcats_own, seconds):
    """Return the stalled-page and slow-page records of one server."""
    from hair_sim.sinks.meshcat_sink import MeshcatClient, start_server
    proc, zmq_url, web_url = start_server(meshcats_own=meshcats_own)
    client = MeshcatClient(zmq_url)
    fast = _Page(web_url)
    pages = [fast]
    stalled = None
    try:
        fast.start()
        time.sleep(0.5)
        _feed(client, 1.0)                    # the pages see a frame before it counts
        rss0 = _rss_mb(proc.pid)
        stalled = _stalled_page(web_url)
        peak = [0.0]
        t0 = time.monotonic()
        sent = _feed(client, seconds,
                     lambda: peak.__setitem__(0, max(peak[0], _rss_mb(proc.pid) - rss0)))
        stalled_row = {'server': server, 'page': 'stopped reading', 'seconds': seconds,
                       'frame_kb': FRAME_BYTES / 1000, 'rate': RATE,
                       'slow_reads': SLOW_READS,
                       'mb_sent': sent * FRAME_BYTES / 2 ** 20,
                       'server_growth_mb': peak[0],
                       'keeping_up_fps': fast.rate(t0)}
        stalled.close()
        stalled = None
        time.sleep(1.0)
        slow = _Page(web_url, slow=True)
        pages.append(slow)
        slow.start()
        t0 = time.monotonic()
        _feed(client, seconds)
        ages = [(t - t0, t - fast.seen[d]) for t, d in slow.frames
                if t >= t0 and d in fast.seen]
        slow_row = {'server': server, 'page': 'reads %g messages a second' % SLOW_READS,
                    'seconds': seconds, 'slow_fps': slow.rate(t0),
                    'age_s_max': max((a for _, a in ages), default=None),
                    'age_s_last': ages[-1][1] if ages else None,
                    'age_s_by_time': [[round(t, 2), round(a, 3)]
                                      for t, a in ages[::max(1, len(ages) // 30)]],
                    'keeping_up_fps': fast.rate(t0)}
        errors = [p.error for p in pages if p.error]
        for row in (stalled_row, slow_row):
            row['page_errors'] = errors
        return [stalled_row, slow_row]
    finally:
        for p in pages:
            p.stop.set()
        for p in pages:
            p.join(timeout=5.0)
        if stalled is not None:
            stalled.close()
        client.close()
        proc.kill()
        proc.wait()


def run(quick):
    """Return the records of both servers (quick: 3 s a case, else 30 s)."""
    seconds = 3.0 if quick else 30.0
    rows = []
    for server, meshcats_own in SERVERS:
        rows += measure(server, meshcats_own, seconds)
    return rows
