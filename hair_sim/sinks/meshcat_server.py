"""
The meshcat server hair_sim starts: meshcat's own, with a bounded backlog per page.

It is meshcat's bridge (meshcat.servers.zmqserver) with a backlog per page, the scene it
sends a page holding each property once, and its page served on 127.0.0.1 only (see
BoundedBridge's methods). meshcat's bridge writes every command to every page at once,
and tornado keeps whatever a page has not read yet, without limit. A page that stops
reading (a frozen background tab, an ssh tunnel whose far end sleeps) grew the server by
the stream's rate, about 6.5 MB a second with thesis_long, for as long as it lasted
(2026-11-29: 52 MB to 377 MB in 50 s), and a page on a link slower than the stream showed
the hair ever later (20 s late after 30 s).

Here a page more than MAX_BACKLOG bytes behind is sent nothing more until it has read all it
was sent. Then it is sent the deletes it missed, and the scene as it is now, from the
bridge's scene tree, as a page that just opened is. So a slow page skips the frames it could
not take and shows the newest, and the server holds at most about MAX_BACKLOG, one scene
and the missed deletes per page. Pages that keep up get every command, as before.

Run as `python hair_sim/sinks/meshcat_server.py [--zmq-url URL] [--parent-pid PID]` (a file,
so that the server does not import the hair_sim package: 52 MB instead of 115-176 MB). It
prints its zmq_url and web_url lines as meshcat's server does, and a line starting with
LOG_PREFIX when a page falls behind or catches up (meshcat_sink.start_server passes those to
the node's log). With --parent-pid it stops once that process has ended.
"""

import argparse
import functools
import os
import sys
import weakref

from meshcat.servers.tree import find_node, walk
from meshcat.servers.zmqserver import ZMQWebSocketBridge
from tornado.ioloop import PeriodicCallback
from tornado.websocket import WebSocketClosedError
import umsgpack

MAX_BACKLOG = 2 ** 20         # bytes; a thesis_long frame is about 0.33 MB, its scene 0.53
LOG_PREFIX = 'hair_sim:'
PARENT_CHECK_PERIOD_MS = 500


class _Page:
    """What the bridge knows of one page: bytes sent and not yet read, and if it is behind."""

    def __init__(self):
        self.backlog = 0
        self.behind = False
        self.skipped = 0                      # commands not sent since it fell behind
        self.deletes = {}                     # the deletes among them, once per path


class BoundedBridge(ZMQWebSocketBridge):
    """meshcat's zmq-to-websocket bridge, with a page more than MAX_BACKLOG behind skipped."""

    def __init__(self, *args, max_backlog=MAX_BACKLOG, **kwargs):
        super().__init__(*args, **kwargs)
        self.max_backlog = int(max_backlog)
        self._pages = weakref.WeakKeyDictionary()      # websocket handler -> _Page

    def _page(self, websocket):
        page = self._pages.get(websocket)
        if page is None:
            page = self._pages[websocket] = _Page()
        return page

    def make_app(self):
        """
        Return meshcat's web app, listening on the bridge's host (127.0.0.1) only.

        meshcat's bridge puts its host in the URL it prints, but its page and websocket
        listened on every interface (0.0.0.0 and [::]), so anyone on the network could
        open pages on it; from another machine, forward the port (ssh -L) instead.
        """
        app = super().make_app()
        listen = app.listen
        app.listen = functools.partial(self._listen_on_host, listen)
        return app

    def _listen_on_host(self, listen, port, **kwargs):
        return listen(port, address=self.host, **kwargs)

    def handle_zmq(self, frames):
        """
        Take a command as meshcat's bridge does, keeping one set_property per property.

        meshcat's bridge appends every set_property to its node for good, and sends them
        all to every page that opens (or here, catches up): the node sets the camera and
        hides the grid and axes on every redraw (a style load, a view change), so after a
        hostile client's 600 loads a page that opened was sent some 1800 of them. The
        last value of a property is all a page shows.
        """
        super().handle_zmq(frames)
        if len(frames) == 3 and frames[0] == b'set_property':
            try:
                path = [p for p in frames[1].decode('utf-8').split('/') if p]
                node = find_node(self.tree, path)
                node.properties = latest_per_property(node.properties)
            except (UnicodeDecodeError, KeyError):
                pass

    def forward_to_websockets(self, frames):
        """Send a command to every page that is not behind (meshcat's bridge sends to all)."""
        cmd, _path, data = frames
        for websocket in list(self.websocket_pool):
            self._send_if_keeping_up(websocket, cmd, data)

    def send_scene(self, websocket):
        """Send the whole scene tree to a page (one that opened, or one that caught up)."""
        for node in walk(self.tree):
            messages = ([node.object] if node.object is not None else []) + list(
                node.properties)
            for extra in (node.transform, node.animation):
                if extra is not None:
                    messages.append(extra)
            for data in messages:
                self._write(websocket, data)

    def _send_if_keeping_up(self, websocket, cmd, data):
        page = self._page(websocket)
        if not page.behind and page.backlog > self.max_backlog:
            page.behind = True
            page.skipped = 0
            print('%s a meshcat page is %.1f MB behind; it is sent nothing more until '
                  'it has read that, then the scene as it is then'
                  % (LOG_PREFIX, page.backlog / 2 ** 20), flush=True)
        if not page.behind:
            self._write(websocket, data)
            return
        page.skipped += 1
        # the scene tree holds what is, not what went: a delete the page missed is sent
        # before the scene (the objects it took away may still be on the page); once per
        # path, in order
        if cmd == b'delete':
            page.deletes[data] = None

    def _write(self, websocket, data):
        try:
            done = websocket.write_message(data, binary=True)
        except WebSocketClosedError:          # closing; on_close takes it out of the pool
            return
        self._page(websocket).backlog += len(data)
        done.add_done_callback(functools.partial(self._written, websocket, len(data)))

    def _written(self, websocket, size, done):
        if not done.cancelled():
            done.exception()                  # a closed stream's error, taken and dropped
        page = self._page(websocket)
        page.backlog -= size
        if page.backlog == 0 and page.behind and websocket in self.websocket_pool:
            page.behind = False
            print('%s a meshcat page caught up after %d commands skipped; sent it the scene'
                  % (LOG_PREFIX, page.skipped), flush=True)
            deletes, page.deletes = page.deletes, {}
            for data in deletes:
                self._write(websocket, data)
            self.send_scene(websocket)


def latest_per_property(properties):
    """
    Return the set_property commands (msgpack) with only the last one of each property.

    Each property keeps the place of its first command; a command that does not unpack
    to a dict with a 'property' is kept as it is.
    """
    last = {}
    for i, data in enumerate(properties):
        try:
            name = umsgpack.unpackb(data).get('property')
        except Exception:                        # noqa: B902 - anything that does not unpack
            name = None
        last[('name', name) if isinstance(name, str) else ('index', i)] = data
    return list(last.values())


def _stop_when_orphaned(parent_pid):
    if os.getppid() != parent_pid:       # nothing reads our stdout any more: say nothing
        sys.exit(0)


def main(argv=None):
    """Serve the meshcat page and take zmq commands until killed."""
    parser = argparse.ArgumentParser(description=__doc__.strip().splitlines()[0])
    parser.add_argument('--zmq-url', default=None,
                        help='zmq address to bind (default: the first free from tcp 6000)')
    parser.add_argument('--max-backlog', type=int, default=MAX_BACKLOG,
                        help='bytes a page may be behind before it skips frames')
    parser.add_argument('--parent-pid', type=int, default=None,
                        help='stop when this process is no longer our parent (it ended)')
    args = parser.parse_args(argv)
    bridge = BoundedBridge(zmq_url=args.zmq_url, max_backlog=args.max_backlog)
    print('zmq_url=%s' % bridge.zmq_url, flush=True)
    print('web_url=%s' % bridge.web_url, flush=True)
    if args.parent_pid is not None:
        # The server runs in a session of its own (a Ctrl-C in the node's terminal does not
        # reach it), so the node stops it. A node killed (kill -9, or SIGHUP when its
        # terminal closed) could not: its server was left holding port 7000, and showing
        # the last frame there, for ever. Orphaned, the server is re-parented, and stops.
        PeriodicCallback(functools.partial(_stop_when_orphaned, args.parent_pid),
                         PARENT_CHECK_PERIOD_MS).start()
    try:
        bridge.run()
    except KeyboardInterrupt:
        pass
    return 0


if __name__ == '__main__':
    sys.exit(main())
