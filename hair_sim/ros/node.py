"""hair_sim_node: head pose and wind in, hair markers, meshes and state out."""

from collections import deque
import math
import os
import sys
import time

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import PoseStamped
from hair_sim_msgs.msg import HairMesh, HairState, Wind
from hair_sim_msgs.srv import EditControlPoint, LoadHairstyle, SaveHairstyle
import numpy as np
from rcl_interfaces.msg import (FloatingPointRange, IntegerRange, ParameterDescriptor,
                                SetParametersResult)
import rclpy
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from rclpy.qos import qos_profile_sensor_data, QoSProfile, ReliabilityPolicy
from std_srvs.srv import Trigger
from visualization_msgs.msg import MarkerArray

from hair_sim.modeling.errors import HairstyleError
from hair_sim.modeling.hairstyle import load_hairstyle, save_hairstyle
from hair_sim.modeling.safepath import resolve_style_path
from hair_sim.physics.params import PhysicsParams
from hair_sim.physics.simulator import HairSimulator, stability_problem
from hair_sim.ros.params import all_parameters
from hair_sim.sinks.markers import MarkerEncoder, MarkerLayout
from hair_sim.sinks.mesh_msg import hair_mesh_cdr, hair_state_cdr

PHYSICS = 'physics.'


def _descriptor(name, default, description, rng):
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
    return sec, int((t - sec) * 1e9)


class HairSimNode(Node):
    """Own topics, parameters, services and timers; the numerics live in HairSimulator."""

    def __init__(self, **kwargs):
        super().__init__('hair_sim', **kwargs)
        self._specs = all_parameters()
        for name, (default, description, rng) in self._specs.items():
            self.declare_parameter(name, default, _descriptor(name, default, description, rng))
        self.counts = {'poses': 0, 'poses_rejected': 0, 'wrong_frame': 0, 'wind': 0,
                       'wind_rejected': 0, 'wind_clamped': 0, 'params_refused': 0,
                       'overruns': 0, 'published': 0}
        physics = self._physics_params()
        style = self._load(self.get_parameter('hairstyle').value)
        self.sim = HairSimulator(style, **physics)
        self.sim.stability_dt = 1.0 / self._p('sim_rate')
        problem = stability_problem(self.sim.params, self.sim, self.sim.stability_dt)
        if problem:
            raise ValueError('physics parameters refused: %s' % problem)
        self._encoder = None
        self._mesh_count = 0
        self._clock_last = None
        self._acc = 0.0
        self.meshcat = None
        self.meshcat_url = None
        self.publish_ms = deque(maxlen=2000)         # recent publish callback durations

        self.create_subscription(PoseStamped, 'head_pose', self._on_pose,
                                 qos_profile_sensor_data)
        self.create_subscription(Wind, 'wind', self._on_wind, 10)
        reliable = QoSProfile(depth=2, reliability=ReliabilityPolicy.RELIABLE)
        self.pub_markers = self.create_publisher(MarkerArray, 'hair_markers', reliable)
        self.pub_mesh = self.create_publisher(HairMesh, 'hair_mesh', reliable)
        self.pub_state = self.create_publisher(HairState, 'hair_state', reliable)
        self.pub_diag = self.create_publisher(DiagnosticArray, '/diagnostics', 10)
        self.create_service(Trigger, '~/reset', self._on_reset)
        self.create_service(LoadHairstyle, '~/load_hairstyle', self._on_load)
        self.create_service(EditControlPoint, '~/edit_control_point', self._on_edit)
        self.create_service(SaveHairstyle, '~/save_hairstyle', self._on_save)
        self.add_on_set_parameters_callback(self._on_set_parameters)
        self._step_timer = self.create_timer(1.0 / self._p('frame_rate'), self._on_frame)
        self._pub_timer = self.create_timer(1.0 / self._p('publish_rate'), self._on_publish)
        self.create_timer(1.0, self._on_diagnostics)
        if self._p('meshcat.enabled'):
            self._start_meshcat()
        self.get_logger().info('hair_sim: %s, %d strips, %d strands x %d vertices'
                               % (style.name, self.sim.strips.n_strips,
                                  self.sim.strips.n_strands, self.sim.strips.n_vertices))

    # -------------------------------------------------------------- parameters
    def _p(self, name):
        return self.get_parameter(name).value

    def _physics_params(self, overrides=None):
        values = {}
        for name in self._specs:
            if name.startswith(PHYSICS):
                values[name[len(PHYSICS):]] = self._p(name)
        values.update(overrides or {})
        return PhysicsParams().replaced(**values).__dict__

    def _on_set_parameters(self, params):
        physics = {}
        for prm in params:
            if prm.name not in self._specs:
                continue
            default, _, rng = self._specs[prm.name]
            value = prm.value
            if isinstance(default, float) and isinstance(value, int) \
                    and not isinstance(value, bool):
                value = float(value)
            if type(value) is not type(default):
                return self._refuse('%s must be %s, not %s' % (
                    prm.name, type(default).__name__, type(value).__name__))
            if isinstance(value, float) and not math.isfinite(value):
                return self._refuse('%s must be finite' % prm.name)
            if rng is not None and not isinstance(value, (bool, str, list)) \
                    and not rng[0] <= value <= rng[1]:
                return self._refuse('%s = %r is outside [%g, %g]' % (prm.name, value, *rng))
            if prm.name == 'viewpoint' and (len(value) != 3 or not all(
                    math.isfinite(v) for v in value)):
                return self._refuse('viewpoint must be 3 finite numbers')
            if prm.name.startswith(PHYSICS):
                physics[prm.name[len(PHYSICS):]] = value
        sim_rate = next((p.value for p in params if p.name == 'sim_rate'), self._p('sim_rate'))
        if physics or any(p.name == 'sim_rate' for p in params):
            try:
                new = PhysicsParams().replaced(**dict(self._physics_params(), **physics))
            except ValueError as exc:
                return self._refuse(str(exc))
            problem = stability_problem(new, self.sim, 1.0 / float(sim_rate))
            if problem:
                return self._refuse(problem)
            self.sim.stability_dt = 1.0 / float(sim_rate)
            if physics:
                self.sim.set_params(**physics)
        changed = {p.name: p.value for p in params}
        if 'hairstyle' in changed:
            try:
                style = self._load(changed['hairstyle'], changed.get('hairstyle_dirs'))
                self.sim.set_style(style)
                self._encoder = None
            except (HairstyleError, ValueError, OSError) as exc:
                return self._refuse('hairstyle: %s' % exc)
        for name, value in changed.items():
            if name == 'frame_rate':
                self._step_timer.timer_period_ns = int(1e9 / value)
            elif name == 'publish_rate':
                self._pub_timer.timer_period_ns = int(1e9 / value)
            elif name == 'meshcat.rate' and self.meshcat is not None:
                self.meshcat.rate = float(value)
        if 'meshcat.enabled' in changed or 'meshcat.zmq_url' in changed:
            enabled = changed.get('meshcat.enabled', self._p('meshcat.enabled'))
            if self.meshcat is not None:
                self.meshcat.stop()
                self.meshcat = None
            if enabled:
                self._start_meshcat(changed.get('meshcat.zmq_url'),
                                    changed.get('meshcat.rate'))
        return SetParametersResult(successful=True)

    def _refuse(self, reason):
        self.counts['params_refused'] += 1
        self.get_logger().warning('parameter change refused: %s' % reason)
        return SetParametersResult(successful=False, reason=reason)

    # -------------------------------------------------------------- inputs
    def _on_pose(self, msg):
        frame = msg.header.frame_id
        if frame not in ('', self._p('world_frame')):
            self.counts['wrong_frame'] += 1
            self.get_logger().warning('head_pose in frame %r refused (expected %r)'
                                      % (frame, self._p('world_frame')),
                                      throttle_duration_sec=5.0)
            return
        st = msg.header.stamp
        t = st.sec + st.nanosec * 1e-9
        if t == 0.0:
            t = self.get_clock().now().nanoseconds * 1e-9
        p, q = msg.pose.position, msg.pose.orientation
        verdict = self.sim.set_head_pose(t, (p.x, p.y, p.z), (q.x, q.y, q.z, q.w))
        self.counts['poses'] += 1
        if verdict in ('invalid', 'repeated', 'out_of_order'):
            self.counts['poses_rejected'] += 1
            self.get_logger().warning('head_pose refused: %s' % verdict,
                                      throttle_duration_sec=5.0)

    def _on_wind(self, msg):
        v = (msg.velocity.x, msg.velocity.y, msg.velocity.z)
        self.counts['wind'] += 1
        try:
            verdict = self.sim.set_wind(v, msg.turbulence, msg.seed)
        except ValueError as exc:
            self.counts['wind_rejected'] += 1
            self.get_logger().warning('wind refused: %s' % exc, throttle_duration_sec=5.0)
            return
        if verdict == 'clamped':
            self.counts['wind_clamped'] += 1
            self.get_logger().warning('wind clamped to %.0f m/s' % self.sim.params.max_wind_speed,
                                      throttle_duration_sec=5.0)

    # -------------------------------------------------------------- stepping
    def _on_frame(self):
        now = self.get_clock().now().nanoseconds * 1e-9
        if self._clock_last is None:
            self._clock_last = now
            return
        elapsed = max(0.0, now - self._clock_last)
        self._clock_last = now
        h = 1.0 / self._p('sim_rate')
        self._acc += elapsed
        n = int(self._acc / h)
        cap = self._p('max_steps_per_frame')
        if n > cap:
            self.counts['overruns'] += 1
            n = cap
            self._acc = 0.0
        else:
            self._acc -= n * h
        for _ in range(n):
            self.sim.step(h)

    # -------------------------------------------------------------- outputs
    def _on_publish(self):
        t0 = time.perf_counter()
        self._publish()
        self.publish_ms.append(1e3 * (time.perf_counter() - t0))

    def _publish(self):
        sim = self.sim
        viewpoint = self._p('viewpoint') if self._p('use_viewpoint') else None
        mesh = sim.mesh(viewpoint=viewpoint)
        R, p = sim.head_pose
        sec, nsec = _stamp(self.get_clock().now().nanoseconds * 1e-9)
        frame = sim.head.frame_id
        if self._p('publish_markers'):
            enc = self._encoder
            if enc is None or enc.layout.tris_per_strip != mesh.tris_per_strip \
                    or enc.texture_id != mesh.texture_id:
                full = mesh if mesh.n_strips == sim.strips.n_strips else sim.mesh()
                layout = MarkerLayout(sim.strips.n_strips, mesh.tris_per_strip, full)
                enc = self._encoder = MarkerEncoder(layout, mesh.texture_id, mesh.texture_png,
                                                    frame)
            self.pub_markers.publish(enc.encode(mesh, R, p, sec, nsec))
        if self._p('publish_mesh'):
            with_tex = self._mesh_count % self._p('texture_every') == 0
            self.pub_mesh.publish(hair_mesh_cdr(mesh, mesh.vertices, self._p('world_frame'),
                                                sec, nsec, with_tex))
            self._mesh_count += 1
        if self._p('publish_state'):
            self.pub_state.publish(hair_state_cdr(sim.pos, sim.sleeping, sim.last_step_time,
                                                  self._p('world_frame'), sec, nsec))
        if self.meshcat is not None:
            self.meshcat.submit(mesh, (R, p))
        self.counts['published'] += 1

    def _on_diagnostics(self):
        sim = self.sim
        st = DiagnosticStatus(name='hair_sim: solver', hardware_id='hair_sim')
        st.level = DiagnosticStatus.OK
        st.message = 'sleeping' if sim.sleeping else 'simulating'
        values = {'step_time_ms': '%.4f' % (1e3 * sim.last_step_time),
                  'sleeping': str(sim.sleeping), 'strips': str(sim.strips.n_strips),
                  'hairstyle': sim.style.name, 'sim_time': '%.3f' % sim.time,
                  'min_sin_theta': '%.3f' % sim.min_sin_theta}
        values.update({k: str(v) for k, v in self.counts.items()})
        values.update({'pose_' + k: str(v) for k, v in sim.motion.counts.items()})
        values.update({k: str(v) for k, v in sim.counters.items()})
        if self.publish_ms:
            values['publish_ms_median'] = '%.3f' % float(np.median(self.publish_ms))
        if self.meshcat is not None:
            values['meshcat_connected'] = str(self.meshcat.connected)
            values['meshcat_frames'] = str(self.meshcat.frames_sent)
            values['meshcat_url'] = self.meshcat_url or ''
        if not np.all(np.isfinite(sim.pos)):
            st.level = DiagnosticStatus.ERROR
            st.message = 'non-finite state'
        st.values = [KeyValue(key=k, value=v) for k, v in values.items()]
        arr = DiagnosticArray()
        arr.header.stamp = self.get_clock().now().to_msg()
        arr.status = [st]
        self.pub_diag.publish(arr)

    # -------------------------------------------------------------- services
    def _load(self, request, dirs=None):
        dirs = self._p('hairstyle_dirs') if dirs is None else dirs
        return load_hairstyle(resolve_style_path(request, dirs, must_exist=True))

    def _on_reset(self, request, response):
        self.sim.reset()
        response.success, response.message = True, 'hair reset to its rest shape'
        return response

    def _on_load(self, request, response):
        try:
            style = self._load(request.path)
            self.sim.set_style(style)
            self._encoder = None
        except (HairstyleError, ValueError, OSError) as exc:
            response.success, response.message = False, str(exc)
            self.get_logger().warning('load_hairstyle refused: %s' % exc)
            return response
        response.success = True
        response.message = 'loaded %s (%d strips)' % (style.name, self.sim.strips.n_strips)
        return response

    def _on_edit(self, request, response):
        pos = request.position
        try:
            style = self.sim.style.with_control_point(request.patch, request.control_hair,
                                                      request.control_point,
                                                      (pos.x, pos.y, pos.z))
            self.sim.set_style(style)
            self._encoder = None
        except (HairstyleError, ValueError) as exc:
            response.success, response.message = False, str(exc)
            return response
        response.success, response.message = True, 're-tessellated %s' % style.name
        return response

    def _on_save(self, request, response):
        try:
            path = resolve_style_path(request.path, self._p('hairstyle_dirs'),
                                      must_exist=False)
            save_hairstyle(self.sim.style, path)
        except (HairstyleError, ValueError, OSError) as exc:
            response.success, response.message = False, str(exc)
            self.get_logger().warning('save_hairstyle refused: %s' % exc)
            return response
        response.success, response.message = True, 'saved %s' % path
        return response

    # -------------------------------------------------------------- meshcat
    def _start_meshcat(self, zmq_url=None, rate=None):
        from hair_sim.sinks.meshcat_sink import MeshcatSink

        def on_url(url):
            self.meshcat_url = url
            self.get_logger().info('meshcat URL %s' % url)

        self.meshcat = MeshcatSink(
            self.sim.head, rate=self._p('meshcat.rate') if rate is None else rate,
            zmq_url=self._p('meshcat.zmq_url') if zmq_url is None else zmq_url,
            logger=self.get_logger(), on_url=on_url).start()

    def destroy_node(self):
        """Stop the meshcat worker, then destroy the node."""
        if self.meshcat is not None:
            self.meshcat.stop()
            self.meshcat = None
        super().destroy_node()


def main(args=None):
    """Run hair_sim_node until Ctrl-C or shutdown."""
    os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    rclpy.init(args=args)
    node = None
    try:
        node = HairSimNode()
        rclpy.spin(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except (HairstyleError, ValueError) as exc:
        print('hair_sim_node: %s' % exc, file=sys.stderr)
        return 1
    finally:
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
    return 0


if __name__ == '__main__':
    sys.exit(main())
