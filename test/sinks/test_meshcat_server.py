"""The meshcat server hair_sim starts: a page that stops reading costs bounded memory."""

import base64
import os
import socket
import struct
import threading
import time

from hair_sim.sinks.meshcat_server import MAX_BACKLOG
from hair_sim.sinks.meshcat_sink import MeshcatClient, start_server

FRAME_BYTES = 300_000           # about a thesis_long hair frame
FRAMES = 100                    # 30 MB in all


def rss_bytes(pid):
    """Return the resident memory of process pid."""
    with open('/proc/%d/status' % pid) as f:
        return int(f.read().split('VmRSS:')[1].split()[0]) * 1024


class RawPage:
    """A websocket page on a plain socket: it reads only when told to."""

    def __init__(self, web_url):
        port = int(web_url.split(':')[2].split('/')[0])
        self.sock = socket.socket()
        self.sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
        self.sock.connect(('127.0.0.1', port))
        key = base64.b64encode(os.urandom(16)).decode()
        self.sock.sendall(('GET / HTTP/1.1\r\nHost: 127.0.0.1\r\nUpgrade: websocket\r\n'
                           'Connection: Upgrade\r\nSec-WebSocket-Key: %s\r\n'
                           'Sec-WebSocket-Version: 13\r\n\r\n' % key).encode())
        self.buf = b''

    def _need(self, n, deadline):
        while len(self.buf) < n:
            self.sock.settimeout(max(0.01, deadline - time.monotonic()))
            chunk = self.sock.recv(1 << 20)
            if not chunk:
                raise ConnectionError('the server closed the page')
            self.buf += chunk

    def messages(self, timeout, last=None):
        """
        Read and return the messages that arrive within timeout (server frames unmasked).

        If last is given, return as soon as it arrived.
        """
        deadline = time.monotonic() + timeout
        out = []
        try:
            self._need(4, deadline)
            if self.buf.startswith(b'HTTP/'):
                while b'\r\n\r\n' not in self.buf:
                    self._need(len(self.buf) + 1, deadline)
                self.buf = self.buf.split(b'\r\n\r\n', 1)[1]
            while time.monotonic() < deadline:
                self._need(2, deadline)
                n, at = self.buf[1] & 0x7F, 2
                if n == 126:
                    self._need(4, deadline)
                    n, at = struct.unpack('>H', self.buf[2:4])[0], 4
                elif n == 127:
                    self._need(10, deadline)
                    n, at = struct.unpack('>Q', self.buf[2:10])[0], 10
                self._need(at + n, deadline)
                out.append(self.buf[at:at + n])
                self.buf = self.buf[at + n:]
                if last is not None and out[-1] == last:
                    break
        except socket.timeout:
            pass
        return out

    def close(self):
        """Close the socket."""
        self.sock.close()


def test_a_page_that_stops_reading_skips_frames_and_then_shows_the_newest():
    """
    A page that stops reading holds no more than about MAX_BACKLOG in the server.

    meshcat's own server keeps all it could not send (it grew by the stream's 6.5 MB/s):
    here 30 MB go out while one page reads nothing. The server grows by less than a
    third of that; a page that keeps up gets every frame; the stalled page, once it reads
    again, gets fewer, the newest last, and then new frames as they come.
    """
    from websockets.sync.client import connect
    assert FRAMES * FRAME_BYTES > 20 * MAX_BACKLOG
    proc, zmq_url, web_url = start_server()
    client = MeshcatClient(zmq_url)
    stalled = RawPage(web_url)
    got = []
    stop = threading.Event()

    def keep_up():
        with connect(web_url.split('/static')[0].replace('http', 'ws') + '/',
                     max_size=None) as ws:
            while not stop.is_set():
                try:
                    got.append(ws.recv(timeout=0.2))
                except TimeoutError:
                    pass

    reader = threading.Thread(target=keep_up, daemon=True)
    try:
        reader.start()
        time.sleep(1.0)
        rss0 = rss_bytes(proc.pid)
        frames = [os.urandom(FRAME_BYTES) for _ in range(FRAMES)]
        grew = 0
        for data in frames:
            assert client.request([b'set_object', b'/hair_sim/hair', data]) == b'ok'
            grew = max(grew, rss_bytes(proc.pid) - rss0)
            time.sleep(0.02)            # 15 MB/s: twice the demo's stream, no flood
        deadline = time.monotonic() + 20
        while len(got) < FRAMES and time.monotonic() < deadline:
            time.sleep(0.1)
        assert got == frames                       # the page that keeps up: every frame
        assert grew < FRAMES * FRAME_BYTES / 3, grew / 2 ** 20

        seen = stalled.messages(timeout=10.0, last=frames[-1])
        assert frames[0] in seen                   # what it was sent before it fell behind
        assert len(seen) < FRAMES / 2, len(seen)   # frames skipped
        assert seen[-1] == frames[-1]              # the scene as it is now: the newest
        newer = os.urandom(FRAME_BYTES)
        assert client.request([b'set_object', b'/hair_sim/hair', newer]) == b'ok'
        assert stalled.messages(timeout=3.0, last=newer) == [newer]   # caught up: sent again
    finally:
        stop.set()
        reader.join(timeout=5.0)
        stalled.close()
        client.close()
        proc.kill()
        proc.wait()


def test_a_page_that_fell_behind_is_sent_the_deletes_it_missed_before_the_scene():
    """
    A page that skipped a delete (a style load redraws the head) loses what went.

    The scene tree only holds what is: resending it alone would leave the old head's
    spheres on the page under the new head's mesh.
    """
    proc, zmq_url, web_url = start_server()
    client = MeshcatClient(zmq_url)
    stalled = RawPage(web_url)
    try:
        sphere = b'sphere' + os.urandom(100)
        assert client.request([b'set_object', b'/hair_sim/head/sphere_0', sphere]) == b'ok'
        frames = [os.urandom(FRAME_BYTES) for _ in range(40)]
        for data in frames:
            assert client.request([b'set_object', b'/hair_sim/hair', data]) == b'ok'
        gone = b'delete' + os.urandom(100)
        mesh = b'mesh' + os.urandom(100)
        for _ in range(2):                          # a second delete of it: sent once
            assert client.request([b'delete', b'/hair_sim/head', gone]) == b'ok'
            assert client.request([b'set_object', b'/hair_sim/head/mesh', mesh]) == b'ok'
        seen = stalled.messages(timeout=5.0)
        assert sphere in seen and frames[0] in seen
        assert sum(f in seen for f in frames) < len(frames) / 2     # it fell behind
        assert seen.count(gone) == 1
        after = seen[seen.index(gone):]
        assert mesh in after and sphere not in after and after[-1] in (mesh, frames[-1])
        assert frames[-1] in after
    finally:
        stalled.close()
        client.close()
        proc.kill()
        proc.wait()


def test_the_server_does_not_load_the_simulator():
    """The server is a small process: it does not import hair_sim (numba, the solvers)."""
    proc, _, _ = start_server()
    try:
        with open('/proc/%d/maps' % proc.pid) as f:
            maps = f.read()
        assert 'numpy' in maps or 'zmq' in maps         # (it does load libraries)
        assert 'numba' not in maps and 'llvmlite' not in maps
    finally:
        proc.kill()
        proc.wait()


def test_a_page_that_opens_gets_the_last_value_of_each_property_once():
    """
    Redraws set the same properties again; a page that opens gets each one's last value.

    meshcat's own server appends them all to the scene and replays them to every new page
    (the node sets three on each redraw: after 600 style loads, 1800 of them).
    """
    import umsgpack
    from meshcat.commands import SetProperty
    from hair_sim.sinks.meshcat_sink import node_path
    proc, zmq_url, web_url = start_server()
    client = MeshcatClient(zmq_url)
    page = None
    try:
        for i in range(50):
            client.send(SetProperty('visible', i % 2 == 0, node_path('/Grid')))
            client.send(SetProperty('position', [float(i), 0.0, 1.0],
                                    node_path('/Cameras/default/rotated/<object>')))
        client.send(SetProperty('visible', True, node_path('/Axes')))
        page = RawPage(web_url)
        sent = [umsgpack.unpackb(m) for m in page.messages(timeout=2.0)]
        got = sorted((m['path'], m['property'], str(m['value'])) for m in sent)
        assert got == sorted([('/Grid', 'visible', 'False'),
                              ('/Cameras/default/rotated/<object>', 'position',
                               str([49.0, 0.0, 1.0])),
                              ('/Axes', 'visible', 'True')])
    finally:
        if page is not None:
            page.close()
        client.close()
        proc.kill()
        proc.wait()


def listening_sockets(pid):
    """Return (address as /proc/net shows it, port) of each TCP socket pid listens on."""
    inodes = set()
    for fd in os.listdir('/proc/%d/fd' % pid):
        try:
            target = os.readlink('/proc/%d/fd/%s' % (pid, fd))
        except OSError:
            continue
        if target.startswith('socket:['):
            inodes.add(target[8:-1])
    out = []
    for table in ('tcp', 'tcp6'):
        with open('/proc/net/' + table) as f:
            for line in f.read().splitlines()[1:]:
                fields = line.split()
                if fields[3] == '0A' and fields[9] in inodes:          # LISTEN
                    address, port = fields[1].split(':')
                    out.append((address, int(port, 16)))
    return out


def test_the_page_is_served_on_the_loopback_only():
    """The page and its websocket listen on 127.0.0.1 (the URL's host), not every interface."""
    proc, zmq_url, web_url = start_server()
    try:
        web_port = int(web_url.split(':')[2].split('/')[0])
        sockets = listening_sockets(proc.pid)
        assert web_port in [port for _, port in sockets], sockets
        assert all(address == '0100007F' for address, _ in sockets), sockets
    finally:
        proc.kill()
        proc.wait()
