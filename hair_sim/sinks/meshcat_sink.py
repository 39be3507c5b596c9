"""
meshcat sink: the head drawn once, the hair streamed as one textured mesh per frame.

Everything meshcat happens on a worker thread, rate limited, fed the newest frame only:
the simulation never waits for the browser. The client talks zmq with time-outs, so a
missing, killed or slow server is logged and retried, never a hang.
"""

import atexit
import os
import re
import subprocess
import sys
import threading
import time

import numpy as np

from hair_sim.sinks.markers import SKIN_RGB

SERVER_START_TIMEOUT = 20.0
SERVER_SCRIPT = os.path.join(os.path.dirname(os.path.abspath(__file__)), 'meshcat_server.py')
REPLY_TIMEOUT_MS = 3000
RETRY_PERIOD = 2.0


def _geometry_classes():
    import meshcat.geometry as g

    class UVMeshGeometry(g.Geometry):
        """TriangularMeshGeometry with a uv attribute: a three.js BufferGeometry."""

        def __init__(self, vertices, faces, uvs):
            super().__init__()
            self.vertices = np.asarray(vertices, dtype=np.float32)
            self.faces = np.asarray(faces, dtype=np.uint32)
            self.uvs = np.asarray(uvs, dtype=np.float32)

        def lower(self, object_data):
            return {'uuid': self.uuid, 'type': 'BufferGeometry',
                    'data': {'attributes': {'position': g.pack_numpy_array(self.vertices.T),
                                            'uv': g.pack_numpy_array(self.uvs.T)},
                             'index': g.pack_numpy_array(self.faces.T)}}

    return g, UVMeshGeometry


def node_path(text):
    """Return a meshcat Path for '/a/b/c' (commands lower a plain str with str.lower())."""
    from meshcat.path import Path
    return Path(tuple(part for part in text.split('/') if part))


def start_server(on_log=None, meshcats_own=False):
    """
    Start a meshcat server as a subprocess; return (process, zmq_url, web_url).

    It is meshcat's own with a bounded backlog per page (hair_sim/sinks/meshcat_server.py,
    run as a file: `-m hair_sim.sinks...` would import the whole package, numba and all,
    into the server), or with meshcats_own meshcat's as it is, for comparison. on_log(line),
    if given, takes the lines it prints about pages falling behind.
    """
    env = dict(os.environ)
    server = (['-m', 'meshcat.servers.zmqserver'] if meshcats_own
              else [SERVER_SCRIPT, '--parent-pid', str(os.getpid())])
    proc = subprocess.Popen([sys.executable, '-u'] + server,
                            stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, env=env,
                            start_new_session=True)
    zmq_url = web_url = None
    deadline = time.monotonic() + SERVER_START_TIMEOUT
    while (zmq_url is None or web_url is None) and time.monotonic() < deadline:
        line = proc.stdout.readline().decode('utf-8', 'replace').strip()
        if not line and proc.poll() is not None:
            break
        m = re.search(r'(tcp://[^\s]+)', line)
        if m and zmq_url is None:
            zmq_url = m.group(1)
        m = re.search(r'(https?://[^\s]+)', line)
        if m and web_url is None and 'zmq' not in line:
            web_url = m.group(1)
    if zmq_url is None or web_url is None:
        proc.kill()
        raise RuntimeError('the meshcat server did not start')
    threading.Thread(target=_drain, args=(proc, on_log), daemon=True).start()
    # The server runs in its own session, so nothing stops it but this process: should
    # this process end without MeshcatSink.stop (an error or a Ctrl-C while the node is
    # still being built), it is killed at exit rather than left holding its port.
    atexit.register(_kill_if_running, proc)
    return proc, zmq_url, web_url


def _kill_if_running(proc):
    if proc.poll() is None:
        proc.kill()
        proc.wait(timeout=5.0)


def _drain(proc, on_log=None):
    from hair_sim.sinks.meshcat_server import LOG_PREFIX
    for raw in iter(proc.stdout.readline, b''):
        line = raw.decode('utf-8', 'replace').strip()
        if on_log is not None and line.startswith(LOG_PREFIX):
            on_log(line[len(LOG_PREFIX):].strip())


class MeshcatClient:
    """A meshcat zmq client whose calls time out instead of blocking for ever."""

    def __init__(self, zmq_url):
        import zmq
        self._zmq = zmq
        self.zmq_url = zmq_url
        self.ctx = zmq.Context.instance()
        self.sock = None
        self._connect()

    def _connect(self):
        zmq = self._zmq
        if self.sock is not None:
            self.sock.close(linger=0)
        self.sock = self.ctx.socket(zmq.REQ)
        self.sock.setsockopt(zmq.RCVTIMEO, REPLY_TIMEOUT_MS)
        self.sock.setsockopt(zmq.SNDTIMEO, REPLY_TIMEOUT_MS)
        self.sock.setsockopt(zmq.LINGER, 0)
        self.sock.connect(self.zmq_url)

    def request(self, parts):
        """Send a multipart request and wait for the reply; raise TimeoutError on silence."""
        try:
            self.sock.send_multipart(parts)
            return self.sock.recv()
        except self._zmq.Again:
            self._connect()                       # a REQ socket must be remade after this
            raise TimeoutError('meshcat server at %s did not answer' % self.zmq_url)

    def web_url(self):
        """Ask the server for its web URL."""
        url = self.request([b'url']).decode('utf-8')
        self._connect()            # meshcat's own client reconnects after asking the URL
        return url

    def send(self, command):
        """Send a meshcat command (SetObject, SetTransform, SetProperty, Delete)."""
        import umsgpack
        data = command.lower()
        self.request([data['type'].encode(), data['path'].encode(), umsgpack.packb(data)])

    def close(self):
        """Close the socket."""
        if self.sock is not None:
            self.sock.close(linger=0)
            self.sock = None


class MeshcatSink:
    """Stream HairMesh frames to a meshcat viewer from a worker thread."""

    def __init__(self, head, rate=20.0, zmq_url='', logger=None, on_url=None,
                 show_spheres=False, view='three_quarter'):
        self.head = head
        self.show_spheres = bool(show_spheres)     # the collision spheres, not the mesh
        self.view = view                           # a CAMERA_VIEWS name
        self.rate = float(rate)
        self.zmq_url = zmq_url
        self.log = logger
        self.on_url = on_url
        self.web_url = None
        self.frames_sent = 0
        self.errors = 0
        self.connected = False
        self._server = None
        self._latest = None
        self._redraw = False
        self._lock = threading.Lock()
        self._wake = threading.Event()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name='meshcat', daemon=True)

    def start(self):
        """Start the worker thread."""
        self._thread.start()
        return self

    def set_head(self, head):
        """Draw another head (a new style's) on the next frame."""
        with self._lock:
            self.head = head
            self._redraw = True
        self._wake.set()

    def submit(self, mesh, head_pose):
        """Hand over the newest frame (R, p); older unsent frames are dropped."""
        with self._lock:
            self._latest = (mesh, head_pose)
        self._wake.set()

    def stop(self):
        """
        Stop the worker and the server it started.

        The server goes first: it runs in its own session, so nothing else stops it, and a
        worker waiting on its reply then fails at once (quietly: it is stopping) instead of
        waiting for the reply's timeout.
        """
        self._stop.set()
        self._wake.set()
        self._kill_server()
        if self._thread.is_alive():
            self._thread.join(timeout=5.0)
        self._kill_server()         # (one the worker started as the stop began, if any)

    def _kill_server(self):
        server, self._server = self._server, None
        if server is not None:
            _kill_if_running(server)

    def _warn(self, msg):
        # (not once stopping: the node's context may be shut down already, and a failure
        # then is the stop's own doing)
        if self.log is not None and not self._stop.is_set():
            self.log.warning(msg, throttle_duration_sec=5.0)

    def _info(self, msg):
        if self.log is not None and not self._stop.is_set():
            self.log.info(msg, throttle_duration_sec=5.0)

    def _connect(self):
        url = self.zmq_url
        if not url:
            if self._server is None or self._server.poll() is not None:
                self._server, url, web = start_server(on_log=self._info)
                self.zmq_url_started = url
            else:
                url = self.zmq_url_started
        client = MeshcatClient(url)
        self.web_url = client.web_url()
        self._draw_static(client)
        if self.on_url is not None:
            self.on_url(self.web_url)
        self.connected = True
        return client

    def _draw_static(self, client):
        """Draw the head once (its mesh, or its collision spheres) and aim the camera."""
        from meshcat.commands import SetObject, SetProperty, SetTransform
        g, _ = _geometry_classes()
        import meshcat.transformations as tf
        skin = g.MeshLambertMaterial(color=SKIN_RGB)
        mesh = None
        if not self.show_spheres:
            try:
                mesh = self.head.display_mesh()
            except (OSError, ValueError) as exc:
                self._warn('head mesh %s unreadable (%s): drawing the spheres'
                           % (self.head.mesh, exc))
        if mesh is not None:
            geom = g.TriangularMeshGeometry(mesh[0], mesh[1])
            client.send(SetObject(g.Mesh(geom, skin), path=node_path('/hair_sim/head/mesh')))
        else:
            for i, s in enumerate(self.head.collision):
                obj = g.Mesh(g.Sphere(float(s[3])), skin)
                path = node_path('/hair_sim/head/sphere_%d' % i)
                client.send(SetObject(obj, path=path))
                client.send(SetTransform(tf.translation_matrix(s[:3]), path))
        # the camera: from the view's direction (three-quarter from the front by default),
        # CAMERA_DISTANCE from the head's centre; the page's orbit target is the world
        # origin, where _send_frame keeps the head's centre (the camera's parent frame is
        # y-up: [x, z, -y] of world)
        x, y, z = CAMERA_DISTANCE * CAMERA_VIEWS[self.view]
        client.send(SetProperty('position', [x, z, -y],
                                node_path('/Cameras/default/rotated/<object>')))
        for clutter in ('/Grid', '/Axes'):
            client.send(SetProperty('visible', False, node_path(clutter)))

    def _send_frame(self, client, mesh, head_pose):
        from meshcat.commands import SetObject, SetTransform
        R, p = head_pose
        T = np.eye(4)
        T[:3, :3] = R
        T[:3, 3] = p
        client.send(SetTransform(T, node_path('/hair_sim/head')))
        # The hair goes in the head's frame, under a node that takes the head's transform.
        # A page applies a transform at once, but a textured object only once its PNG has
        # decoded (three.js' ObjectLoader is asynchronous with images), so for a while it
        # shows this frame's transforms with an earlier frame's hair. In world coordinates
        # that hair was drawn where the head had been: headless Chromium caught it 5-10 cm
        # above the scalp in 2 of 5 screenshots of the demo. In the head's frame the roots
        # stay on the scalp whichever hair is shown; only its shape can be a frame old.
        client.send(SetTransform(T, node_path('/hair_sim/hair')))
        # the view follows the head: the scene moves so the head's centre stays at the
        # orbit target (its turns and nods still show)
        follow = np.eye(4)
        follow[:3, 3] = -(p + R @ self.head.scalp[:, :3].mean(axis=0))
        client.send(SetTransform(follow, node_path('/hair_sim')))
        if len(mesh.indices):
            client.send(SetObject(hair_object(mesh, head_pose),
                                  path=node_path('/hair_sim/hair')))
        self.frames_sent += 1

    def _run(self):
        from meshcat.commands import Delete
        client = None
        last_try = -1e9
        due = 0.0                   # when the next frame may go: frames keep `rate` on average
        while not self._stop.is_set():
            self._wake.wait(timeout=0.5)
            self._wake.clear()
            if self._stop.is_set():
                break
            if client is None:
                if time.monotonic() - last_try < RETRY_PERIOD:
                    continue
                last_try = time.monotonic()
                try:
                    client = self._connect()
                except Exception as exc:                  # noqa: B902 - any failure: retry
                    self.errors += 1
                    self.connected = False
                    self._warn('meshcat unavailable (%s); ROS topics go on, retrying' % exc)
                    client = None
                    continue
            wait = due - time.monotonic()
            if wait > 0:
                if self._stop.wait(wait):
                    break
            with self._lock:
                frame, self._latest = self._latest, None
                redraw, self._redraw = self._redraw, False
            if frame is None and not redraw:
                continue
            start = time.monotonic()
            # scheduled from when a send starts, not ends; a late frame sets a new pace
            due = max(due + 1.0 / self.rate, start)
            try:
                if redraw:
                    client.send(Delete(node_path('/hair_sim/head')))
                    self._draw_static(client)
                if frame is not None:
                    self._send_frame(client, *frame)
            except Exception as exc:                      # noqa: B902
                self.errors += 1
                self.connected = False
                self._warn('meshcat send failed (%s); reconnecting' % exc)
                client.close()
                client = None
        if client is not None:
            client.close()


def hair_object(mesh, head_pose=None):
    """
    Return the meshcat object of a hair mesh: U-shape geometry with the alpha texture.

    head_pose (R, p): the vertices go in that head frame (the mesh's are world); None
    leaves them in the world.

    The texture's row 0 is the root (v = 0, render/texture.py), as glTF and RViz read a
    PNG; three.js flips textures by default (flipY), which would put the tips' fade at the
    roots, so the texture goes with flipY = False.
    """
    g, UVMeshGeometry = _geometry_classes()
    tex = g.ImageTexture(image=g.PngImage(mesh.texture_png), wrap=[1001, 1001], flipY=False)
    mat = g.MeshLambertMaterial(color=0xffffff, map=tex, transparent=True, alphaTest=0.3,
                                side=2)
    vertices = mesh.vertices
    if head_pose is not None:
        R, p = head_pose
        vertices = ((vertices - p) @ R).astype(np.float32)
    return g.Mesh(UVMeshGeometry(vertices, mesh.indices, mesh.uvs), mat)


CAMERA_DISTANCE = 0.45                  # m from the head's centre
# where the camera looks from (head's centre to camera, world axes; x is the face's side)
CAMERA_VIEWS = {name: np.array(d) / np.linalg.norm(d) for name, d in (
    ('three_quarter', [0.68, -0.68, 0.27]), ('front', [1.0, 0.0, 0.12]),
    ('side', [0.0, -1.0, 0.12]), ('back', [-1.0, 0.0, 0.2]))}

CHROMIUM_FLAGS = ['--headless', '--no-sandbox', '--use-gl=swiftshader',
                  '--enable-unsafe-swiftshader', '--disable-background-networking',
                  '--disable-component-update', '--disable-sync', '--no-first-run',
                  '--disable-quic']


def find_chromium():
    """Return the path of a Chromium executable, or None."""
    import shutil
    for name in ('chromium', 'chromium-browser', 'google-chrome'):
        path = shutil.which(name)
        if path:
            return path
    return None


def screenshot(url, path, width=900, height=700, budget_ms=6000, timeout=90, attempts=2):
    """
    Render `url` in headless Chromium (software WebGL) and save a PNG at `path`.

    A Chromium that has not finished in `timeout` s is killed and started again, up to
    `attempts` times in all (seen once on a loaded 2-core machine: the page of a live
    stream never let the virtual time budget run out).
    """
    import tempfile
    chromium = find_chromium()
    if chromium is None:
        raise RuntimeError('no chromium executable (apt-get install chromium)')
    for _ in range(attempts):
        with tempfile.TemporaryDirectory() as profile:
            try:
                subprocess.run([chromium] + CHROMIUM_FLAGS + [
                    '--user-data-dir=%s' % profile, '--window-size=%d,%d' % (width, height),
                    '--virtual-time-budget=%d' % budget_ms, '--screenshot=%s' % path, url],
                    stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, timeout=timeout,
                    check=False)
            except subprocess.TimeoutExpired:
                continue
        if os.path.isfile(path):
            return path
    raise RuntimeError('chromium wrote no screenshot of %s (%d attempts of %d s)'
                       % (url, attempts, timeout))
