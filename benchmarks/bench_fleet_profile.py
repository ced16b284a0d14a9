#!/usr/bin/env python3
"""Benchmark: where a fleet drone's CPU goes -- per process, per message path, with rospy's cost per message.

Four measurements in one run (about 4 minutes), on a private ROS master:

1. rospy per message (two processes, ``--rate`` Hz for ``--window`` s each): for every message type on the
   fleet's 100 Hz paths (nav_msgs/Odometry, anafi_sim/DroneData, the Sphinx type, tf2_msgs/TFMessage with 3
   transforms, gazebo_msgs/ModelState, gazebo_msgs/ModelStates with 2N models for N = 1, 10, 20, the piloting
   command) the CPU [us] of the publisher process per message (the message built as the nodes build it, then
   published) with one subscriber and with none (counting the serialize() calls: rospy serializes nothing
   without a connection), and of the subscriber process per message received (it deserializes and counts);
   for nav_msgs/Odometry also at 100 Hz (the fleet's rate: one thread wake-up per message) and one process with
   two rospy.Subscribers on the topic (counting the deserialize() calls: once per message, or per subscriber?).
   CPU = time.process_time() of each process (all threads, ns resolution) across a window both share.
   Beside: an idle node on our run_node glue (diagnostics thread at 1 Hz, master watch), no traffic, 20 s.
2. in process, best of 3: build only, serialize only, deserialize only, publish with no subscriber, per type;
   and the cores per call, driven as the nodes drive them: the simulator step (physics 200 Hz, telemetry
   100 Hz, estimate 30 Hz; anafi_sim.sim.simulator), telemetry formatting and parsing of one sample, the
   interface's GroundTruthInterface.on_sample and its publish() (DroneData + Odometry + Sphinx + TF of 3
   transforms, publishers without subscribers), the simulator's estimate topics (30 Hz), Mirror.on_ground_truth
   + the two ModelState messages, the MPC cycle (10 Hz, with its three states and one waypoint), the trajectory
   generator's update + waypoint message, the kinematic world's handling of one ModelState and its 100 Hz cycle
   (advance + states + ModelStates, published without subscribers) with 2N + 1 models.
3. live: ``roslaunch anafi_sim fleet.launch drones:=2 evaluate:=false`` (as bench_fleet.py), once every drone
   flies: the message rate of every topic (``--rates-window`` s, rostopic-hz style with rospy.AnyMsg, plus its
   publishers and subscribers from the master, taken before subscribing), then ``--live-window`` s of CPU per
   process (psutil, anafi_sim.processes.TreeCpu) by role.
4. the table "where each percent goes": per drone and per process, rate x cost of every path item against the
   measured CPU, and the residual (thread wake-ups, GIL, timers, what is not itemised); and the same items
   projected to N = 20 (the per-drone share of the world, and the mirrors' /gazebo/model_states which grows
   with N).

Writes benchmarks/results/fleet_profile.md and fleet_profile.json (``--no-write``: print only; ``--from-json``:
rewrite the .md from the .json). Run (inside env.bash, in a network namespace of your own):
python benchmarks/bench_fleet_profile.py
"""
import argparse
import datetime
import importlib
import io
import json
import math
import os
import platform
import sys
import tempfile
import threading
import time

import psutil

from anafi_sim import processes

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
RESULTS = os.path.join(ROOT, 'benchmarks', 'results', 'fleet_profile.md')
RESULTS_JSON = os.path.join(ROOT, 'benchmarks', 'results', 'fleet_profile.json')
MASTER_PORTS = (12600, 12900)
LIVE_DRONES = 2
PROJECT_N = 20


# ============================================================================ messages as the nodes build them
def _script(name):
    """The module of a node (anafi_sim.nodes.<name>)."""
    return importlib.import_module('anafi_sim.nodes.' + name)


def _sample():
    from anafi_sim.telemetry.protocol import FIELDS, TelemetrySample
    return TelemetrySample(**dict((f, 0.1 * (i + 1)) for i, f in enumerate(FIELDS)))


def _odometry():
    import rospy
    from nav_msgs.msg import Odometry
    from anafi_sim.ros import conversions
    o = Odometry()
    o.header.stamp = rospy.Time.from_sec(time.time())
    o.header.frame_id = 'world'
    o.child_frame_id = 'anafi1/base_link'
    o.pose.pose = conversions.pose((1.0, 2.0, 3.0), (0.0, 0.05, 0.1, 0.99))
    o.twist.twist = conversions.twist((0.4, -0.2, 0.3), (0.05, -0.02, 0.3))
    return o


def _drone_data():
    import rospy
    from anafi_sim.msg import DroneData
    from anafi_sim.ros import conversions
    return conversions.drone_data(DroneData(), _sample(), rospy.Time.from_sec(time.time()), 'world')


def _sphinx():
    from anafi_sim.ros.wire_types import SPHINX_FIELDS, sphinx_class
    d = _drone_data()
    return sphinx_class()(**dict((f, getattr(d, f)) for f in SPHINX_FIELDS))


def _tf3():
    import rospy
    from tf2_msgs.msg import TFMessage
    from anafi_sim.interface import ground_truth as gt
    transform = _script('interface_node')._transform
    s = _sample()
    stamp = rospy.Time.from_sec(time.time())
    t_sa, q_sa = gt.stability_axes_pose(s.x, s.y, s.z, s.yaw)
    t_bl, q_bl = gt.base_link_in_stability_axes(s.roll, s.pitch)
    t_cam, q_cam = gt.camera_in_base_link(s.gimbal_roll, s.gimbal_pitch, (0.1, 0.0, 0.0))
    return TFMessage([transform(stamp, 'world', 'a/stability_axes', t_sa, q_sa),
                      transform(stamp, 'a/stability_axes', 'a/base_link', t_bl, q_bl),
                      transform(stamp, 'a/base_link', 'a/camera', t_cam, q_cam)])


def _model_state():
    from anafi_sim.ros import conversions, gazebo_types
    return gazebo_types.model_state_class()(model_name='anafi1', pose=conversions.pose((1.0, 2.0, 3.0),
                                            (0.0, 0.05, 0.1, 0.99)),
                                            twist=conversions.twist((0.4, -0.2, 0.3), (0.05, -0.02, 0.3)),
                                            reference_frame='world')


def _model_states(models):
    from anafi_sim.ros import conversions, gazebo_types
    msg = gazebo_types.model_states_class()()
    msg.name = ['anafi%d' % i for i in range(models)]
    msg.pose = [conversions.pose((1.0, 2.0, 3.0), (0.0, 0.05, 0.1, 0.99)) for _ in range(models)]
    msg.twist = [conversions.twist((0.4, -0.2, 0.3), (0.05, -0.02, 0.3)) for _ in range(models)]
    return msg


def _rpyt():
    import rospy
    from anafi_sim.ros.wire_types import piloting_command_class
    msg = piloting_command_class()()
    msg.header.stamp = rospy.Time.from_sec(time.time())
    msg.roll, msg.pitch, msg.yaw, msg.gaz = 1.0, -2.0, 3.0, 4.0
    return msg


def _class_of(key):
    return type(BUILDERS[key]())


BUILDERS = {
    'odometry': _odometry, 'drone_data': _drone_data, 'sphinx': _sphinx, 'tf3': _tf3,
    'model_state': _model_state, 'model_states_2': lambda: _model_states(2),
    'model_states_20': lambda: _model_states(20), 'model_states_40': lambda: _model_states(40), 'rpyt': _rpyt}
LABELS = {
    'odometry': 'nav_msgs/Odometry', 'drone_data': 'anafi_sim/DroneData', 'sphinx': 'sphinx_with_gazebo/Sphinx',
    'tf3': 'tf2_msgs/TFMessage (3 transforms)', 'model_state': 'gazebo_msgs/ModelState',
    'model_states_2': 'gazebo_msgs/ModelStates, 2 models (N = 1)',
    'model_states_20': 'gazebo_msgs/ModelStates, 20 models (N = 10)',
    'model_states_40': 'gazebo_msgs/ModelStates, 40 models (N = 20)',
    'rpyt': 'olympe_bridge/PilotingCommand'}
TYPES = ('odometry', 'drone_data', 'sphinx', 'tf3', 'model_state', 'model_states_2', 'model_states_20',
         'model_states_40', 'rpyt')


def _count_calls(cls, method):
    """Wrap ``cls.method`` with a counter; the counter (a one-item list)."""
    count = [0]
    original = getattr(cls, method)

    def counted(self, *args):
        count[0] += 1
        return original(self, *args)
    setattr(cls, method, counted)
    return count


# ============================================================================ worker processes
def _sleep_until(t):
    while True:
        left = t - time.time()
        if left <= 0:
            return
        time.sleep(min(left, 0.5))


def _write(path, data):
    tmp = path + '.tmp'
    with open(tmp, 'w') as f:
        json.dump(data, f)
    os.replace(tmp, path)


def worker_pub(a):
    """Publish ``a.type`` on ``a.topic`` at ``a.rate`` Hz, building each message; CPU and counts over the window."""
    import rospy
    rospy.init_node('prof_pub', anonymous=True, disable_signals=True)
    build = BUILDERS[a.type]
    cls = _class_of(a.type)
    serialized = _count_calls(cls, 'serialize')
    pub = rospy.Publisher(a.topic, cls, queue_size=100, tcp_nodelay=True)
    deadline = time.time() + 20.0
    while pub.get_num_connections() < a.subs and time.time() < deadline:
        time.sleep(0.02)
    connected = time.time()
    period = 1.0 / a.rate
    sent = 0
    marks = {}
    nxt = time.time()
    while True:
        now = time.time()
        if 'start' not in marks and now >= a.t_start:
            marks['start'] = (time.process_time(), sent, serialized[0], now)
        if now >= a.t_end:
            marks['end'] = (time.process_time(), sent, serialized[0], now)
            break
        pub.publish(build())
        sent += 1
        nxt += period
        delay = nxt - time.time()
        if delay > 0:
            time.sleep(delay)
        elif delay < -0.1:
            nxt = time.time()
    time.sleep(0.5)
    c0, n0, s0, w0 = marks.get('start', marks['end'])
    c1, n1, s1, w1 = marks['end']
    _write(a.out, {'cpu': c1 - c0, 'messages': n1 - n0, 'serialized': s1 - s0, 'wall': w1 - w0,
                   'connections': pub.get_num_connections(), 'late_connect': connected > a.t_start})
    rospy.signal_shutdown('done')


def worker_sub(a):
    """``a.subs`` rospy.Subscribers on ``a.topic`` in this process; CPU, messages and deserialize() calls over
    the window."""
    import rospy
    rospy.init_node('prof_sub', anonymous=True, disable_signals=True)
    cls = _class_of(a.type)
    deserialized = _count_calls(cls, 'deserialize')
    received = [0]

    def callback(msg):
        received[0] += 1
    for _ in range(a.subs):
        rospy.Subscriber(a.topic, cls, callback, queue_size=100, tcp_nodelay=True)
    _sleep_until(a.t_start)
    c0, n0, d0 = time.process_time(), received[0], deserialized[0]
    _sleep_until(a.t_end)
    c1, n1, d1 = time.process_time(), received[0], deserialized[0]
    _write(a.out, {'cpu': c1 - c0, 'callbacks': n1 - n0, 'deserialized': d1 - d0, 'subscribers': a.subs,
                   'messages': (n1 - n0) // max(1, a.subs)})
    time.sleep(0.3)
    rospy.signal_shutdown('done')


def worker_sleep(a):
    """A bare Python loop (no rospy) sleeping to the next period at ``a.rate`` Hz: CPU per wake-up."""
    period = 1.0 / a.rate
    _sleep_until(a.t_start - 1.0)
    nxt = time.time()
    wakes = 0
    marks = {}
    while True:
        now = time.time()
        if 'start' not in marks and now >= a.t_start:
            marks['start'] = (time.process_time(), wakes)
        if now >= a.t_end:
            marks['end'] = (time.process_time(), wakes)
            break
        wakes += 1
        nxt += period
        delay = nxt - time.time()
        if delay > 0:
            time.sleep(delay)
    (c0, w0), (c1, w1) = marks.get('start', marks['end']), marks['end']
    _write(a.out, {'cpu': c1 - c0, 'messages': w1 - w0})


def worker_idle(a):
    """A node on the run_node glue doing nothing but its diagnostics (1 Hz) and the master watch."""
    import rospy
    from anafi_sim.ros.node import OK, diagnostic_status, diagnostics_publisher, run_node, start_diagnostics_thread

    class Idle(object):
        def run(self):
            status = diagnostic_status('prof_idle: idle node', OK, 'idle', [('key', 'value')])
            start_diagnostics_thread(1.0, lambda: [status], diagnostics_publisher())

            def window():
                _sleep_until(a.t_start)
                c0 = time.process_time()
                _sleep_until(a.t_end)
                _write(a.out, {'cpu': time.process_time() - c0, 'wall': a.t_end - a.t_start})
                rospy.signal_shutdown('done')
            threading.Thread(target=window, daemon=True).start()
            rospy.spin()
    run_node('prof_idle', Idle, watch_master=True, disable_signals=True)


# ============================================================================ in-process timing
class Listened(object):
    """A rospy publisher that reports one subscriber (so a node builds its messages) and has none."""

    def __init__(self, pub):
        self.publish = pub.publish

    @staticmethod
    def get_num_connections():
        return 1


def per_call(fn, n, rounds=3):
    """CPU [us] per call of ``fn`` (best of ``rounds`` x ``n`` calls, time.process_time)."""
    best = float('inf')
    for _ in range(rounds):
        t0 = time.process_time()
        for _ in range(n):
            fn()
        best = min(best, time.process_time() - t0)
    return 1e6 * best / n


def message_costs():
    """{type: {build, serialize, deserialize, publish_nosub, bytes}} [us] in this process (rospy initialised)."""
    import rospy
    out = {}
    for key in TYPES:
        build = BUILDERS[key]
        msg = build()
        cls = type(msg)
        buff = io.BytesIO()
        msg.serialize(buff)
        data = buff.getvalue()
        n = 400 if key.startswith('model_states_') else 3000

        def ser():
            b = io.BytesIO()
            msg.serialize(b)
        pub = rospy.Publisher('/prof/inproc/%s' % key, cls, queue_size=10)
        out[key] = {'build': per_call(build, n), 'serialize': per_call(ser, n),
                    'deserialize': per_call(lambda: cls().deserialize(data), n),
                    'publish_nosub': per_call(lambda: pub.publish(msg), n), 'bytes': len(data)}
        pub.unregister()
    return out


def core_costs():
    """CPU [us] per call of the cores and the nodes' message building, driven as the nodes drive them."""
    import rospy
    from anafi_sim import paths
    from anafi_sim.sim.bridge import PilotingMapping
    from anafi_sim.sim.clock import SimClock
    from anafi_sim.sim.drone_model import DEFAULT_SETTINGS, AnafiModel, load_model_params
    from anafi_sim.sim.simulator import SimulatedAnafi
    from anafi_sim.sim.state_estimate import StateEstimate
    from anafi_sim.telemetry.protocol import TelemetryParser, format_sample, new_stream_id
    from anafi_sim.telemetry.server import BlockDecimator
    from anafi_sim.interface import ground_truth as gt
    from anafi_sim.gazebo.mirror import Mirror
    from anafi_sim.gazebo.kinematic_world import KinematicWorld
    from anafi_sim.sim.clock import ScaledSteps
    from anafi_sim.ros import gazebo_types
    from anafi_control.frames import euler_to_quaternion
    from anafi_control.mpc_tracking import MpcTracking
    from anafi_sim.mission.generator import TrajectoryGenerator
    from anafi_sim.mission.trajectory import SCENARIO_DIR, load_scenario
    from anafi_sim.ros.waypoints import DEFAULT_WAYPOINT_TYPE, waypoint_class, waypoint_message
    from tf2_msgs.msg import TFMessage
    from nav_msgs.msg import Odometry
    from anafi_sim.msg import DroneData
    out = {}

    # --- simulator: physics 200 Hz, telemetry 100 Hz, estimate 30 Hz; a command every 20 steps (10 Hz)
    model = AnafiModel(load_model_params(paths.config_path('anafi_model.yaml')), mapping=PilotingMapping(),
                       seed=0, settings=dict(DEFAULT_SETTINGS))
    sim = SimulatedAnafi(model, StateEstimate(model.params), SimClock(200.0, 1.0, 100.0, 30.0, False))
    sim.start(time.monotonic())
    k = [0]
    last = {}

    def step():
        k[0] += 1
        if k[0] % 20 == 0:
            sim.on_command(2.0, -1.0, 5.0, 0.1)
        s = sim.step()
        if s.estimate is not None:
            last['estimate'] = s.estimate
    for _ in range(1200):   # take-off done, flying
        step()
    out['sim_step'] = per_call(step, 2000)
    sample = model.truth_sample(1.0)

    # simulator's ROS outputs: sim/truth (100 Hz) and the 9 estimate topics (30 Hz), no subscribers
    node_mod = _script('anafi_sim_node')
    fake = object.__new__(node_mod.AnafiSimNode)
    fake.child_frame, fake.odom_frame, fake.truth_frame = 'anafi1/base_link', 'anafi1/odom', 'anafi1/base_link_gt'
    fake.sim_stamps = False
    for name in ('pub_odom', 'pub_pose', 'pub_attitude', 'pub_speed', 'pub_altitude', 'pub_rpy', 'pub_camera',
                 'pub_camera_base', 'pub_state_enu', 'pub_truth', 'pub_tf'):
        setattr(fake, name, None)
    from geometry_msgs.msg import PoseStamped, QuaternionStamped, Vector3Stamped
    from std_msgs.msg import Float32
    from anafi_sim.ros.wire_types import paper_state_class
    fake.State = paper_state_class()
    pubs = []
    for name, cls in (('pub_odom', Odometry), ('pub_pose', PoseStamped), ('pub_attitude', QuaternionStamped),
                      ('pub_speed', Vector3Stamped), ('pub_altitude', Float32), ('pub_rpy', Vector3Stamped),
                      ('pub_camera', QuaternionStamped), ('pub_camera_base', QuaternionStamped),
                      ('pub_state_enu', fake.State), ('pub_truth', Odometry)):
        pub = rospy.Publisher('/prof/sim/%s' % name, cls, queue_size=10)
        setattr(fake, name, pub)
        pubs.append(pub)
    estimate = last['estimate']
    out['sim_estimate_publish'] = per_call(lambda: fake._publish_estimate(estimate, rospy.Time.now()), 1000)
    out['sim_truth_publish'] = per_call(lambda: fake._publish_truth(sample, rospy.Time.now()), 2000)

    # --- telemetry: one sample formatted (simulator), the CLI's block handling, parsed (interface)
    stream_id = new_stream_id()
    text = format_sample(sample, stream_id=stream_id) + '\n'
    out['telemetry_format'] = per_call(lambda: (format_sample(sample, stream_id=stream_id) + '\n').encode('ascii'),
                                       3000)
    block = text.encode('ascii')
    sink = io.BytesIO()
    decimator = BlockDecimator(0.0)

    def cli():
        pending = block
        end = pending.rfind(b'\n\n')
        complete = pending[:end + 2]
        if decimator.keep(complete):
            sink.seek(0)
            sink.write(complete)
    out['cli_block'] = per_call(cli, 3000)
    parser = TelemetryParser()
    lines = text.splitlines(True)

    def parse():
        result = None
        for line in lines:
            got = parser.feed_line(line, True)
            if got is not None:
                result = got
        return result
    out['telemetry_parse'] = per_call(parse, 2000)
    out['telemetry_lines'] = len(lines)

    # --- interface: on_sample (100 Hz stream) and publish() (4 messages, no subscribers)
    core = gt.GroundTruthInterface(publish_rate=100.0, stale_timeout=0.5)
    ts = [0.0]

    def on_sample():
        ts[0] += 0.01
        return core.on_sample(sample._replace(timestamp=ts[0]), time.time())
    out['interface_on_sample'] = per_call(on_sample, 3000)
    iface_mod = _script('interface_node')
    iface = object.__new__(iface_mod.InterfaceNode)
    iface.p = {'stamp_with_sample_time': False, 'camera_offset': (0.1, 0.0, 0.0)}
    iface.frame_id, iface.base_link, iface.stability_axes, iface.camera = ('world', 'a/base_link',
                                                                           'a/stability_axes', 'a/camera')
    iface.body_fixed = None
    from anafi_sim.ros.wire_types import sphinx_class
    iface.sphinx_class = sphinx_class()
    # publishers that say someone listens (the node builds a message only then) but have no subscriber: the
    # messages are built and published, not serialised
    iface.pub_data = Listened(rospy.Publisher('/prof/iface/drone_data', DroneData, queue_size=50))
    iface.pub_sphinx = Listened(rospy.Publisher('/prof/iface/sphinx', iface.sphinx_class, queue_size=50))
    iface.pub_odom = Listened(rospy.Publisher('/prof/iface/odom', Odometry, queue_size=50))
    iface.pub_tf = Listened(rospy.Publisher('/prof/iface/tf', TFMessage, queue_size=100))
    out['interface_publish'] = per_call(lambda: iface.publish(sample), 2000)
    # the reader thread's path for one sample: readline + decode + on_line (parse, on_sample), publish excluded
    reader = object.__new__(iface_mod.InterfaceNode)
    reader.parser = TelemetryParser()
    reader.core = gt.GroundTruthInterface(publish_rate=100.0, stale_timeout=0.5)
    reader.lock = threading.Lock()
    reader.publish = lambda _sample: None
    blocks = [(format_sample(sample._replace(timestamp=0.01 * (i + 1)), stream_id=stream_id) + '\n').encode()
              for i in range(3000)]
    stream = io.BufferedReader(io.BytesIO(b''.join(blocks)))
    readline = stream.readline

    def read_sample():
        for _ in range(len(lines)):
            raw = readline(4096)
            reader.on_line(raw.decode('utf-8', 'replace'), time.time())
    out['interface_reader'] = per_call(read_sample, 900, rounds=3)

    # --- mirror: on_gimbal + on_ground_truth + the two ModelState messages (no subscriber)
    mirror = Mirror(drone_name='anafi1', rate=100.0)
    for name in (mirror.drone_model, mirror.camera_model):
        mirror.spawn.on_spawn_result(name, True, 'ok', 0.0)
    mirror_mod = _script('gazebo_mirror_node')
    mnode = object.__new__(mirror_mod.GazeboMirrorNode)
    mnode.ModelState = gazebo_types.model_state_class()
    state_pub = rospy.Publisher('/prof/mirror/set_model_state', mnode.ModelState, queue_size=10)
    mt = [100.0]

    def mirror_core():
        mt[0] += 0.01
        mirror.on_gimbal(0.01, -0.2, mt[0], mt[0] + 0.001)
        return mirror.on_ground_truth((1.0, 2.0, 3.0), (0.0, 0.05, 0.1, 0.99), (0.4, -0.2, 0.3),
                                      (0.05, -0.02, 0.3), mt[0], mt[0] + 0.002)
    out['mirror_core'] = per_call(mirror_core, 3000)
    states = mirror_core()
    out['mirror_states'] = len(states)
    out['mirror_messages_build'] = per_call(lambda: [mnode._message(s) for s in states], 3000)
    out['mirror_messages_publish'] = per_call(lambda: [state_pub.publish(mnode._message(s)) for s in states], 3000)

    # --- MPC at 10 Hz of time: 3 states (30 Hz) + 1 waypoint + the cycle; circle r = 2 m, v = 1 m/s
    mpc = MpcTracking()
    tm = [0.0]

    def mpc_period():
        t0 = tm[0]
        for i in range(3):
            t = t0 + i / 30.0
            a = 0.5 * t
            mpc.on_state(t, (2.0 * math.cos(a) - 0.05, 2.0 * math.sin(a), 1.5), euler_to_quaternion(0.0, 0.0, a),
                         (1.0, 0.0, 0.0))
        a = 0.5 * t0
        mpc.on_waypoint(t0, (2.0 * math.cos(a), 2.0 * math.sin(a), 1.5, -math.sin(a), math.cos(a), 0.0, 0.0))
        result = mpc.cycle(t0 + 0.09)
        tm[0] += 0.1
        return result
    for _ in range(20):
        mpc_period()
    out['mpc_period'] = per_call(mpc_period, 150)
    mpc_states = per_call(lambda: mpc.on_state(tm[0], (2.0, 0.0, 1.5), (0.0, 0.0, 0.0, 1.0), (1.0, 0.0, 0.0)), 3000)
    out['mpc_on_state'] = mpc_states

    # --- trajectory generator: update + waypoint message at 10 Hz
    gen = TrajectoryGenerator(load_scenario('circle_r2_v1', SCENARIO_DIR))
    gen.start(0.0)
    tg = [0.0]
    wp_class = waypoint_class(DEFAULT_WAYPOINT_TYPE)
    wp_pub = rospy.Publisher('/prof/generator/waypoint', wp_class, queue_size=10)

    def gen_tick():
        tg[0] += 0.1
        wp, _ = gen.update(tg[0])
        if wp is not None:
            wp_pub.publish(waypoint_message(DEFAULT_WAYPOINT_TYPE, wp, rospy.Time.from_sec(tg[0]), 'world'))
    out['generator_tick'] = per_call(gen_tick, 1000)

    # --- kinematic world: one ModelState through the node's handler; the 100 Hz cycle with 2N + 1 models
    world_mod = _script('kinematic_world_node')
    with open(paths.data_path('urdf', 'anafi.urdf')) as f:
        urdf = f.read()
    with open(paths.data_path('urdf', 'anafi_camera.urdf')) as f:
        camera_urdf = f.read()
    out['world_cycle'] = {}
    for n in (1, LIVE_DRONES, 10, PROJECT_N):
        wnode = object.__new__(world_mod.KinematicWorldNode)
        wnode.world = KinematicWorld(gravity=9.81, ground_plane=True)
        for i in range(n):
            wnode.world.spawn('anafi%d' % (i + 1), urdf, (6.0 * i, 0.0, 0.0))
            wnode.world.spawn('anafi%d_camera' % (i + 1), camera_urdf, (6.0 * i + 0.1, 0.0, 0.0))
        wnode.lock = threading.Lock()
        wnode.p = {'max_step': 0.01, 'publish_clock': False}
        wnode.steps = ScaledSteps(1.0, 0.1)
        wnode.cycles = 0
        wnode.clock_pub = None
        wnode.ModelStates = gazebo_types.model_states_class()
        wnode.states_msg = wnode.ModelStates()
        wnode.state_pub = rospy.Publisher('/prof/world%d/model_states' % n, wnode.ModelStates, queue_size=1)
        wnode.contact_pub = None
        out['world_cycle'][str(n)] = per_call(lambda: wnode.cycle(0.01), 300 if n < 10 else 60)
        if n == LIVE_DRONES:
            msg = _model_state()
            out['world_set_state'] = per_call(lambda: wnode._set(msg), 3000)
    for pub in pubs:
        pub.unregister()
    return out


# ============================================================================ the two-process runs
class Runner(object):
    """Starts worker processes (this script with --worker) on the private master."""

    def __init__(self, procs, env, workdir):
        self.procs, self.env, self.workdir = procs, env, workdir
        self.count = 0

    def start(self, kind, key, topic, t_start, t_end, subs=1, rate=1000.0):
        self.count += 1
        name = 'w%d_%s_%s' % (self.count, kind, key)
        path = os.path.join(self.workdir, name + '.json')
        self.procs.start(name, [sys.executable, os.path.abspath(__file__), '--worker', kind, '--type', key,
                                '--topic', topic, '--t-start', repr(t_start), '--t-end', repr(t_end),
                                '--subs', str(subs), '--rate', repr(rate), '--out', path], self.env)
        return name, path

    def collect(self, started, timeout):
        """{name: result dict or None} once every worker wrote its file (or ``timeout`` s passed)."""
        deadline = time.time() + timeout
        out = {}
        for name, path in started:
            while not os.path.exists(path) and time.time() < deadline:
                time.sleep(0.1)
            try:
                with open(path) as f:
                    out[name] = json.load(f)
            except (IOError, ValueError):
                out[name] = None
                print('worker %s wrote nothing; log tail:\n%s' % (name, self.procs.log_tail(name)), flush=True)
            self.procs.stop(name, grace=2.0)
        return out


def rospy_runs(runner, args):
    """Per type: publisher with one subscriber, publisher alone; Odometry also at 100 Hz and with a process of
    two subscribers. Two types at a time. {key: {...}}."""
    jobs = []
    for rate in (args.fleet_rate, args.rate):
        for key in TYPES:
            jobs.append((key, 'sub1@%g' % rate, 1, rate))
            jobs.append((key, 'nosub@%g' % rate, 0, rate))
    jobs.append(('odometry', 'sub2@%g' % args.fleet_rate, 2, args.fleet_rate))
    results = {}
    batch = args.batch
    for i in range(0, len(jobs), batch):
        t_start = time.time() + args.lead
        t_end = t_start + args.window
        started = []
        for key, variant, subs, rate in jobs[i:i + batch]:
            topic = '/prof/%s/%s' % (key, variant.replace('@', '_').replace('.', '_'))
            if subs:
                started.append(('sub',) + runner.start('sub', key, topic, t_start, t_end, subs=subs))
            started.append(('pub',) + runner.start('pub', key, topic, t_start, t_end, subs=1 if subs else 0,
                                                   rate=rate))
        got = runner.collect([(n, p) for _, n, p in started], args.lead + args.window + 25.0)
        for (role, name, _), (key, variant, subs, rate) in zip(
                started, [j for j in jobs[i:i + batch] for _ in range(2 if j[2] else 1)]):
            results.setdefault(key, {}).setdefault(variant, {})[role] = got[name]
            results[key][variant]['rate'] = rate
        print('rospy runs: %s done' % ', '.join('%s/%s' % (j[0], j[1]) for j in jobs[i:i + batch]), flush=True)
    return results


def per_message(run, role):
    """us of CPU per message of one side of a run (NaN when missing)."""
    r = (run or {}).get(role)
    if not r or not r.get('messages'):
        return float('nan')
    return 1e6 * r['cpu'] / r['messages']


# ============================================================================ live fleet
def live_fleet(procs, env, port, workdir, args):
    """fleet.launch drones:=2: topic rates and their publishers / subscribers, then CPU per process."""
    import rosgraph
    import rospy
    sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
    import bench_fleet
    diag = bench_fleet.Diagnostics()
    n = LIVE_DRONES
    launch = procs.start('fleet', ['roslaunch', '--port', str(port), 'anafi_sim', 'fleet.launch',
                                   'drones:=%d' % n, 'evaluate:=false',
                                   'out_dir:=%s' % os.path.join(workdir, 'fleet')], env)
    names = ['anafi%d' % (i + 1) for i in range(n)]
    try:
        def flying():
            snap = diag.snapshot()
            gens = [snap.get('trajectory_generator: /%s/trajectory_generator' % d) for d in names]
            return all(g is not None and g[2] == 'running' for g in gens)
        processes.require(lambda: launch.poll() is None and flying(), 180.0, 'all drones flying',
                          lambda: procs.log_tail('fleet', 30))
        time.sleep(args.settle)
        master = rosgraph.Master('/prof_rates')
        pubs, subs, _ = master.getSystemState()
        me = rospy.get_name()
        publishers = dict((t, [x for x in nodes if x != me]) for t, nodes in pubs)
        subscribers = dict((t, [x for x in nodes if x != me]) for t, nodes in subs)
        counts = {}
        lock = threading.Lock()

        def counter(topic):
            def cb(_msg):
                with lock:
                    counts[topic] = counts.get(topic, 0) + 1
            return cb
        skip = ('/rosout', '/rosout_agg')
        handles = [rospy.Subscriber(t, rospy.AnyMsg, counter(t), queue_size=200)
                   for t in sorted(publishers) if publishers[t] and t not in skip]
        time.sleep(1.5)
        with lock:
            counts.clear()
        t0 = time.time()
        time.sleep(args.rates_window)
        with lock:
            snap = dict(counts)
        wall = time.time() - t0
        for h in handles:
            h.unregister()
        rates = dict((t, {'hz': snap.get(t, 0) / wall, 'publishers': publishers.get(t, []),
                          'subscribers': subscribers.get(t, [])}) for t in publishers if publishers[t])
        time.sleep(1.0)
        before = diag.snapshot()
        per_process = {}

        def role(proc, is_root):
            r = bench_fleet.role_of(proc, is_root)
            try:
                cmd = proc.cmdline()
            except psutil.Error:
                cmd = []
            try:
                ns = [proc.environ().get('ROS_NAMESPACE', '')]
            except psutil.Error:
                ns = ['']
            node = [c.split(':=', 1)[1] for c in cmd if c.startswith('__name:=')]
            per_process[(proc.pid, proc.create_time())] = {'role': r, 'ns': ns[0] if ns else '',
                                                           'name': node[0] if node else ''}
            return r
        window = processes.CpuWindow({'launch': processes.TreeCpu(launch.pid, role),
                                      'core': processes.TreeCpu(procs.started[0][1].pid, role)},
                                     args.live_window).run()
        time.sleep(1.5)
        after = diag.snapshot()
        cpu = {}
        for tree in window.trees.values():
            for key, c in tree.last.items():
                info = per_process.get(key, {'role': 'other', 'ns': '', 'name': ''})
                cpu['%d' % key[0]] = dict(info, pct=100.0 * (c - tree.base.get(key, 0.0)) / window.wall)
        drones = bench_fleet.drone_figures(names, before, after)
    finally:
        procs.stop('fleet')
    per_role = {}
    for tree in ('launch', 'core'):
        for r, (c, count) in window.cpu[tree].items():
            entry = per_role.setdefault(r, [0.0, 0])
            entry[0] += 100.0 * c / window.wall
            entry[1] += count
    return {'n': n, 'rates': rates, 'rates_wall': wall, 'roles': per_role, 'processes': cpu, 'drones': drones,
            'wall': window.wall, 'busy': window.busy, 'load_before': window.load_before,
            'load_after': window.load_after, 'bench_cpu': 100.0 * window.bench_cpu / window.wall}


# ============================================================================ the attribution
def _fit_model_states(msg, runs, field):
    """(a, b) of cost = a + b x models, least squares over the three ModelStates sizes (us)."""
    xs, ys = [], []
    for key, models in (('model_states_2', 2), ('model_states_20', 20), ('model_states_40', 40)):
        v = field(key)
        if not math.isnan(v):
            xs.append(models)
            ys.append(v)
    if len(xs) < 2:
        return float('nan'), float('nan')
    mx, my = sum(xs) / len(xs), sum(ys) / len(ys)
    b = sum((x - mx) * (y - my) for x, y in zip(xs, ys)) / sum((x - mx) ** 2 for x in xs)
    return my - b * mx, b


def costs_table(data):
    """Per type [us per message]: pub1, pub0, sub1 at the fleet's rate, pub1_fast, pub0_fast, sub1_fast at
    ``--rate``; serialize() calls without a subscriber; the in-process figures; Odometry's two-subscriber run."""
    runs, inproc = data['rospy'], data['messages']
    fleet, fast = data['args']['fleet_rate'], data['args']['rate']
    out = {}
    for key in TYPES:
        r = runs.get(key, {})
        s1, s0 = r.get('sub1@%g' % fleet, {}), r.get('nosub@%g' % fleet, {})
        row = dict(inproc.get(key, {}))
        row['pub1'] = per_message(s1, 'pub')
        row['sub1'] = per_message(s1, 'sub')
        row['pub0'] = per_message(s0, 'pub')
        row['pub1_fast'] = per_message(r.get('sub1@%g' % fast), 'pub')
        row['sub1_fast'] = per_message(r.get('sub1@%g' % fast), 'sub')
        row['pub0_fast'] = per_message(r.get('nosub@%g' % fast), 'pub')
        p0 = (s0 or {}).get('pub') or {}
        row['serialized_nosub'] = p0.get('serialized', float('nan'))
        row['messages_nosub'] = p0.get('messages', float('nan'))
        p1 = (s1 or {}).get('pub') or {}
        row['serialized_sub1'] = p1.get('serialized', float('nan'))
        row['messages_sub1'] = p1.get('messages', float('nan'))
        out[key] = row
    odo = runs.get('odometry', {})
    out['odometry']['sub2'] = per_message(odo.get('sub2@%g' % fleet), 'sub')
    sub2 = (odo.get('sub2@%g' % fleet) or {}).get('sub') or {}
    out['odometry']['sub2_deserialized_per_message'] = (sub2.get('deserialized', 0) / sub2['messages']
                                                        if sub2.get('messages') else float('nan'))
    return out


def _rate(live, topic, default):
    """Per-drone message rate [Hz] of ``topic`` (a drone topic without the namespace, or a global one)."""
    rates = live['rates']
    if topic.startswith('/'):
        return rates.get(topic, {}).get('hz', default)
    vals = [rates['/anafi%d/%s' % (i + 1, topic)]['hz'] for i in range(live['n'])
            if '/anafi%d/%s' % (i + 1, topic) in rates]
    return sum(vals) / len(vals) if vals else default


def _subs(live, topic):
    rates = live['rates']
    if topic.startswith('/'):
        return len(rates.get(topic, {}).get('subscribers', []))
    vals = [len(rates['/anafi%d/%s' % (i + 1, topic)]['subscribers']) for i in range(live['n'])
            if '/anafi%d/%s' % (i + 1, topic) in rates]
    return max(vals) if vals else 0


def attribution(data, n=None):
    """{role: [(item, rate Hz, us per event, % of a core per drone)]} for a fleet of ``n`` drones (default the
    live one): rates from the live run (per drone), costs from the rospy runs and the in-process timings."""
    live, core, c = data['live'], data['core'], costs_table(data)
    n = n or live['n']
    idle = data['idle_pct']
    conn = dict((k, c[k]['pub1'] - c[k]['pub0']) for k in TYPES)   # us per message per subscribed connection
    a_sub, b_sub = _fit_model_states(None, None, lambda k: c[k]['sub1'])
    a_con, b_con = _fit_model_states(None, None, lambda k: conn[k])
    wake = wake_up(c)
    models = 2 * n + 1
    world_cycle = core['world_cycle'].get(str(n))
    if world_cycle is None:    # between measured sizes: linear in the models
        pts = sorted((int(k), v) for k, v in core['world_cycle'].items())
        (n0, v0), (n1, v1) = pts[-2], pts[-1]
        world_cycle = v0 + (v1 - v0) * (n - n0) / float(n1 - n0)

    def item(label, rate, us):
        return (label, rate, us, rate * us / 1e4)
    r_truth = _rate(live, 'sim/truth', 100.0)
    r_est = _rate(live, 'drone/odom', 30.0)
    r_cmd = _rate(live, 'drone/rpyt', 10.0)
    r_gt = _rate(live, 'ground_truth/odom', 100.0)
    r_dd = _rate(live, 'ground_truth/drone_data', 100.0)
    r_sphinx = _rate(live, 'sphinx/drone_data', 100.0)
    r_wp = _rate(live, 'position_control/waypoint', 10.0)
    r_stats = _rate(live, 'mpc/stats', 10.0)
    r_ms = _rate(live, '/gazebo/model_states', 100.0)
    r_set = _rate(live, '/gazebo/set_model_state', 200.0 * live['n']) / live['n']
    r_tf = _rate(live, '/tf', 100.0 * live['n']) / live['n']
    extra = lambda topic, key, rate: item('serialize + send %s to %d subscriber(s)' % (topic, _subs(live, topic)),
                                          rate, conn[key] * _subs(live, topic))
    bare = data.get('bare_wake_us', wake)

    def publish(key, subs):
        """build + publish() in process + (serialize + send) per subscribed connection [us]."""
        return c[key]['build'] + c[key]['publish_nosub'] + subs * conn[key]
    table = {}
    table['simulator'] = [
        item('physics step + estimate + truth sample (core; 200 Hz)', 200.0, core['sim_step']),
        item('loop wake-ups (sleep between steps)', 200.0, wake),
        item('telemetry sample formatted for the CLI', 100.0, core['telemetry_format']),
        item('sim/truth Odometry built + publish() (no subscriber: %d)' % _subs(live, 'sim/truth'), r_truth,
             core['sim_truth_publish']),
        item('estimate: 9 topics built + publish()', r_est, core['sim_estimate_publish']),
        extra('drone/odom', 'odometry', r_est),
        item('drone/rpyt received (subscriber side)', r_cmd, c['rpyt']['sub1']),
        item('idle node (diagnostics 1 Hz, master watch)', 1.0, idle * 1e4)]
    table['telemetry CLI'] = [item('block split + write (core)', 100.0, core['cli_block']),
                              item('wake-ups (recv, write; a bare Python loop\'s wake-up)', 100.0, bare)]
    table['interface'] = [
        item('reader thread wake-ups', 100.0, wake),
        item('reader: %d lines readline + decode + on_line (parse, on_sample)' % core['telemetry_lines'], 100.0,
             core['interface_reader']),
        item('publish(): DroneData + Odometry + Sphinx + TF(3) built + 4 publish()', r_gt, core['interface_publish']),
        extra('ground_truth/odom', 'odometry', r_gt), extra('ground_truth/drone_data', 'drone_data', r_dd),
        extra('sphinx/drone_data', 'sphinx', r_sphinx),
        item('serialize + send /tf to %d subscriber(s)' % _subs(live, '/tf'), r_tf,
             conn['tf3'] * _subs(live, '/tf')),
        item('idle node (diagnostics 1 Hz, master watch)', 1.0, idle * 1e4)]
    table['mirror'] = [
        item('ground_truth/odom received (Odometry)', r_gt, c['odometry']['sub1']),
        item('ground_truth/drone_data received (DroneData)', r_dd, c['drone_data']['sub1']),
        item('Mirror.on_gimbal + on_ground_truth (core)', r_gt, core['mirror_core']),
        item('2 ModelState built + publish() (core)', r_gt, core['mirror_messages_publish']),
        item('2 ModelState serialize + send to %d subscriber(s) (world)' % _subs(live, '/gazebo/set_model_state'),
             r_gt, 2 * conn['model_state'] * _subs(live, '/gazebo/set_model_state')),
        item('/gazebo/model_states received (%d models)' % models, r_ms, a_sub + b_sub * models),
        item('main loop wake-ups (20 Hz)', 20.0, wake),
        item('idle node (diagnostics 1 Hz, master watch)', 1.0, idle * 1e4)]
    table['controller'] = [
        item('MPC period: cycle + 3 states + 1 waypoint (core)', 10.0, core['mpc_period']),
        item('drone/odom received (Odometry)', r_est, c['odometry']['sub1']),
        item('waypoint received (~ PilotingCommand cost)', r_wp, c['rpyt']['sub1']),
        item('timer wake-ups (10 Hz)', 10.0, wake),
        item('drone/rpyt built + publish() + send (subscribers: %d)' % _subs(live, 'drone/rpyt'), r_cmd,
             publish('rpyt', _subs(live, 'drone/rpyt'))),
        item('drone/rpyt received by its own commander watch', r_cmd, c['rpyt']['sub1']),
        item('mpc/stats published (~ PilotingCommand, subscribers: %d)' % _subs(live, 'mpc/stats'), r_stats,
             publish('rpyt', _subs(live, 'mpc/stats'))),
        item('idle node (diagnostics 1 Hz, master watch)', 1.0, idle * 1e4)]
    table['generator'] = [
        item('Rate wake-ups (10 Hz)', 10.0, wake),
        item('generator update + waypoint built + publish() (core)', r_wp, core['generator_tick']),
        item('serialize + send the waypoint (~ PilotingCommand) to %d subscriber(s)'
             % _subs(live, 'position_control/waypoint'), r_wp, conn['rpyt'] * _subs(live, 'position_control/waypoint')),
        item('idle node (diagnostics 1 Hz, master watch)', 1.0, idle * 1e4)]
    table['world'] = [
        item('/gazebo/set_model_state received (ModelState)', r_set, c['model_state']['sub1']),
        item('KinematicWorld.set_state via the node', r_set, core['world_set_state']),
        item('cycle: advance + states + ModelStates built + publish() (%d models), / N' % models, r_ms,
             world_cycle / n),
        item('serialize + send model_states (%d models) to %d mirrors, / N' % (models, n), r_ms,
             (a_con + b_con * models + max(0, n - 1) * conn['rpyt']) / n),
        item('loop wake-ups (100 Hz), / N', 100.0, wake / n),
        item('idle node, / N', 1.0, idle * 1e4 / n)]
    return table


def wake_up(c):
    """us of CPU of one wake-up of a sleeping loop: the publisher process's CPU per message without a subscriber
    at the fleet's rate minus building and publishing the message in process (Odometry)."""
    o = c['odometry']
    return o['pub0'] - o['build'] - o['publish_nosub']


#: the cuts of a shared layout (one process per role hosting every drone's instance, in-process delivery between
#: instances hosted together): (name, [(role, label start, share of the item that goes away)]); the share of a
#: per-process item that stays is 1 / N (one per process instead of one per drone), written 'N'
CUTS = (
    ('interface -> mirror delivered in process (needs the interface and the mirror of a drone in one process; '
     'ground_truth/odom and drone_data then not serialized, sent, received)',
     [('interface', 'serialize + send ground_truth/odom', 1.0), ('interface', 'serialize + send ground_truth/drone',
                                                                  1.0),
      ('mirror', 'ground_truth/odom received', 1.0), ('mirror', 'ground_truth/drone_data received', 1.0)]),
    ('mirror -> world delivered in process (needs the mirrors and the kinematic world in one process; the 2 '
     'ModelStates per sample)',
     [('mirror', '2 ModelState serialize + send', 1.0), ('world', '/gazebo/set_model_state received', 1.0)]),
    ('/gazebo/model_states: one subscription per mirror process instead of one per drone (per-role process)',
     [('mirror', '/gazebo/model_states received', 'N'), ('world', 'serialize + send model_states', 'N')]),
    ('simulator: one stepping loop for every drone (per-role process; one wake-up per step)',
     [('simulator', 'loop wake-ups', 'N')]),
    ('interface: one reader thread for every drone\'s telemetry (per-role process; wake-ups shared only when '
     'the samples arrive together)',
     [('interface', 'reader thread wake-ups', 'N')]),
    ('simulator -> controller delivered in process (needs both in one process; drone/odom 30 Hz, drone/rpyt '
     '10 Hz and its commander watch)',
     [('simulator', 'serialize + send drone/odom', 1.0), ('controller', 'drone/odom received', 1.0),
      ('simulator', 'drone/rpyt received', 1.0), ('controller', 'drone/rpyt received', 1.0)]),
    ('idle node costs (diagnostics thread, master watch, timers) once per process (per-role processes)',
     [(r, 'idle node (diagnostics', 'N') for r in ('simulator', 'interface', 'mirror', 'controller', 'generator')]
     + [('mirror', 'main loop wake-ups', 'N'), ('controller', 'timer wake-ups', 'N'),
        ('generator', 'Rate wake-ups', 'N')]),
)


def cut_savings(data, n):
    """[(cut, % core per drone saved at ``n`` drones, items it removes)] from ``attribution(data, n)``."""
    table = attribution(data, n)
    out = []
    for name, parts in CUTS:
        saved, labels = 0.0, []
        for role, start, share in parts:
            for label, rate, us, pct in table.get(role, []):
                if label.startswith(start):
                    saved += pct * ((1.0 - 1.0 / n) if share == 'N' else share)
                    labels.append('%s: %s' % (role, label))
        out.append((name, saved, labels))
    return out


def measured_per_drone(live):
    n = live['n']
    return dict((role, v[0] / n) for role, v in live['roles'].items())


# ============================================================================ the report
def _f(v, fmt='%.1f'):
    return 'n/a' if v is None or (isinstance(v, float) and math.isnan(v)) else fmt % v


def markdown(data):
    c = costs_table(data)
    live = data['live']
    fleet, fast = data['args']['fleet_rate'], data['args']['rate']
    lines = ['# Where a fleet drone\'s CPU goes: per process, per message path', '',
             'Generated by `benchmarks/bench_fleet_profile.py` (%s, Python %s, %d CPU cores, %s; load average '
             '%.1f / %.1f / %.1f at the start). Rerun (inside env.bash, in a network namespace of your own): '
             '`python benchmarks/bench_fleet_profile.py` (about %.0f s). CPU = user + sys; *us* = microseconds of '
             'CPU; *%% core* = percent of one core.'
             % (data['date'], data['python'], data['cores'], data['cpu_model'], data['load'][0], data['load'][1],
                data['load'][2], data['duration_s']), '',
             '## 1. rospy per message', '',
             'Two processes on a private master: a publisher building each message as the nodes do and publishing '
             'it at %g Hz (and %g Hz), and a subscriber counting what it receives (rospy deserializes before the '
             'callback); CPU of each process (time.process_time, all threads) over the same %g s window / messages. '
             '*No subscriber*: the publisher alone. In process (best of 3): build only, serialize only '
             '(msg.serialize into a BytesIO), deserialize only, and publish() of a built message with no '
             'subscriber.' % (fleet, fast, data['args']['window']), '',
             '| message | bytes | build | serialize | deserialize | publish(), no subscriber (in process) '
             '| publisher per msg, 1 sub | publisher per msg, no sub | of which serialize + send '
             '| subscriber per msg | publisher per msg at %g Hz, 1 sub / no sub | subscriber per msg at %g Hz '
             '| serialize() calls per msg, no sub |' % (fast, fast),
             '|---|---|---|---|---|---|---|---|---|---|---|---|---|']
    for key in TYPES:
        r = c[key]
        ser0 = r['serialized_nosub'] / r['messages_nosub'] if r.get('messages_nosub') else float('nan')
        lines.append('| %s | %s | %s | %s | %s | %s | %s | %s | %s | %s | %s / %s | %s | %s |' % (
            LABELS[key], _f(r.get('bytes'), '%d'), _f(r.get('build')), _f(r.get('serialize')),
            _f(r.get('deserialize')), _f(r.get('publish_nosub')), _f(r['pub1']), _f(r['pub0']),
            _f(r['pub1'] - r['pub0']), _f(r['sub1']), _f(r['pub1_fast']), _f(r['pub0_fast']), _f(r['sub1_fast']),
            _f(ser0, '%.2f')))
    o = c['odometry']
    lines += ['', 'All figures in us of CPU; the first four columns in process, the others per message of the '
              'publisher or subscriber process at %g Hz (the fleet\'s rate: every message wakes a thread) unless '
              'said. One sleeping loop\'s wake-up (Odometry publisher without subscriber minus building and '
              'publishing in process): %s us; of a bare Python sleep loop (no rospy) at %g Hz: %s us. One '
              'subscriber process with two rospy.Subscribers on the Odometry '
              'topic: %s us per message (one: %s), deserialize() called %s times per message.'
              % (fleet, _f(wake_up(c)), fleet, _f(data.get('bare_wake_us')), _f(o['sub2']), _f(o['sub1']),
                 _f(o['sub2_deserialized_per_message'], '%.2f')), '',
              'Idle rospy node on our run_node glue (diagnostics thread at 1 Hz, master watch, no traffic), %g s: '
              '%s %% of a core.' % (data['args']['idle_window'], _f(data['idle_pct'], '%.2f')), '',
              '## 2. The cores per call (in process, no ROS traffic)', '',
              '| path item | us per call | calls per s per drone | % core per drone |', '|---|---|---|---|']
    core = data['core']
    for label, key, rate in (
            ('simulator step (physics 200 Hz; telemetry 100 Hz and estimate 30 Hz decimated in)', 'sim_step', 200),
            ('simulator: sim/truth Odometry built + publish() (no subscriber)', 'sim_truth_publish', 100),
            ('simulator: 9 estimate topics built + publish() (no subscribers)', 'sim_estimate_publish', 30),
            ('telemetry: one sample formatted (simulator side)', 'telemetry_format', 100),
            ('telemetry CLI: one block split and written', 'cli_block', 100),
            ('telemetry: one sample parsed (%d lines, interface side)' % core['telemetry_lines'], 'telemetry_parse',
             100),
            ('GroundTruthInterface.on_sample', 'interface_on_sample', 100),
            ('interface reader: one sample\'s lines readline + decode + on_line (publish excluded)',
             'interface_reader', 100),
            ('interface publish(): DroneData + Odometry + Sphinx + TF(3), no subscribers', 'interface_publish', 100),
            ('Mirror.on_gimbal + on_ground_truth', 'mirror_core', 100),
            ('mirror: the 2 ModelState messages built', 'mirror_messages_build', 100),
            ('mirror: the 2 ModelState messages built + publish() (no subscriber)', 'mirror_messages_publish', 100),
            ('MPC period: cycle + 3 on_state + on_waypoint', 'mpc_period', 10),
            ('MPC on_state alone', 'mpc_on_state', 30),
            ('trajectory generator update + waypoint built + publish()', 'generator_tick', 10),
            ('kinematic world: one ModelState through the node (set_state)', 'world_set_state', 200)):
        lines.append('| %s | %s | %d | %s |' % (label, _f(core[key]), rate, _f(core[key] * rate / 1e4, '%.2f')))
    for n, v in sorted(core['world_cycle'].items(), key=lambda kv: int(kv[0])):
        lines.append('| kinematic world cycle, N = %s (%d models): advance + states + ModelStates + publish() '
                     '| %s | 100 / N | %s |' % (n, 2 * int(n) + 1, _f(v), _f(v * 100 / 1e4 / int(n), '%.2f')))
    lines += ['', '## 3. Live: fleet.launch drones:=%d evaluate:=false' % live['n'], '',
              'Message rates over %.0f s (rospy.AnyMsg counters of this script, which subscribed only for that '
              'window), with the publishers and subscribers the master knew before (this script excluded). '
              'Per drone: anafi1\'s topics.' % live['rates_wall'], '',
              '| topic | Hz | publishers | subscribers |', '|---|---|---|---|']
    for topic in sorted(live['rates']):
        if topic.startswith('/anafi2/'):
            continue
        r = live['rates'][topic]
        lines.append('| %s | %.1f | %s | %s |' % (topic, r['hz'], ', '.join(r['publishers']),
                                                  ', '.join(r['subscribers']) or '-'))
    lines += ['', 'CPU over %.0f s by process [%% core] (machine busy %.0f %%, load %.1f -> %.1f; this script %.1f %%):'
              % (live['wall'], live['busy'], live['load_before'][0], live['load_after'][0], live['bench_cpu']), '',
              '| role | namespace | node | % core |', '|---|---|---|---|']
    for pid, p in sorted(live['processes'].items(), key=lambda kv: (kv[1]['role'], kv[1]['ns'], -kv[1]['pct'])):
        lines.append('| %s | %s | %s | %.1f |' % (p['role'], p['ns'] or '-', p['name'] or '-', p['pct']))
    figs = [f for f in live['drones'].values() if f]
    if figs:
        lines += ['', 'Drones during the window: RTF min %.3f, ground truth min %.1f Hz, mirror sent min %.1f Hz.'
                  % (min(f['rtf'] for f in figs), min(f['truth_hz'] for f in figs),
                     min(f['mirror_hz'] for f in figs))]
    lines += ['', '## 4. Where each percent goes (per drone, N = %d live)' % live['n'], '',
              'Each item: rate (measured live, per drone) x cost (sections 1-2); for a topic with subscribers, the '
              'publisher\'s serialize + send = (publisher per message with 1 subscriber) - (with none). '
              'Residual = measured - items: thread wake-ups and GIL hand-overs not itemised, timers, the '
              'telemetry reader thread, sockets of the rospy runs not seen in the cores. The world and the master '
              'are shared: their per-drone share is the total / N.', '']
    lines += _attribution_lines(data, live['n'], measured_per_drone(live))
    lines += ['', '## 5. The same items at N = %d (projected)' % PROJECT_N, '',
              'Rates as live; what grows with N: /gazebo/model_states (2N + 1 models, to every mirror at 100 Hz) '
              'and the world\'s cycle; the world\'s and the master\'s fixed costs spread over N. '
              'No measured column: projection only.', '']
    lines += _attribution_lines(data, PROJECT_N, None)
    total = sum(r[3] for rows in attribution(data, PROJECT_N).values() for r in rows)
    lines += ['', '## The cuts of a shared layout at N = %d, ranked' % PROJECT_N, '',
              'Each cut: the items of section 5 it removes (in-process delivery: no serialization, no send, no '
              'receive thread) or shares by the N drones of a process (one loop, one thread, one subscription: '
              'the item x (1 - 1/N)). Items total %.1f %% core per drone; the master\'s and roslaunch\'s share '
              'are not itemised.' % total, '',
              '| cut | % core per drone saved | items |', '|---|---|---|']
    left = total
    for name, saved, labels in sorted(cut_savings(data, PROJECT_N), key=lambda x: -x[1]):
        left -= saved
        lines.append('| %s | %.2f | %s |' % (name, saved, '; '.join(labels)))
    lines += ['', 'Left per drone after every cut above: %.1f %% core (items only).' % left]
    lines += ['', '## Largest items per drone at N = %d' % PROJECT_N, '']
    items = []
    for role, rows in attribution(data, PROJECT_N).items():
        for label, rate, us, pct in rows:
            items.append((pct, role, label))
    for pct, role, label in sorted(items, reverse=True)[:12]:
        lines.append('- %.2f %% core: %s -- %s' % (pct, role, label))
    return '\n'.join(lines) + '\n'


def _attribution_lines(data, n, measured):
    table = attribution(data, n)
    lines = ['| process | path item | rate [Hz] | us per event | % core per drone |', '|---|---|---|---|---|']
    total_items = total_measured = 0.0
    for role in ('simulator', 'telemetry CLI', 'interface', 'mirror', 'controller', 'generator', 'world'):
        rows = table[role]
        s = sum(r[3] for r in rows)
        total_items += s
        for label, rate, us, pct in rows:
            lines.append('| %s | %s | %.1f | %s | %s |' % (role, label, rate, _f(us), _f(pct, '%.2f')))
        if measured is not None:
            m = measured.get(role, 0.0)
            total_measured += m
            lines.append('| **%s** | **items %s, measured %s, residual %s** | | | |'
                         % (role, _f(s, '%.2f'), _f(m, '%.2f'), _f(m - s, '%.2f')))
        else:
            lines.append('| **%s** | **items %s** | | | |' % (role, _f(s, '%.2f')))
    if measured is not None:
        m = measured.get('master + rosout', 0.0) + measured.get('roslaunch', 0.0)
        total_measured += m
        lines.append('| **master + rosout + roslaunch** | **measured %s (not itemised)** | | | |' % _f(m, '%.2f'))
        lines.append('| **all** | **items %s, measured %s, residual %s** | | | |'
                     % (_f(total_items, '%.2f'), _f(total_measured, '%.2f'), _f(total_measured - total_items, '%.2f')))
    else:
        lines.append('| **all** | **items %s** | | | |' % _f(total_items, '%.2f'))
    return lines


# ============================================================================ main
def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument('--fleet-rate', type=float, default=100.0, help='Hz of the rospy runs at the fleet\'s rate')
    ap.add_argument('--rate', type=float, default=1000.0, help='Hz of the fast rospy runs')
    ap.add_argument('--window', type=float, default=5.0, help='s measured per rospy run')
    ap.add_argument('--lead', type=float, default=7.0, help='s for the workers to start before a window')
    ap.add_argument('--batch', type=int, default=6, help='rospy runs at a time')
    ap.add_argument('--idle-window', type=float, default=20.0)
    ap.add_argument('--settle', type=float, default=5.0)
    ap.add_argument('--rates-window', type=float, default=5.0)
    ap.add_argument('--live-window', type=float, default=20.0)
    ap.add_argument('--skip', nargs='*', default=[], choices=['rospy', 'live'], help='parts not run (tests)')
    ap.add_argument('--no-write', action='store_true')
    ap.add_argument('--from-json', action='store_true')
    # worker mode (this script started by itself)
    ap.add_argument('--worker', choices=['pub', 'sub', 'idle', 'sleep'])
    ap.add_argument('--type', choices=TYPES)
    ap.add_argument('--topic')
    ap.add_argument('--t-start', type=float)
    ap.add_argument('--t-end', type=float)
    ap.add_argument('--subs', type=int, default=1)
    ap.add_argument('--out')
    args = ap.parse_args(argv)
    if args.worker:
        {'pub': worker_pub, 'sub': worker_sub, 'idle': worker_idle, 'sleep': worker_sleep}[args.worker](args)
        return 0
    if args.from_json:
        with open(RESULTS_JSON) as f:
            data = json.load(f)
        _write_md(markdown(data))
        return 0
    import rospy
    t_begin = time.time()
    data = {'date': datetime.datetime.utcnow().strftime('%Y-%m-%d %H:%M UTC'), 'python': platform.python_version(),
            'cores': os.cpu_count() or 0, 'cpu_model': processes.cpu_model(), 'load': os.getloadavg(),
            'args': vars(args)}
    with tempfile.TemporaryDirectory(prefix='bench_fleet_profile_') as workdir:
        procs = processes.Processes(workdir, grace=20.0)
        try:
            uri, env = processes.private_master(procs, os.path.join(workdir, 'ros_home'),
                                                os.path.join(workdir, 'log'), MASTER_PORTS, join=True)
            port = int(uri.rsplit(':', 1)[1])
            rospy.init_node('bench_fleet_profile', anonymous=True, disable_signals=True)
            runner = Runner(procs, env, workdir)
            t_idle = time.time() + args.lead
            idle = runner.start('idle', 'rpyt', '/unused', t_idle, t_idle + args.idle_window)
            bare = runner.start('sleep', 'rpyt', '/unused', t_idle, t_idle + args.window, rate=args.fleet_rate)
            print('in-process costs ...', flush=True)
            data['messages'] = message_costs()
            data['core'] = core_costs()
            print(json.dumps(data['core'], indent=1), flush=True)
            got = runner.collect([idle, bare], args.lead + args.idle_window + 20.0)
            data['idle_pct'] = 100.0 * got[idle[0]]['cpu'] / got[idle[0]]['wall'] if got[idle[0]] else float('nan')
            data['bare_wake_us'] = per_message({'w': got[bare[0]]}, 'w')
            print('idle node: %.2f %% core' % data['idle_pct'], flush=True)
            data['rospy'] = rospy_runs(runner, args) if 'rospy' not in args.skip else {}
            if data['rospy']:
                for key, row in costs_table(data).items():
                    print('%-16s pub1 %7.1f  pub0 %7.1f  sub1 %7.1f us/msg' % (key, row['pub1'], row['pub0'],
                                                                           row['sub1']), flush=True)
            if 'live' not in args.skip:
                print('live fleet ...', flush=True)
                data['live'] = live_fleet(procs, env, port, workdir, args)
        finally:
            procs.stop_all()
    data['duration_s'] = time.time() - t_begin
    if not args.no_write:
        tmp = RESULTS_JSON + '.tmp'
        with open(tmp, 'w') as f:
            json.dump(data, f, indent=1, sort_keys=True)
        os.replace(tmp, RESULTS_JSON)
    if 'live' in data and data['rospy']:
        text = markdown(data)
        print(text)
        if not args.no_write:
            _write_md(text)
    return 0


def _write_md(text):
    tmp = RESULTS + '.tmp'
    with open(tmp, 'w') as f:
        f.write(text)
    os.replace(tmp, RESULTS)
    print('written %s' % RESULTS)


if __name__ == '__main__':
    sys.exit(main())
