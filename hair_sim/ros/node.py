"""
hair_sim_node: head pose and wind in, hair markers, meshes and state out.

The node owns topics, parameters, services and timers; the numerics live in HairSimulator
and the renderer. Its boundary holds against careless and hostile pipelines:

- every callback catches what it does not expect, answers or logs it, counts it in
  /diagnostics and leaves the running simulation as it was; nothing ends the process;
- parameters are validated as a whole in on_set (nothing changes there) and applied in
  post_set, so a refused set changes nothing;
- styles (load, edit, the hairstyle parameter) are read, checked against the frame budget,
  built and stability-checked on a worker thread while the old one keeps publishing, then
  swapped in with one assignment (see scene.py); derived state is keyed by the scene
  version;
- every published message carries the stamp of the head pose it was computed for.
"""

import argparse
from collections import Counter, deque
import copy
import errno
import functools
import math
import os
import re
import signal
import sys
import threading
import time
import traceback

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import PoseStamped
from hair_sim_msgs.msg import HairMesh, HairMeshTopology, HairState, Wind
from hair_sim_msgs.srv import EditControlPoint, LoadHairstyle, SaveHairstyle
import numpy as np
from rcl_interfaces.msg import (FloatingPointRange, IntegerRange, ParameterDescriptor,
                                SetParametersResult)
import rclpy
from rclpy.callback_groups import ReentrantCallbackGroup
from rclpy.clock import Clock, ClockType
from rclpy.exceptions import ParameterException
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import (DurabilityPolicy, qos_profile_sensor_data, QoSProfile,
                       ReliabilityPolicy)
from rclpy.task import Future
from rclpy.utilities import remove_ros_args
from std_srvs.srv import Trigger
from visualization_msgs.msg import MarkerArray

from hair_sim.modeling import fields
from hair_sim.modeling.errors import HairstyleError
from hair_sim.modeling.hairstyle import budget_problem, load_hairstyle, save_hairstyle
from hair_sim.modeling.safepath import allowed_dirs, resolve_save_path, resolve_style_path
from hair_sim.modeling.strips import build_strips
from hair_sim.physics.params import PhysicsParams
from hair_sim.physics.simulator import HairSimulator, SimulationDiverged, stability_problem
from hair_sim.render.mesh import HairRenderer
from hair_sim.ros.clock_step import ClockStepWaker
from hair_sim.ros.params import all_parameters, PHYSICS
from hair_sim.ros.pose_lead import PoseLead
from hair_sim.ros.ros_init import init_ros
from hair_sim.ros.scene import Scene, SceneBuilder
from hair_sim.ros.sim_clock import SimClockWatch
from hair_sim.sinks.markers import (delete_all_markers, head_marker_cdr, head_sphere_markers,
                                    MarkerEncoder, MarkerLayout)
from hair_sim.sinks.meshcat_sink import CAMERA_VIEWS
from hair_sim.sinks.mesh_msg import hair_mesh_cdr, hair_mesh_topology_cdr, hair_state_cdr

LATENCY_WINDOW = 600            # publishes kept for the latency percentiles
# meshcat.zmq_url: a server's tcp://host:port (a name, an IPv4 address or a bracketed IPv6
# one). Anything starting with tcp:// was taken: tcp://localhost or tcp://localhost:abc then
# warned 'meshcat unavailable (Invalid argument ...); retrying' every 5 s for ever, and
# tcp://localhost:99999 waited without a word
_ZMQ_URL = re.compile(r'tcp://(?:\[[0-9A-Fa-f:.]{2,45}\]|[A-Za-z0-9][A-Za-z0-9.-]{0,252})'
                      r':([0-9]{1,5})\Z')
MAX_MESSAGE = 300               # characters of a refusal reason sent back
# Requests (and answers) wait in a keep-last history of this depth: rmw_fastrtps drops the
# oldest beyond it. The default 10 lost loads fired at 40 a second whenever the executor
# was held up for a quarter of a second; 100 holds 2.5 s of such a stream.
SERVICE_QOS = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE)
# The solver's wall-time credit (s): it earns max_physics_share of the wall time that
# passes and spends what its steps take, and steps only while it has some. At most this
# much is saved up (a burst to catch up after a pause), and a step that costs more than
# the credit (a 1/60 s step of the articulated model in a 40 m/s gale: up to 0.4 s) leaves
# at most this much owed, so the solver is back within PHYSICS_CREDIT / share s.
PHYSICS_CREDIT = 0.1
# At most this many frame ticks' share of the wall time (max_physics_share / frame rate) of
# the credit is spent in one call: spent at once, a full credit (a step's work bound from
# it, at a cost per segment-substep measured in calm air, two to three times under a
# gale's with its contacts) stopped the outputs for about 0.2 s at each onset of a 40 m/s
# gale on the articulated model (the node's publish_gap_max_ms up to 227 ms), now about
# 0.1 s (a step taken again is cut to the bound too, HairSimulator._cut_retry; README).
# One tick's share dropped simulated time in the demo's ordinary gusts (24 ms in 20 s at
# sim_rate 60); two dropped none (/tmp scripts, 2026-11-30).
FRAME_SPEND_TICKS = 2.0
# A first guess of the wall time (s) of one segment-substep; the node then measures it
# (the median over the last SEGMENT_COST_WINDOW awake steps, each step's wall time over its
# segment-substeps: a hiccup does not move it, and every awake step updates it). A step
# may update as many as this call's share of the credit pays for, and at least as many as
# fit in its frame tick's share of the wall time (max_physics_share / frame_rate): the
# articulated model's substeps grow with how fast its tips whip, and one step of it in a
# gale took up to 0.4 s, which stopped the outputs for as long; a step cut to what fits
# simulates less time (HairSimulator.max_step_work). A bound from the tick alone cut the
# demo's steps in its ordinary gusts too, and a per-segment cost measured only on large
# steps stuck high once steps were cut small: the hair then ran at a tenth of real time
# after the gale.
SEGMENT_SUBSTEP_S = 1e-6
SEGMENT_COST_WINDOW = 64
# Under use_sim_time a /clock that ticks slower than frame_rate (a simulator's 10 Hz clock,
# a bag played at 3x with its 40 Hz clock) moves more than a frame's time per tick, and the
# frame timer fires once a tick: max_steps_per_frame then holds per frame_rate tick of wall
# time, as a budget of steps that wall time refills and the steps taken spend, holding up
# to this many ticks' steps (a 10 Hz clock at real speed had 1/3 of its time dropped as
# overruns, without a word: the hair swung in slow motion). A budget, not the wall time
# since the last tick alone: a 40 Hz clock at 3x whose ticks arrive up to 60 % of a period
# early or late, as a loaded simulator's do, lost 4.5 % of its time in the early ones.
SIM_CLOCK_TICKS_MAX = 15


def _descriptor(default, description, rng):
    d = ParameterDescriptor(description=description)
    if rng is not None and not isinstance(default, bool):
        if isinstance(default, int):
            d.integer_range = [IntegerRange(from_value=int(rng[0]), to_value=int(rng[1]),
                                            step=1)]
        elif isinstance(default, float):
            d.floating_point_range = [FloatingPointRange(from_value=float(rng[0]),
                                                         to_value=float(rng[1]), step=0.0)]
    return d


def _stamp(t):
    sec = int(math.floor(t))
    return sec, min(int((t - sec) * 1e9), 999999999)


def _short(text):
    text = str(text)
    return text if len(text) <= MAX_MESSAGE else text[:MAX_MESSAGE - 3] + '...'


def guarded(kind):
    """Wrap a timer or subscription callback: an unexpected error is logged and counted."""
    def wrap(fn):
        @functools.wraps(fn)
        def run(self, *args):
            try:
                return fn(self, *args)
            except Exception as exc:                  # noqa: B902 - the node must live on
                self._internal_error(kind, exc)
                return None
        return run
    return wrap


# parameters every rclpy node has (not in config/hair_sim.yaml)
ROS_OWN_PARAMETERS = {'use_sim_time', 'start_type_description_service'}


class HairSimNode(Node):
    """Own topics, parameters, services and timers; the numerics live in HairSimulator."""

    def __init__(self, **kwargs):
        super().__init__('hair_sim', **kwargs)
        self._specs = all_parameters()
        # an integer given for a floating-point parameter (`-p sim_rate:=120`, `sim_rate:
        # 120` in a params file) is taken as that float: rclpy refused it, and the node
        # stopped at start ("expecting type 'DOUBLE'"). rclpy keeps the start values
        # where only its own declare reads them, and calls no pre-set callback there.
        overrides = getattr(self, '_parameter_overrides', {})
        overrides.update({p.name: p for p in self._as_declared_types(overrides.values())})
        for name, (default, description, rng) in self._specs.items():
            self.declare_parameter(name, default, _descriptor(default, description, rng))
        self.counts = Counter({'poses': 0, 'wrong_frame': 0, 'wind': 0, 'wind_rejected': 0,
                               'wind_clamped': 0, 'params_refused': 0, 'overruns': 0,
                               'physics_over_share': 0, 'published': 0,
                               'markers_published': 0, 'system_clock_steps': 0})
        self.refused = Counter()          # refused inputs by kind (in /diagnostics)
        self.errors = Counter()           # unexpected errors caught, by callback
        self._validated = None            # (parameters, derived values) from on_set
        # what --ros-args -p gives is checked as a SetParameters call is (the physics by
        # PhysicsParams and the step below): a node refuses to start on what it refuses
        why = self._value_problem({name: self._p(name) for name in self._specs})
        if why:
            raise ValueError('parameters refused: %s' % why)
        # a name this node does not declare (a typo: physics.dampin) is ignored by rclpy
        # without a word; say so once (the overrides from --ros-args and params files)
        unknown = sorted(set(getattr(self, '_parameter_overrides', {})) - set(self._specs)
                         - ROS_OWN_PARAMETERS)
        if unknown:
            self.get_logger().warning(
                'ignored: %s %s (see config/hair_sim.yaml)'
                % (', '.join(_short(n) for n in unknown[:10]),
                   'is not a parameter of this node' if len(unknown) == 1
                   else 'are not parameters of this node'))
        style = self._read_style(self._p('hairstyle'), self._p('hairstyle_dirs'),
                                 self._rates(), self._frames())
        sim = HairSimulator(style, **self._physics_params())
        try:
            sim.plan_step(1.0 / self._p('sim_rate'))
        except ValueError as exc:
            raise ValueError('physics parameters refused: %s' % exc) from None
        _read_display_mesh(style.head)
        self.scene = Scene(1, sim, HairRenderer.for_simulator(sim))
        self._load_kernels()
        self._committed = 0               # seq of the last build job swapped in
        self._encoder = None
        self._encoder_key = None
        self._topology_sent = None        # scene version whose topology was last sent
        self._published_version = None   # scene version last published
        self._clock_last = None
        self._acc = 0.0
        self.overrun_dropped = 0.0        # s of node-clock time the overruns dropped
        self._last_overrun = None         # perf_counter() of the last overrun
        self._clock_moved_wall = None     # perf_counter() when the node clock last moved
        self._step_budget = 0.0           # steps a sim-time frame may take (SIM_CLOCK_TICKS_MAX)
        self._credit = PHYSICS_CREDIT     # the solver's wall-time credit (s)
        self._credit_wall = None          # perf_counter() when it was last earned
        self._over_share_seen = 0         # physics_over_share at the last diagnostics
        self._namesakes = 0               # other nodes in the graph with this node's name
        self._segment_costs = deque(maxlen=SEGMENT_COST_WINDOW)   # s per segment-substep
        self._last_drop = None            # perf_counter() of the last frame that dropped time
        self._last_step = (0.0, 0)        # wall s and substeps of the last step taken
        # how early poses land; slews latency none needs away, and buffers a pose interval
        self.pose_lead = PoseLead(self._p('interpolate_poses'))
        self.meshcat = None
        self.meshcat_url = None
        self.publish_ms = deque(maxlen=2000)          # publish callback durations
        self.latency_ms = deque(maxlen=LATENCY_WINDOW)  # pose stamp -> publish
        self._last_publish = None
        self.publish_gap_ms = 0.0                      # longest gap between publishes
        self._tf_pub = None
        # a finished build is answered (and swapped in) at once, from the executor's thread:
        # it waited for the next frame tick, and under use_sim_time with no /clock (a bag
        # paused) no tick came: a load, even one refused, went unanswered for ever
        self._builds_done = self.create_guard_condition(self._on_builds_done)
        self.builder = SceneBuilder(on_done=self._builds_done.trigger)

        self.create_subscription(PoseStamped, 'head_pose', self._on_pose,
                                 qos_profile_sensor_data)
        self.create_subscription(Wind, 'wind', self._on_wind, 10)
        reliable = QoSProfile(depth=2, reliability=ReliabilityPolicy.RELIABLE)
        self.pub_markers = self.create_publisher(MarkerArray, 'hair_markers', reliable)
        latched = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                             durability=DurabilityPolicy.TRANSIENT_LOCAL)
        self.pub_head = self.create_publisher(MarkerArray, 'head_markers', latched)
        self._head_key = None             # what head_markers last carried
        self._head_source = None          # (head file, mesh name) of self._head_mesh
        self._head_mesh = None
        self.pub_mesh = self.create_publisher(HairMesh, 'hair_mesh', reliable)
        # UVs, triangles, offsets and texture: sent when the style (its scene) changes, kept
        # for late subscribers; hair_mesh then carries the vertices only
        self.pub_topology = self.create_publisher(HairMeshTopology, 'hair_mesh_topology',
                                                  latched)
        self.pub_state = self.create_publisher(HairState, 'hair_state', reliable)
        self.pub_diag = self.create_publisher(DiagnosticArray, '/diagnostics', 10)
        self._make_tf_publisher()
        # The build services wait (as coroutines) for the worker while the timers run on:
        # they need a callback group of their own, one that lets several wait at once.
        services = ReentrantCallbackGroup()
        self.create_service(Trigger, '~/reset', self._on_reset, qos_profile=SERVICE_QOS)
        self.create_service(LoadHairstyle, '~/load_hairstyle', self._on_load,
                            qos_profile=SERVICE_QOS, callback_group=services)
        self.create_service(EditControlPoint, '~/edit_control_point', self._on_edit,
                            qos_profile=SERVICE_QOS, callback_group=services)
        self.create_service(SaveHairstyle, '~/save_hairstyle', self._on_save,
                            qos_profile=SERVICE_QOS, callback_group=services)
        self.add_pre_set_parameters_callback(self._as_declared_types)
        self.add_on_set_parameters_callback(self._validate_parameters)
        self.add_post_set_parameters_callback(self._apply_parameters)
        self._steady_clock = Clock(clock_type=ClockType.STEADY_TIME)
        self._timers = []
        self._make_timers(self.get_parameter('use_sim_time').value)
        self._clock_steps = ClockStepWaker(self, on_step=self._on_clock_step)
        self._markers_due = 0.0            # markers go out from the publish tick when due
        if self._p('meshcat.enabled'):
            self._start_meshcat()
        strips = sim.strips
        self.get_logger().info('hair_sim: %s, %d strips, %d strands x %d vertices'
                               % (style.name, strips.n_strips, strips.n_strands,
                                  strips.n_vertices))

    def _load_kernels(self):
        """
        Take the first use of the frame's kernels before the node's clock starts.

        numba loads a kernel's machine code from its cache at the kernel's first call: the
        first two steps took 34-45 ms and the first mesh 31-41 ms, in the first frames of
        a run, while the node's clock ran on. So in some starts of `make demo` (3 of 11 on
        2026-12-02) the first frames moved the clock beyond max_steps_per_frame twice within
        a second, and the node warned of dropped time before the hair had moved; on an empty
        cache they compiled for 50 s and dropped as much. Here a copy of the
        simulator takes two steps under a head that moves (the first poses' head-motion
        filter and, in the thesis model, its charts' turn: another 9-10 ms) and the copy's
        mesh is built (whole, and from the viewpoint when one is set); the running scene is
        not touched. (A copy that diverges has loaded what it reached; the running one then
        meets that in its frames, as any.)
        """
        spare = copy.deepcopy(self.scene.sim)
        h = 1.0 / self._p('sim_rate')
        try:
            for k in (1, 2):
                half_turn = 0.005 * k             # rad: a yaw of 0.01, then 0.02 rad
                spare.set_head_pose(spare.time + k * h, [0.0, 0.0, 1e-3 * k],
                                    [0.0, 0.0, math.sin(half_turn), math.cos(half_turn)])
                spare.step(h)
        except SimulationDiverged:
            pass
        renderer = HairRenderer.for_simulator(spare)
        renderer.mesh_of(spare)
        if self._viewpoint() is not None:
            renderer.mesh_of(spare, self._viewpoint())

    def _make_timers(self, sim_time):
        """
        (Re)create the frame, publish and diagnostics timers on the node's pacing clock.

        The pacing clock is the ROS clock under use_sim_time (a bag's /clock paces the
        node), and a steady clock otherwise. Without sim time the ROS clock is the system
        clock, and rcl times its timers on it: a step of the system clock back (an NTP
        correction, `date -s`, a VM resumed) stopped every timer for as long as the step
        (60 s back: no hair_state for 60 s, 2026-11-30), and a step ahead was stepped as
        simulated time. The stepping measures elapsed time on the same clock; stamps stay
        on the ROS clock, where the head poses' are.
        """
        for timer in self._timers:
            self.destroy_timer(timer)
        self._pacing_clock = self.get_clock() if sim_time else self._steady_clock
        clock = self._pacing_clock
        self.frame_timer = self.create_timer(1.0 / self._p('frame_rate'), self._on_frame,
                                             clock=clock)
        self.publish_timer = self.create_timer(1.0 / self._p('publish_rate'),
                                               self._on_publish, clock=clock)
        # (the diagnostics describe the node, which runs in wall time: on a stopped /clock
        # they go on, and say so)
        self._timers = [self.frame_timer, self.publish_timer,
                        self.create_timer(1.0, self._on_diagnostics,
                                          clock=self._steady_clock)]
        self._sim_clock = SimClockWatch(self._steady_now()) if sim_time else None
        self._clock_publishers = 0
        self._clock_last = None           # the elapsed time starts again on this clock
        # (the ROS time as use_sim_time comes on; see _advance)
        self._sim_time_from = self._pacing_now() if sim_time else None
        slewed, self.pose_lead = self.pose_lead.slewed, PoseLead(self._p('interpolate_poses'))
        self.pose_lead.slewed = slewed

    def _on_clock_step(self, step):
        """Executor thread: the system clock stepped by `step` s (ClockStepWaker woke us)."""
        self.counts['system_clock_steps'] += 1
        self.get_logger().warning(
            'the system clock stepped %+.3f s (counted in system_clock_steps); the node '
            'paces itself on %s, and head poses re-anchor on their stamps'
            % (step, 'the simulated clock' if self._on_sim_time() else 'a steady clock'),
            throttle_duration_sec=5.0)

    def _on_sim_time(self):
        return self._pacing_clock is not self._steady_clock

    def _steady_now(self):
        return self._steady_clock.now().nanoseconds * 1e-9

    def _watch_sim_clock(self, st, values):
        """Under use_sim_time: say when /clock stands still, or never came (see sim_clock)."""
        watch = self._sim_clock
        if watch is None:
            return
        now = self._steady_now()
        was_still, never_ran = watch.still_for(now), watch.never_ran()
        news = watch.note(self.get_clock().now().nanoseconds, now)
        values['sim_clock_still_s'] = '%.1f' % watch.still_for(now)
        values['sim_clock_stalls'] = str(watch.stalls)
        if news == 'stopped' and watch.never_ran():
            self.get_logger().warning(
                'use_sim_time is true and no /clock has arrived in %.0f s: the hair is not '
                'stepped, and is published once a second as it stands, until one does (play '
                'a bag with --clock, start the simulator, or set use_sim_time false)'
                % watch.still_for(now))
        elif news == 'stopped':
            self.get_logger().warning(
                'the simulated clock (/clock) has not moved for %.0f s: the hair holds '
                'still, and is published once a second as it stands, until it runs again'
                % watch.still_for(now))
        elif news == 'resumed':
            self.get_logger().info('the simulated clock (/clock) %s after %.1f s'
                                   % ('arrived' if never_ran else 'runs again', was_still))
        if watch.still:
            st.level = DiagnosticStatus.WARN
            st.message += ('; use_sim_time: no /clock yet' if watch.never_ran() else
                           '; use_sim_time: /clock stopped %.0f s ago' % watch.still_for(now))
        clocks = self._count_clock_publishers()
        values['clock_publishers'] = str(clocks)
        if clocks > 1:
            st.level = DiagnosticStatus.WARN
            st.message += '; use_sim_time: %d publishers on /clock' % clocks

    def _count_clock_publishers(self):
        """
        Under use_sim_time: return how many publishers /clock has; say when more than one.

        A bag played with --clock while a simulator publishes /clock too (or two bags):
        the ROS time then jumps between their clocks at every message. Tried with two
        clocks 60 s apart at 50 Hz each: the node dropped 59 s as an overrun 9 times in
        12 s and its timers fired at 45 Hz where 30 were set, and only the overruns were
        said, as if the machine were slow.
        """
        infos = self.get_publishers_info_by_topic('/clock')
        n = len(infos)
        if n > 1 and n > self._clock_publishers:
            # (a node's name can come later than its publisher: rmw says _NODE_NAME_UNKNOWN_)
            names = sorted({'%s/%s' % (i.node_namespace.rstrip('/'), i.node_name)
                            for i in infos if '_UNKNOWN_' not in i.node_name})
            self.get_logger().warning(
                '%d publishers on /clock%s: the simulated time jumps between their clocks, '
                'and the hair with it (keep one: a bag played with --clock, or the '
                'simulator)' % (n, ' (%s)' % ', '.join(_short(name) for name in names[:5])
                                if names else ''))
        elif n <= 1 < self._clock_publishers:
            self.get_logger().info('/clock has %d publisher%s now: its time no longer jumps '
                                   'between clocks' % (n, '' if n == 1 else 's'))
        self._clock_publishers = n
        return n

    def _pacing_now(self):
        return self._pacing_clock.now().nanoseconds * 1e-9

    # -------------------------------------------------------------- state
    @property
    def sim(self):
        """Return the running simulator (of the current scene)."""
        return self.scene.sim

    @property
    def head_frame(self):
        """Return this avatar's head frame (the parameter, or the head file's frame_id)."""
        return self._p('head_frame') or self.sim.head.frame_id

    def _p(self, name):
        return self.get_parameter(name).value

    def _rates(self, overrides=None):
        v = dict(sim_rate=self._p('sim_rate'), publish_rate=self._p('publish_rate'),
                 model=self._p(PHYSICS + 'model'))
        v.update(overrides or {})
        return v

    def _physics_params(self, overrides=None):
        values = {name[len(PHYSICS):]: self._p(name) for name in self._specs
                  if name.startswith(PHYSICS)}
        values.update(overrides or {})
        return PhysicsParams().replaced(**values).__dict__

    def _refuse(self, kind, reason, log=True):
        """Count a refused input of `kind` and log why (throttled); return the reason."""
        self.refused[kind] += 1
        if log:
            self.get_logger().warning('%s refused: %s' % (kind, _short(reason)),
                                      throttle_duration_sec=2.0)
        return _short(reason)

    def _internal_error(self, where, exc):
        if not self.context.ok():
            # Ctrl-C or SIGTERM shut the context down under a callback that was publishing
            # ("publisher's context is invalid"): a stop, not a fault to log with its
            # traceback (1 stop in 6 at publish_rate 240 did)
            return
        self.errors[where] += 1
        self.get_logger().error('%s: unexpected %s: %s (counted; the node goes on)\n%s'
                                % (where, type(exc).__name__, _short(exc),
                                   ''.join(traceback.format_exception(exc))[-2000:]),
                                throttle_duration_sec=5.0)

    # -------------------------------------------------------------- parameters
    def _as_declared_types(self, params):
        """pre-set: the parameters, an integer for a floating-point one as that float."""
        out = []
        for p in params:
            spec = self._specs.get(p.name)
            if spec is not None and type(spec[0]) is float \
                    and p.type_ == Parameter.Type.INTEGER:
                p = Parameter(p.name, Parameter.Type.DOUBLE, float(p.value))
            out.append(p)
        return out

    def _validate_parameters(self, params):
        """on_set: check the whole set against the running scene; change nothing here."""
        try:
            return self._validate_parameters_unsafe(params)
        except Exception as exc:                      # noqa: B902
            self._internal_error('parameters', exc)
            return self._param_refused('internal error: %s' % exc)

    def _param_refused(self, reason):
        self.counts['params_refused'] += 1
        return SetParametersResult(successful=False, reason=self._refuse('parameter', reason))

    def _validate_parameters_unsafe(self, params):
        new = {p.name: p.value for p in params if p.name in self._specs}
        if not new:
            return SetParametersResult(successful=True)
        why = self._value_problem(new)
        if why:
            return self._param_refused(why)
        physics = {k[len(PHYSICS):]: v for k, v in new.items() if k.startswith(PHYSICS)}
        rates = self._rates({k: new[k] for k in ('sim_rate', 'publish_rate') if k in new})
        rates['model'] = physics.get('model', rates['model'])
        try:
            physics_new = PhysicsParams().replaced(**dict(self._physics_params(), **physics))
        except ValueError as exc:
            return self._param_refused(str(exc))
        style = None
        if 'hairstyle' in new:
            try:
                style = self._read_style(new['hairstyle'], new.get(
                    'hairstyle_dirs', self._p('hairstyle_dirs')), rates, self._frames(new))
                rest = build_strips(style).rest
                lengths = np.linalg.norm(np.diff(rest, axis=1), axis=2)
            except (HairstyleError, ValueError, OSError) as exc:
                return self._param_refused('hairstyle: %s' % exc)
            problem = stability_problem(physics_new, lengths, 1.0 / rates['sim_rate'])
            if problem:
                return self._param_refused('hairstyle %s: %s' % (style.name, problem))
        elif 'sim_rate' in new or 'publish_rate' in new or 'model' in physics:
            why = budget_problem(self.sim.style, **rates)
            if why:
                return self._param_refused(why)
        if physics or 'sim_rate' in new:
            problem = stability_problem(physics_new, self.sim, 1.0 / rates['sim_rate'])
            if problem:
                return self._param_refused(problem)
        self._validated = (params_key(params), style)
        return SetParametersResult(successful=True)

    def _value_problem(self, new):
        """
        Return why values refused whatever the scene is are refused, or None.

        new is {name: value}. Numbers must be finite; frame names valid (world_frame not
        empty: poses, wind and world-frame output are in it; head_frame may be, for the
        head file's frame); and viewpoint, hairstyle_dirs and the meshcat strings what
        they say. The same checks refuse a SetParameters call and a node's start.
        """
        for name, value in new.items():
            default = self._specs[name][0]
            if isinstance(value, float) and not math.isfinite(value):
                return '%s must be finite' % name
            if isinstance(default, str) and name.endswith('frame') \
                    and value and not fields._FRAME.match(value):
                return '%s %r is not a valid frame name' % (name, value)
        if 'world_frame' in new and not new['world_frame']:
            return 'world_frame must name a frame (head poses, wind and output are in it)'
        if 'world_frame' in new or 'head_frame' in new:
            # (at the start there is no head yet: _read_style checks the head file's frame)
            head_file = self.sim.head.frame_id if hasattr(self, 'scene') else None
            why = head_frame_problem(*self._frames(new), head_file)
            if why:
                return why
        if 'viewpoint' in new:
            try:
                vp = [float(v) for v in new['viewpoint']]
            except (TypeError, ValueError):
                vp = []
            if len(vp) != 3 or not all(math.isfinite(v) and abs(v) < 1e3 for v in vp):
                return 'viewpoint must be 3 finite numbers (m)'
        if 'hairstyle_dirs' in new:
            bad = [d for d in new['hairstyle_dirs'] if d != '' and not _is_dir(d)]
            if bad or not new['hairstyle_dirs']:
                return 'hairstyle_dirs: %s is not a directory' % (bad[0] if bad else
                                                                  '(none given)')
        if 'meshcat.zmq_url' in new and new['meshcat.zmq_url']:
            url = _ZMQ_URL.match(new['meshcat.zmq_url'])
            if url is None or not 1 <= int(url.group(1)) <= 65535:
                return ('meshcat.zmq_url must be empty or tcp://host:port (port 1-65535), '
                        'not %r' % new['meshcat.zmq_url'][:80])
        if 'meshcat.view' in new and new['meshcat.view'] not in CAMERA_VIEWS:
            return 'meshcat.view must be one of %s, not %r' % (', '.join(CAMERA_VIEWS),
                                                               new['meshcat.view'][:40])
        return None

    @guarded('parameters')
    def _apply_parameters(self, params):
        """post_set: apply a set that on_set accepted (all of it)."""
        for p in params:
            if p.name == 'use_sim_time' and bool(p.value) != self._on_sim_time():
                self._make_timers(bool(p.value))
        changed = {p.name: p.value for p in params if p.name in self._specs}
        validated = self._validated
        self._validated = None
        physics = {k[len(PHYSICS):]: v for k, v in changed.items() if k.startswith(PHYSICS)}
        # on_set checked the new parameters at the new step together: apply them together
        dt = 1.0 / float(changed['sim_rate']) if 'sim_rate' in changed else None
        if physics:
            self.sim.set_params(step_dt=dt, **physics)
        elif dt is not None:
            self.sim.plan_step(dt)
        if 'hairstyle' in changed:
            style = validated[1] if validated and validated[0] == params_key(params) else None
            if style is None:
                style = self._read_style(changed['hairstyle'], self._p('hairstyle_dirs'),
                                         self._rates(), self._frames())
            self._submit('hairstyle', lambda job: self._build_scene(style, 'loaded'), None)
        if 'interpolate_poses' in changed:
            self.pose_lead.interpolate = bool(changed['interpolate_poses'])
        timers = {'frame_rate': self.frame_timer, 'publish_rate': self.publish_timer}
        for name, timer in timers.items():
            if name in changed:
                timer.timer_period_ns = int(1e9 / changed[name])
        if self.meshcat is not None and ('publish_rate' in changed or 'meshcat.rate' in changed):
            self.meshcat.rate = self._meshcat_rate()
        if self.meshcat is not None and ('meshcat.show_spheres' in changed
                                         or 'meshcat.view' in changed):
            self.meshcat.show_spheres = self._p('meshcat.show_spheres')
            self.meshcat.view = self._p('meshcat.view')
            self.meshcat.set_head(self.sim.head)              # redrawn on the next frame
        # (a set of the values running, as `ros2 param load` of the file started with makes,
        # keeps the viewer: restarting killed the server a browser page was connected to)
        if ('meshcat.enabled' in changed or 'meshcat.zmq_url' in changed) and not (
                self.meshcat is not None and self._p('meshcat.enabled')
                and self.meshcat.zmq_url == self._p('meshcat.zmq_url')):
            if self.meshcat is not None:
                self.meshcat.stop()
                self.meshcat = None
                self.meshcat_url = None
            if self._p('meshcat.enabled'):
                self._start_meshcat()

    # -------------------------------------------------------------- styles
    def _frames(self, new=None):
        """Return (world_frame, head_frame) as parameters: `new`'s values, else the node's."""
        new = new or {}
        return (new.get('world_frame', self._p('world_frame')),
                new.get('head_frame', self._p('head_frame')))

    def _read_style(self, request, dirs, rates, frames):
        """
        Resolve, read and check a style (and its head) inside `dirs`, within the budget.

        frames is (world_frame, head_frame) as parameters, from _frames: a head whose
        frame_id is the world's, with no head_frame to name another, is refused.
        """
        path = resolve_style_path(request, dirs, must_exist=True)
        style = load_hairstyle(path, search_dirs=dirs)
        why = budget_problem(style, **rates) \
            or head_frame_problem(*frames, style.head.frame_id)
        if why:
            raise HairstyleError(why)
        return style

    def _build_scene(self, style, verb):
        """Worker thread: build a simulator and renderer for `style`; check them fully."""
        sim = HairSimulator(style, **self.sim.params.__dict__)
        try:
            sim.plan_step(self.sim.stability_dt)
        except ValueError as exc:
            raise HairstyleError('%s: %s' % (style.name, exc)) from None
        renderer = HairRenderer.for_simulator(sim)
        _read_display_mesh(style.head)
        return sim, renderer, '%s %s (%d strips)' % (verb, style.name, style.n_strips)

    def _submit(self, kind, fn, future):
        """Queue a build; return the job, or None (refused) when too many are waiting."""
        job = self.builder.submit(kind, fn, future)
        if job is None:
            self._refuse(kind, '%d builds are already waiting' % self.builder.max_pending)
        return job

    def _collect_builds(self):
        """Swap in the newest finished scene; answer every finished job (node thread)."""
        jobs = []
        while self.builder.finished:
            jobs.append(self.builder.finished.popleft())
        if not jobs:
            return
        jobs.sort(key=lambda j: j.seq)
        newest = max((j for j in jobs if j.error is None and j.result is not None
                      and j.result[0] is not None), key=lambda j: j.seq, default=None)
        for job in jobs:                  # every job is answered, whatever one of them does
            try:
                ok, message = self._settle(job, job is newest)
            except Exception as exc:                  # noqa: B902
                self._internal_error('swap ' + job.kind, exc)
                ok, message = False, 'internal error: %s' % _short(exc)
            if job.future is not None:
                job.future.set_result((ok, message))
            elif not ok:
                self.get_logger().error('%s: %s' % (job.kind, message))

    def _settle(self, job, newest):
        """Return (ok, message) for a finished job; swap its scene in if it is the newest."""
        if job.error is not None:
            if isinstance(job.error, (HairstyleError, ValueError, OSError)):
                return False, self._refuse(job.kind, job.error)
            self._internal_error('build ' + job.kind, job.error)
            return False, 'internal error: %s' % _short(job.error)
        if job.result[0] is None:                     # no new scene (a save)
            return True, job.result[2]
        if newest and job.seq > self._committed:
            return self._swap(job)
        return True, '%s; superseded by a later change' % job.result[2]

    def _swap(self, job):
        sim, renderer, message = job.result
        old = self.sim
        # (checked again here: the parameters may have changed while it was built)
        problem = stability_problem(old.params, sim, old.stability_dt) or \
            budget_problem(sim.style, **self._rates()) or \
            head_frame_problem(*self._frames(), sim.head.frame_id)
        if problem:
            self.builder.latest_style = None          # edits start from the running style
            return False, self._refuse(job.kind, problem)
        sim.adopt(old)
        self.scene = Scene(self.scene.version + 1, sim, renderer)
        self._committed = job.seq
        if self.meshcat is not None:
            self.meshcat.set_head(sim.head)
        self.get_logger().info('%s in %.0f ms' % (message, 1e3 * job.seconds))
        return True, message

    async def _await_job(self, kind, fn):
        future = Future()
        job = self._submit(kind, fn, future)
        if job is None:
            return False, 'busy: %d builds are already waiting' % self.builder.max_pending
        return await future

    # -------------------------------------------------------------- services
    async def _on_load(self, request, response):
        dirs = list(self._p('hairstyle_dirs'))
        rates = self._rates()
        frames = self._frames()
        path = request.path

        def build(job):
            return self._build_scene(self._read_style(path, dirs, rates, frames), 'loaded')
        return await self._answer('load_hairstyle', build, response)

    async def _on_edit(self, request, response):
        pos = request.position
        xyz = (pos.x, pos.y, pos.z)
        rates = self._rates()
        index = (request.patch, request.control_hair, request.control_point)

        def build(job):
            style = self._latest_style().with_control_point(*index, xyz)
            why = budget_problem(style, **rates)
            if why:
                raise HairstyleError(why)
            return self._build_scene(style, 're-tessellated')
        return await self._answer('edit_control_point', build, response)

    async def _on_save(self, request, response):
        dirs = list(self._p('hairstyle_dirs'))
        target, overwrite = request.path, request.overwrite

        def save(job):
            path = resolve_save_path(target, dirs, overwrite)
            style = self._latest_style()
            try:
                save_hairstyle(style, path)
            except OSError as exc:
                if exc.errno not in (errno.EACCES, errno.EPERM, errno.EROFS):
                    raise
                # (the parameter is what a user can change: a pip install into a root-owned
                # venv keeps the shipped folder, the only one by default, read-only)
                raise OSError(exc.errno, '%s; this node may not write in that folder: list '
                              'one it may first in hairstyle_dirs (a new style goes to the '
                              'first that is not the shipped folder)' % exc.strerror) from exc
            return None, None, 'saved %s to %s' % (style.name, path)
        return await self._answer('save_hairstyle', save, response)

    async def _answer(self, kind, fn, response):
        try:
            response.success, response.message = await self._await_job(kind, fn)
        except Exception as exc:                      # noqa: B902
            self._internal_error(kind, exc)
            response.success, response.message = False, 'internal error: %s' % _short(exc)
        return response

    def _latest_style(self):
        """Worker thread: the style edits and saves start from (after the queued builds)."""
        return self.builder.latest_style or self.sim.style

    def _on_reset(self, request, response):
        try:
            self.sim.reset(clock=True)
            response.success = True
            response.message = 'hair reset to its rest shape; the pose clock re-anchors on ' \
                'the next pose'
        except Exception as exc:                      # noqa: B902
            self._internal_error('reset', exc)
            response.success, response.message = False, 'internal error: %s' % _short(exc)
        return response

    # -------------------------------------------------------------- inputs
    @guarded('head_pose')
    def _on_pose(self, msg):
        frame = msg.header.frame_id
        self.counts['poses'] += 1
        if frame not in ('', self._p('world_frame')):
            self.counts['wrong_frame'] += 1
            self._refuse('pose_wrong_frame', 'head_pose in frame %r (expected %r)'
                         % (frame[:100], self._p('world_frame')))
            return
        st = msg.header.stamp
        t = st.sec + st.nanosec * 1e-9
        if t == 0.0:
            t = self.get_clock().now().nanoseconds * 1e-9
        p, q = msg.pose.position, msg.pose.orientation
        verdict = self.sim.set_head_pose(t, (p.x, p.y, p.z), (q.x, q.y, q.z, q.w))
        if verdict in ('invalid', 'repeated', 'out_of_order'):
            self._refuse('pose_' + verdict, 'head_pose %s' % verdict.replace('_', ' '))
            return
        self._note_pose_lead(t)
        if self._tf_pub is not None and self._p('publish_tf'):
            self._publish_tf(msg)

    def _note_pose_lead(self, stamp):
        """Note how far ahead of the simulator's clock the pose stamped `stamp` landed."""
        motion = self.sim.motion
        if self._clock_last is None or motion.offset is None:
            return                        # the simulator's clock has not started
        now = self._pacing_now()
        # the simulator's clock now: its time, the part of a step owed, the time since
        # the last frame
        sim_now = self.sim.time + self._acc + max(0.0, now - self._clock_last)
        samples = motion.samples
        gap = stamp - samples[-2][1] if len(samples) > 1 else 0.0
        self.pose_lead.note(motion, now, stamp - motion.offset - sim_now, gap)

    @guarded('wind')
    def _on_wind(self, msg):
        v = np.array([msg.velocity.x, msg.velocity.y, msg.velocity.z])
        self.counts['wind'] += 1
        frame = msg.header.frame_id
        if frame == self.head_frame:
            v = self.sim.head_pose[0] @ v                 # head frame -> world
        elif frame not in ('', self._p('world_frame')):
            self.counts['wind_rejected'] += 1
            self._refuse('wind_wrong_frame', 'wind in frame %r (the world is %r, the head %r)'
                         % (frame[:100], self._p('world_frame'), self.head_frame))
            return
        try:
            verdict = self.sim.set_wind(v, msg.turbulence, msg.seed)
        except ValueError as exc:
            self.counts['wind_rejected'] += 1
            self._refuse('wind_invalid', exc)
            return
        if verdict == 'clamped':
            self.counts['wind_clamped'] += 1
            self.get_logger().warning('wind clamped to %.0f m/s' % self.sim.params.max_wind_speed,
                                      throttle_duration_sec=5.0)

    # -------------------------------------------------------------- stepping
    @guarded('frame')
    def _on_frame(self):
        self._collect_builds()
        self._advance()

    @guarded('builds')
    def _on_builds_done(self):
        self._collect_builds()
        self._publish_held_scene(still=False)

    def _publish_held_scene(self, still):
        """
        On a simulated clock, send a scene the publish timer has not sent, or is not sending.

        On a /clock that stands still (none yet, or a bag paused to tune a style against
        one frame) the publish timer does not fire: a browser showed the head without hair,
        and a loaded style was never seen. Here the hair of a load or edit is sent at once
        (from the builds' callback), and, with still, the hair as it stands when nothing
        went out for a second (the diagnostics' tick, on the steady clock), so subscribers
        that come later get it too.
        """
        if not self._on_sim_time():
            return
        quiet = self._last_publish is None or time.perf_counter() - self._last_publish > 0.9
        if self._published_version != self.scene.version or (still and quiet):
            self._on_publish()

    def _advance(self):
        """
        Step the solver up to the node clock (at most max_steps_per_frame steps).

        The solver steps while it has wall-time credit (max_physics_share of the wall
        time, PHYSICS_CREDIT), and spends at most FRAME_SPEND_TICKS frame ticks' share of
        it in one call: the simulated time of the steps it cannot take is dropped,
        so that a costly step (the articulated model in a gale) slows the hair, not the
        outputs and the callbacks.
        """
        now = self._pacing_now()
        if self._sim_time_from is not None:
            if now == self._sim_time_from:
                # no /clock since use_sim_time came on: nothing to step, and no time to
                # anchor to. The ROS time is then 0, or the last /clock of an earlier run
                # (use_sim_time set again): anchored there by a publish of the held scene,
                # the next /clock came as elapsed time, an overrun that dropped it all
                return
            self._sim_time_from = None
        wall = time.perf_counter()
        if self._clock_last is None:
            self._clock_last, self._clock_moved_wall = now, wall
            # full: the first ticks after the anchor may come in a burst, the node held
            # up as the clock started (with a frame's steps, a 10 Hz clock lost 0.13-0.23
            # s and a 3x one 0.76 s, in 2 of 6 runs on a loaded machine)
            self._step_budget = float(SIM_CLOCK_TICKS_MAX * self._p('max_steps_per_frame'))
            return
        elapsed = max(0.0, now - self._clock_last)
        self._clock_last = now
        h = 1.0 / self._p('sim_rate')
        self._acc += elapsed
        n = int(self._acc / h)
        cap = self._p('max_steps_per_frame')
        sim_time = self._on_sim_time()
        if elapsed > 0.0:
            if sim_time:                  # (see SIM_CLOCK_TICKS_MAX)
                ticks = (wall - self._clock_moved_wall) * self._p('frame_rate')
                self._step_budget = min(SIM_CLOCK_TICKS_MAX * cap,
                                        self._step_budget + ticks * cap)
                cap = max(cap, int(self._step_budget))
            self._clock_moved_wall = wall
        if n > cap:
            beyond = self._acc - cap * h
            self._note_overrun(beyond, cap, wall)
            self.sim.skip_time(beyond)                   # dropped: the pose clock moves on
            n = cap
            self._acc = 0.0
        else:
            self._acc -= n * h
        if sim_time:
            self._step_budget = max(0.0, self._step_budget - n)
        sim = self.sim
        step = self.pose_lead.slew(now, elapsed)
        if step != 0.0:                   # poses land early: follow them sooner; or too
            sim.shift_pose_clock(step)    # late to interpolate between: later
        if self._credit_wall is not None:
            self._credit = min(PHYSICS_CREDIT, self._credit + self._p('max_physics_share')
                               * (wall - self._credit_wall))
        self._credit_wall = wall
        done = 0
        dropped = sim.time_dropped
        tick = self._p('max_physics_share') / max(self._p('frame_rate'), self._p('publish_rate'))
        cost = float(np.median(self._segment_costs)) if self._segment_costs else \
            SEGMENT_SUBSTEP_S
        spend = min(self._credit, FRAME_SPEND_TICKS * tick)       # (this call's share)
        try:
            while done < n and spend > 0.0:
                sim.max_step_work = max(1, int(max(spend, tick) / cost))
                segments = sim.counters['segment_updates']
                substeps = sim.counters['substeps']
                t0 = time.perf_counter()
                try:
                    sim.step(h)
                finally:
                    took = time.perf_counter() - t0
                    self._credit = max(-PHYSICS_CREDIT, self._credit - took)
                    spend = min(spend - took, self._credit)
                    done += 1
                    segments = sim.counters['segment_updates'] - segments
                    self._last_step = (took, sim.counters['substeps'] - substeps)
                    if segments > 0:
                        self._segment_costs.append(took / segments)
        except SimulationDiverged as exc:
            self.refused['nonfinite_state_reset'] += 1
            self.get_logger().error('%s (counted)' % exc, throttle_duration_sec=2.0)
            return
        if done < n:                      # out of credit: the steps not taken are dropped
            sim.drop_time((n - done) * h)
        dropped = sim.time_dropped - dropped
        if dropped > 0.0:
            # over its share of the wall time: the outputs keep their rates, the hair
            # falls behind the clock and the time it cannot simulate is dropped. Said when
            # it lasts (a drop within a second of the last one): a lone one, loading a
            # kernel's compiled code on its first use, is counted only.
            self.counts['physics_over_share'] += 1
            lasts = self._last_drop is not None and wall - self._last_drop < 1.0
            self._last_drop = wall
            if not lasts:
                return
            self.get_logger().warning(
                'the %s model\'s last step took %.0f ms and %d substeps: %.0f ms of '
                'simulated time dropped in this frame, to keep the outputs at rate with the '
                'solver under %.0f %% of the wall time (counted in physics_over_share)'
                % (sim.params.model, 1e3 * self._last_step[0], self._last_step[1],
                   1e3 * dropped, 100 * self._p('max_physics_share')),
                throttle_duration_sec=5.0)

    def _note_overrun(self, dropped, cap, wall):
        """Count `dropped` s of node-clock time beyond `cap` steps; say it when it lasts."""
        self.counts['overruns'] += 1
        self.overrun_dropped += dropped
        lasts = self._last_overrun is not None and wall - self._last_overrun < 1.0
        self._last_overrun = wall
        if lasts:                         # (a lone one, a stall or a clock's jump: counted)
            self.get_logger().warning(
                'the node clock moved %.0f ms beyond %d step%s of 1/%g s in one frame: '
                'dropped, the hair falls behind it (counted in overruns and '
                'overrun_dropped_s; raise max_steps_per_frame to simulate it)'
                % (1e3 * dropped, cap, '' if cap == 1 else 's', self._p('sim_rate')),
                throttle_duration_sec=5.0)

    # -------------------------------------------------------------- outputs
    def _stamp_now(self):
        """Return (sec, nanosec) of the head pose the current state was computed for."""
        now = self.get_clock().now().nanoseconds * 1e-9
        stamp = self.sim.stamp_at()
        if stamp is None:
            return _stamp(now)
        self.latency_ms.append(1e3 * (now - stamp))
        return _stamp(stamp)

    @guarded('publish')
    def _on_publish(self):
        t0 = time.perf_counter()
        if self._last_publish is not None:
            self.publish_gap_ms = max(self.publish_gap_ms, 1e3 * (t0 - self._last_publish))
        self._last_publish = t0
        self._advance()                       # publish the state of now, not of a frame ago
        scene = self.scene
        sim = scene.sim
        mesh = scene.mesh(self._viewpoint())
        sec, nsec = self._stamp_now()
        world = self._p('world_frame')
        if self._p('publish_mesh'):
            topology_id = scene.version % 2 ** 32
            if self._topology_sent != scene.version:    # first, so it is there before its mesh
                self.pub_topology.publish(hair_mesh_topology_cdr(
                    scene.renderer.topology(), topology_id, world, sec, nsec))
                self._topology_sent = scene.version
                self.counts['topologies_published'] += 1
            self.pub_mesh.publish(hair_mesh_cdr(mesh.vertices, mesh.strip_ids, topology_id,
                                                world, sec, nsec))
        if self._p('publish_state'):
            self.pub_state.publish(hair_state_cdr(sim.pos, sim.sleeping, sim.last_step_time,
                                                  world, sec, nsec))
        if self.meshcat is not None:
            self.meshcat.submit(mesh, sim.head_pose)
        self.counts['published'] += 1
        self._published_version = scene.version
        self.publish_ms.append(1e3 * (time.perf_counter() - t0))
        if time.monotonic() >= self._markers_due:          # the big one last, at its own rate
            self._markers_due = max(self._markers_due + 1.0 / self._p('marker_rate'),
                                    time.monotonic() - 0.5 / self._p('publish_rate'))
            self._publish_markers(sec, nsec)

    def _viewpoint(self):
        return [float(v) for v in self._p('viewpoint')] if self._p('use_viewpoint') else None

    def _publish_head(self, sec, nsec, in_head):
        """
        Send the head's display mesh (or its spheres) on head_markers, as the hair goes.

        In head_frame (markers_in_head_frame): frame-locked, once per head. In world_frame:
        under the current head pose, again whenever the head has moved (at marker_rate).
        """
        head = self.scene.style.head
        if self._head_source != (head.path, head.mesh):
            self._head_source = (head.path, head.mesh)
            try:
                self._head_mesh = head.display_mesh()
            except (OSError, ValueError) as exc:   # GlbError is a ValueError
                self.counts['head_mesh_unreadable'] += 1
                self.get_logger().warning('head %s: display mesh %r not drawn (%s); RViz '
                                          'gets the collision spheres'
                                          % (head.name, head.mesh, exc))
                self._head_mesh = None
        R, p = (np.eye(3), np.zeros(3)) if in_head else self.scene.sim.head_pose
        frame = self.head_frame if in_head else self._p('world_frame')
        key = (self._head_source, frame, np.round(R, 9).tobytes(), np.round(p, 9).tobytes())
        if key == self._head_key:
            return
        self._head_key = key
        if self._head_mesh is not None:
            vertices, triangles = self._head_mesh
            self.pub_head.publish(head_marker_cdr(vertices @ R.T + p, triangles, frame, sec,
                                                  nsec, frame_locked=in_head))
        else:
            spheres = head.collision.copy()
            spheres[:, :3] = spheres[:, :3] @ R.T + p
            self.pub_head.publish(head_sphere_markers(spheres, frame, sec, nsec,
                                                      frame_locked=in_head))
        self.counts['head_markers_published'] += 1

    def _publish_markers(self, sec, nsec):
        if not self._p('publish_markers'):
            return
        in_head = self._p('markers_in_head_frame')
        self._publish_head(sec, nsec, in_head)
        scene = self.scene
        mesh = scene.mesh(self._viewpoint())
        frame = self.head_frame if in_head else self._p('world_frame')
        key = (scene.version, mesh.tris_per_strip, mesh.texture_id, frame)
        if self._encoder_key != key:
            full = mesh if mesh.n_strips == scene.renderer.n_strips else scene.mesh()
            layout = MarkerLayout(scene.renderer.n_strips, mesh.tris_per_strip, full)
            self._encoder = MarkerEncoder(layout, mesh.texture_id, mesh.texture_png, frame,
                                          frame_locked=in_head)
            if self._encoder_key is not None:            # the layout changed: clear RViz
                self.pub_markers.publish(delete_all_markers(frame, sec, nsec))
            self._encoder_key = key
        R, p = scene.sim.head_pose if in_head else (np.eye(3), np.zeros(3))
        self.pub_markers.publish(self._encoder.encode(mesh, R, p, sec, nsec))
        self.counts['markers_published'] += 1

    def _make_tf_publisher(self):
        try:
            from tf2_msgs.msg import TFMessage
        except ImportError:                  # a full ROS 2 install has it; the wheels do not
            return
        qos = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE)
        self._tf_pub = self.create_publisher(TFMessage, '/tf', qos)
        self._tf_type = TFMessage

    def _publish_tf(self, pose_msg):
        self._tf_pub.publish(self._tf_type(transforms=[head_transform(
            pose_msg, self._p('world_frame'), self.head_frame)]))

    @guarded('diagnostics')
    def _on_diagnostics(self):
        self._publish_held_scene(still=True)
        sim = self.sim
        fqn = self.get_fully_qualified_name()
        st = DiagnosticStatus(name='hair_sim: %s' % fqn, hardware_id=fqn)
        st.level = DiagnosticStatus.OK
        st.message = 'sleeping' if sim.sleeping else 'simulating'
        values = {'step_time_ms': '%.4f' % (1e3 * sim.last_step_time),
                  'sleeping': str(sim.sleeping), 'strips': str(sim.strips.n_strips),
                  'hairstyle': sim.style.name, 'model': sim.params.model,
                  'sim_rate': '%g' % self._p('sim_rate'), 'sim_time': '%.3f' % sim.time,
                  'min_sin_theta': '%.3f' % sim.min_sin_theta,
                  'scene_version': str(self.scene.version),
                  'builds_pending': str(self.builder.pending),
                  'publish_gap_max_ms': '%.1f' % self.publish_gap_ms,
                  'overrun_dropped_s': '%.3f' % self.overrun_dropped}
        values.update({k: str(v) for k, v in self.counts.items()})
        values.update({k: str(v) for k, v in sim.diagnostics().items()})
        values.update({'refused_' + k: str(v) for k, v in sorted(self.refused.items())})
        values.update({'error_' + k: str(v) for k, v in sorted(self.errors.items())})
        values['refused_total'] = str(sum(self.refused.values()))
        if self.publish_ms:
            values['publish_ms_median'] = '%.3f' % float(np.median(self.publish_ms))
        values['pose_clock_slewed_ms'] = '%.1f' % (1e3 * self.pose_lead.slewed)
        if self._segment_costs:
            values['segment_substep_us'] = '%.3f' % (1e6 * np.median(self._segment_costs))
        now = self._pacing_now()
        least, slack = self.pose_lead.least(now), self.pose_lead.least_slack(now)
        if least is not None:
            values['pose_lead_ms_min'] = '%.1f' % (1e3 * least)
            values['pose_slack_ms_min'] = '%.1f' % (1e3 * slack)
        if self.latency_ms:
            lat = np.asarray(self.latency_ms)
            values['latency_ms_p50'] = '%.1f' % float(np.percentile(lat, 50))
            values['latency_ms_p95'] = '%.1f' % float(np.percentile(lat, 95))
        if self.meshcat is not None:
            values['meshcat_connected'] = str(self.meshcat.connected)
            values['meshcat_frames'] = str(self.meshcat.frames_sent)
            values['meshcat_url'] = self.meshcat_url or ''
        self._watch_sim_clock(st, values)
        over = self.counts['physics_over_share']
        if over > self._over_share_seen:
            st.level = DiagnosticStatus.WARN
            st.message += '; over its share of the wall time: simulated time dropped'
        self._over_share_seen = over
        if self.errors:
            st.level = DiagnosticStatus.WARN
            st.message += '; %d unexpected error(s) caught' % sum(self.errors.values())
        namesakes = self._count_namesakes()
        values['nodes_with_this_name'] = str(namesakes + 1)
        if namesakes:
            st.level = DiagnosticStatus.WARN
            st.message += '; %d other node(s) named %s' % (namesakes, fqn)
        if not np.all(np.isfinite(sim.pos)):
            st.level = DiagnosticStatus.ERROR
            st.message = 'non-finite state'
        st.values = [KeyValue(key=k, value=v) for k, v in values.items()]
        arr = DiagnosticArray()
        arr.header.stamp = self.get_clock().now().to_msg()
        arr.status = [st]
        self.pub_diag.publish(arr)

    def _count_namesakes(self):
        """
        Return how many other nodes in the graph share this node's name; say when it changes.

        A second `make demo` (or node) started without a namespace of its own is named
        /hair_sim too: each node then takes both trackers' poses (refused as out of
        order every few seconds) and both publish on the same topics, where a renderer
        sees two heads of hair in turn. ROS starts such a node without a word.
        """
        name, ns = self.get_name(), self.get_namespace()
        n = max(0, sum(1 for other in self.get_node_names_and_namespaces()
                       if other == (name, ns)) - 1)
        fqn = self.get_fully_qualified_name()
        if n > self._namesakes:
            self.get_logger().warning(
                '%s in the graph: the topics and poses of the same names mix (give each '
                'node its own namespace: --ros-args -r __ns:=/alice)'
                % ('another node named %s' % fqn if n == 1 else
                   '%d other nodes named %s' % (n, fqn)))
        elif n < self._namesakes:
            self.get_logger().info('%d other node(s) named %s left in the graph' % (n, fqn))
        self._namesakes = n
        return n

    # -------------------------------------------------------------- meshcat
    def _meshcat_rate(self):
        return min(float(self._p('meshcat.rate')), float(self._p('publish_rate')))

    def _start_meshcat(self):
        from hair_sim.sinks.meshcat_sink import MeshcatSink

        def on_url(url):
            self.meshcat_url = url
            self.get_logger().info('meshcat URL %s' % url)

        self.meshcat = MeshcatSink(self.sim.head, rate=self._meshcat_rate(),
                                   zmq_url=self._p('meshcat.zmq_url'),
                                   logger=self.get_logger(), on_url=on_url,
                                   show_spheres=self._p('meshcat.show_spheres'),
                                   view=self._p('meshcat.view')).start()

    def destroy_node(self):
        """Stop the workers, then destroy the node."""
        self._clock_steps.stop()
        if self.meshcat is not None:
            self.meshcat.stop()
            self.meshcat = None
        self.builder.stop()
        super().destroy_node()


def params_key(params):
    """Return a comparable key of a parameter list (names and values)."""
    return tuple((p.name, repr(p.value)) for p in params)


def head_frame_problem(world_frame, head_frame, head_file_frame):
    """
    Return why the head's frame (head_frame, else the head file's) cannot be, or None.

    It cannot be world_frame: wind stamped in the world was then turned with the head (as
    wind in the head frame is), head-frame markers were drawn at the world's origin, and
    tf2 refuses a transform from a frame to itself.
    """
    if head_frame:
        if head_frame == world_frame:
            return 'head_frame %r is world_frame: the head needs a frame of its own' % head_frame
    elif head_file_frame is not None and head_file_frame == world_frame:
        return ('the head file\'s frame_id %r is world_frame: set head_frame to give the '
                'head a frame of its own' % head_file_frame)
    return None


def head_transform(pose_msg, world_frame, head_frame):
    """Return the TransformStamped world_frame -> head_frame of a head pose message."""
    from geometry_msgs.msg import TransformStamped
    tf = TransformStamped()
    tf.header.stamp = pose_msg.header.stamp
    tf.header.frame_id = world_frame
    tf.child_frame_id = head_frame
    p, q = pose_msg.pose.position, pose_msg.pose.orientation
    tf.transform.translation.x, tf.transform.translation.y = p.x, p.y
    tf.transform.translation.z = p.z
    tf.transform.rotation = q
    return tf


def _is_dir(path):
    try:
        return os.path.isdir(allowed_dirs([path])[0])
    except (OSError, ValueError, TypeError):
        return False


def parameter_help():
    """Return every parameter with its default, range and description, for --help."""
    lines = ['parameters (--ros-args -p name:=value, or --params-file FILE; all in '
             'config/hair_sim.yaml):']
    for name, (default, description, rng) in all_parameters().items():
        bounds = ' [%g, %g]' % tuple(rng) if rng else ''
        lines.append('  %s := %r%s  %s' % (name, default, bounds, description))
    return '\n'.join(lines)


def check_own_arguments(argv):
    """
    Answer --help, and refuse what is not a ROS argument (exit 2), before ROS starts.

    A node takes its settings as --ros-args -p name:=value: anything else (hair_sim_demo's
    --style given to the node) would be ignored without a word.
    """
    try:
        own = remove_ros_args(list(argv))[1:]
    except RuntimeError as exc:     # rcl cannot parse them: a params file missing, not YAML
        raise SystemExit('hair_sim_node: %s' % exc) from None
    if own:
        parser = argparse.ArgumentParser(
            prog='hair_sim_node', description=__doc__.strip().splitlines()[0],
            epilog=parameter_help(), formatter_class=argparse.RawDescriptionHelpFormatter)
        parser.parse_args(own)


def _read_display_mesh(head):
    """
    Read the head's display mesh where a scene is built (it is read once: HeadModel).

    The publishing thread then draws it from memory. A mesh that cannot be read is said
    where it would be drawn (head_markers, the meshcat sink), and the spheres are drawn.
    """
    try:
        head.display_mesh()
    except (OSError, ValueError):
        pass


def main(args=None):
    """Run hair_sim_node until Ctrl-C or shutdown; bad input never ends it."""
    check_own_arguments(sys.argv if args is None else args)
    init_ros(args)
    node = None
    try:
        node = HairSimNode()
        while rclpy.ok():
            try:
                rclpy.spin(node)
            except (KeyboardInterrupt, ExternalShutdownException):
                break
            except Exception as exc:                  # noqa: B902 - log, count, spin on
                node._internal_error('executor', exc)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except (HairstyleError, ValueError, ParameterException) as exc:
        # (a value out of its declared range, or of the wrong type, is refused by rclpy)
        print('hair_sim_node: %s' % exc, file=sys.stderr)
        return 1
    finally:
        ignore_interrupts_while_stopping()
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
    return 0


def ignore_interrupts_while_stopping():
    """
    Ignore a further Ctrl-C: the program is stopping, and its cleanup must run to its end.

    The cleanup joins the workers (with timeouts) and kills the meshcat server, which runs
    in its own session and outlives a program that does not. A second Ctrl-C during it (a
    user pressing again) printed a KeyboardInterrupt traceback from the join and left the
    server holding port 7000, where the next demo's URL then showed its stale scene.
    """
    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGINT, signal.SIG_IGN)


if __name__ == '__main__':
    sys.exit(main())
