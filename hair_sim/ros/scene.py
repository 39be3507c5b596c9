"""
What the node runs, as one swappable object, and the worker that builds the next one.

A Scene is a style's simulator and renderer with a version; everything derived from it
(mesh cache, marker layout and encoder) is keyed by that version, never by `id()`, so a
freed style whose address is reused can never hand out a stale renderer. New scenes (a
load, an edit, the hairstyle parameter) are built and checked completely on the
SceneBuilder's thread, one at a time and in order, while the node keeps publishing the old
one; the node swaps a finished scene in with one assignment on its own thread.
"""

from collections import deque
from dataclasses import dataclass, field
import itertools
import threading
import time

from hair_sim.render.mesh import HairRenderer


@dataclass
class Scene:
    """A style's simulator and renderer; `version` changes on every swap."""

    version: int
    sim: object
    renderer: HairRenderer

    @property
    def style(self):
        """Return the running hairstyle."""
        return self.sim.style

    def mesh(self, viewpoint=None):
        """Return the HairMesh of the current state (rebuilt only when the state changed)."""
        return self.renderer.mesh_of(self.sim, viewpoint)


@dataclass
class Job:
    """One build on the worker: `fn` returns (scene or None, message) or raises."""

    seq: int
    kind: str
    fn: object
    future: object                     # rclpy Future the node completes after the swap
    result: tuple = None
    error: BaseException = None
    seconds: float = 0.0
    extra: dict = field(default_factory=dict)


class SceneBuilder:
    """Run build jobs one at a time on a worker thread; finished jobs queue up for the node."""

    def __init__(self, max_pending=8, on_done=None):
        self.max_pending = max_pending
        self.on_done = on_done
        self.finished = deque()            # jobs done, for the node's thread to collect
        self._seq = itertools.count(1)
        self._queue = deque()
        self._cv = threading.Condition()
        self._stop = False
        self.pending = 0
        self.latest_style = None           # the style of the last scene built (worker's view)
        self._thread = threading.Thread(target=self._run, name='scene_builder', daemon=True)
        self._thread.start()

    def submit(self, kind, fn, future):
        """Queue fn; return the Job, or None when too many builds are already waiting."""
        with self._cv:
            if self.pending >= self.max_pending:
                return None
            job = Job(seq=next(self._seq), kind=kind, fn=fn, future=future)
            self.pending += 1
            self._queue.append(job)
            self._cv.notify()
        return job

    def stop(self):
        """Stop the worker after the job it is on."""
        with self._cv:
            self._stop = True
            self._cv.notify()
        self._thread.join(timeout=10.0)

    def _run(self):
        while True:
            with self._cv:
                while not self._queue and not self._stop:
                    self._cv.wait()
                if self._stop:
                    return
                job = self._queue.popleft()
            t0 = time.perf_counter()
            try:
                job.result = job.fn(job)
                if job.result[0] is not None:
                    self.latest_style = job.result[0].style
            except BaseException as exc:              # noqa: B902 - handed to the node
                job.error = exc
            job.seconds = time.perf_counter() - t0
            with self._cv:
                self.pending -= 1
            self.finished.append(job)
            if self.on_done is not None:
                try:
                    self.on_done()
                except Exception:                     # noqa: B902 - the node is going
                    pass                              # (its frame tick collects the job)
