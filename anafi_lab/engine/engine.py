"""In-process experiment engine: one experiment in one process on virtual time, with the cores the ROS graph
runs (pure, no ROS).

Stage: experiments. Reproduces experiment.launch without a ROS master, without a wall clock and without a
second implementation of anything: the simulated Anafi (``anafi_sim.sim.simulator.SimulatedAnafi`` on a
``SimClock``: model, estimate, bridge mapping), the ground-truth interface's decimation
(``anafi_sim.interface.ground_truth.GroundTruthInterface``), the trajectory generator
(``anafi_sim.mission.trajectory.TrajectoryGenerator``), the experiment monitor's hold-at-start and start
rule (``anafi_sim.mission.monitor.ExperimentMonitor``), the controller (any ``anafi_control.contract``
Controller as controller_node.py runs it; the paper's PID framework as its distributed graph: relative
state, six ``anafi_control.pid.PidController`` nodes, ``anafi_control.pid_wiring.CommandAssembler``) and the
evaluator (``anafi_sim.mission.evaluation.LiveEvaluator``: the summary schema evaluator.py writes).
The clockwork is ``anafi_lab.engine.event_loop``: integer nanoseconds, ROS timers on /clock ticks,
messages with transport delays.

``Engine(scenario, controller, seed=..., wind=..., ...).run()`` -> ``RunResult`` (summary dict as the
evaluator writes it, run figures, the Evaluation with its reference log). Bit-for-bit deterministic for a
given seed: the only randomness is the model's wind gusts (numpy Generator seeded with ``seed``, drawn once
per physics step, see ``anafi_sim.sim.drone_model``), events run in a fixed order, OSQP runs a fixed number
of iterations per rho update (no time limit, no time-based adaptation); wall-clock figures (solve times,
wall seconds) go to ``info`` only, never into the summary.

Schedule (``DEFAULT_SCHEDULE``; every entry is a parameter, ``Engine(schedule={...})``). Rates and periods
come from the configuration the launch files load; latencies are wall seconds of the ROS graph and become
simulation seconds times ``ros_rtf`` (the graph runs at that real-time factor, so 1 ms of wall is 2 ms of
simulation time at rtf 2); phases are the start times of the nodes' timers [s of simulation time]:

====================  ========  =============================================================================
key                   default   source
====================  ========  =============================================================================
physics_rate          200 Hz    anafi_sim/config/sim.yaml ``rate`` (anafi_sim_node.py)
telemetry_rate        100 Hz    sim.yaml ``telemetry_rate``: ground-truth samples to the interface
truth_rate            100 Hz    anafi_sim/config/interface.yaml ``rate``: ground_truth/odom
estimate_rate         30 Hz     sim.yaml ``estimate_publish_rate``: drone/odom (values change at the model's
                                ``estimate_rate``, 20 Hz, anafi_model.yaml)
generator_rate        10 Hz     trajectory_generator.py ``~rate``
hold_period           0.1 s     experiment_monitor.py: hold waypoint every 0.1 s of ROS time before the start
monitor_period        0.01 s    experiment_monitor.py: its loop sleeps 10 ms (wall) while holding
min_commands          5         experiment_monitor.py ``~min_commands``: engaged commands before the start
start_delay           0 s       extra simulation time before the monitor may start (the ROS graph also waits
                                for the evaluator's and recorder's subscriptions: 1-20 s in the committed
                                batch; it only lengthens the hover at the start point)
relative_state_rate   30 Hz     pid.launch ``pid_relative_state ~rate``
pid_command_rate      10 Hz     pid.launch ``pid_command ~rate``
effort_timeout        0.5 s     pid.launch ``pid_command ~effort_timeout``
state_timeout         0.5 s     mpc.launch / pid.launch ``state_timeout``
waypoint_timeout      1.0 s     mpc.launch / pid.launch ``waypoint_timeout``
ros_rtf               2         experiment.launch ``rtf`` (the committed ROS batch ran at 2)
message_latency       0.5 ms    wall, one TCPROS hop on loopback; the ROS runs' bags show every message
                                received within the /clock tick it was stamped in (5 ms of simulation)
clock_latency         0 ms      wall, /clock to a node (same bags: nodes read the newest tick)
mpc_latency           2.7 ms    wall, from the cycle's clock reading to the command leaving: median of
                                mpc_cycle_time_mean_ms over the committed batch's MPC runs
controller_latency    0 ms      wall, the same for any other controller of the contract (controller_node.py)
pid_coalesce          1 ms      wall, pid_controller.py ``COALESCE_WINDOW``: a loop computes 1 ms after the
                                message that woke it (messages within the window: one computation)
pid_latency           0 ms      wall, one pid computation (tens of microseconds)
controller_phase      0.030 s   controller_node.py's cycles (``~timer_phase``, clock.TIMER_PHASES: the node
                                aligns its timer to it; the MPC cycled at 30/35 ms past every 100 ms in a
                                recorded ROS run of circle_r1_v1 before the alignment)
generator_phase       0.080 s   the trajectory generator's ticks (``~timer_phase``, clock.TIMER_PHASES): the
                                waypoint is 50 ms old at the controller's cycle, the mean over a random phase
                                (before the nodes aligned their timers each ROS start-up drew one: 15 ms in a
                                recorded circle_r1_v1 run, 95 ms in one of straight_2). The MPC tracks the
                                waypoint as received (no extrapolation over its age), so on fast trajectories
                                e_mu moves with this phase (anafi_lab/sweeps/schedule_phases.yaml measures how
                                much)
relative_state_phase  0.0 s     pid_relative_state's timer (not recorded; its cycles then fall on the
                                estimate's ticks)
pid_command_phase     0.0 s     pid_command's timer: commands at 0/5 ms past every 100 ms in a recorded ROS
                                run of circle_r1_v1 (distributed PID)
preview_horizon       3.0 s     trajectory_generator.py ``~preview_horizon``: the preview (command/trajectory)
                                published with every waypoint when a PREVIEW controller (preview_mpc) listens
preview_step          0.05 s    trajectory_generator.py ``~preview_step``: its sample spacing
====================  ========  =============================================================================

Known simplifications (numbers that round away in the summaries): the ground truth and estimate reach the
evaluator as numbers, not through the telemetry text (9 significant digits) and nav_msgs/Odometry round
trips; /clock ticks are exact multiples of the physics period (rospy.Time.from_sec may truncate one
nanosecond); a node's callbacks never wait for another callback's lock.
"""
import collections
import copy
import importlib
import math
import os
import time

from anafi_control import registry
from anafi_control.contract import NODE_KEYS, Controller, InputGate
from anafi_control.mpc_tracking import DEFAULTS as MPC_TRACKING_DEFAULTS, PARAM_NAMES as MPC_PARAM_NAMES, \
    TRACKING_KEYS as MPC_TRACKING_KEYS, MpcTracking
from anafi_control.pid import PidController
from anafi_control.pid_framework import LOOP_NAMES, make_config, relative_state
from anafi_control.preview_mpc import DEFAULTS as PREVIEW_DEFAULTS, PredictionModel
from anafi_control.pid_wiring import COMMAND_LOOPS, CommandAssembler, input_topics, loop_inputs, loop_topics
from anafi_sim import names, paths, run_files
from anafi_sim.mission.evaluation import LiveEvaluator
from anafi_sim.mission.monitor import ExperimentMonitor
from anafi_lab.engine.event_loop import ACTION, PHYSICS, TIMER, EventLoop, NodeClock, Timer, Topic, to_ns, to_s
from anafi_sim.mission.trajectory import Scenario, load_scenario, scenario_path
from anafi_sim.mission.generator import DONE, TrajectoryGenerator
from anafi_sim.interface.ground_truth import GroundTruthInterface, odometry
from anafi_sim.sim.bridge import MAX_TILT_DEG, MAX_VERTICAL_SPEED, MAX_YAW_RATE_DEG, PilotingMapping
from anafi_sim.sim.clock import TIMER_PHASES, SimClock
from anafi_sim.sim.conditions_profile import load_conditions
from anafi_sim.sim.drone_model import DEFAULT_MODEL_FILE, DEFAULT_SETTINGS, AnafiModel, load_model_params
from anafi_sim.sim.simulator import SimulatedAnafi
from anafi_sim.sim.state_estimate import StateEstimate

try:        # the flight envelope of the controller contract (geofence, reach, speeds, tilt), where it has one
    from anafi_control.contract import LIMIT_DEFAULTS, Envelope
except ImportError:     # pragma: no cover - a contract without an envelope
    LIMIT_DEFAULTS, Envelope = {}, None

#: the schedule of the ROS graph (see the module doc for the source of every default)
DEFAULT_SCHEDULE = collections.OrderedDict([
    ('physics_rate', 200.0), ('telemetry_rate', 100.0), ('truth_rate', 100.0), ('estimate_rate', 30.0),
    ('generator_rate', 10.0), ('hold_period', 0.1), ('monitor_period', 0.01), ('min_commands', 5),
    ('start_delay', 0.0), ('relative_state_rate', 30.0), ('pid_command_rate', 10.0), ('effort_timeout', 0.5),
    ('state_timeout', 0.5), ('waypoint_timeout', 1.0),
    ('ros_rtf', 2.0), ('message_latency', 0.0005), ('clock_latency', 0.0), ('mpc_latency', 0.0027),
    ('controller_latency', 0.0), ('pid_coalesce', 0.001), ('pid_latency', 0.0),
    ('controller_phase', TIMER_PHASES['controller']), ('generator_phase', TIMER_PHASES['generator']),
    ('relative_state_phase', 0.0),
    ('pid_command_phase', 0.0), ('preview_horizon', 3.0), ('preview_step', 0.05),
])
#: schedule keys in wall seconds of the ROS graph (times ``ros_rtf`` = simulation seconds)
WALL_KEYS = ('monitor_period', 'message_latency', 'clock_latency', 'mpc_latency', 'controller_latency',
             'pid_coalesce', 'pid_latency')
_RATE_KEYS = ('physics_rate', 'telemetry_rate', 'truth_rate', 'estimate_rate', 'generator_rate',
              'relative_state_rate', 'pid_command_rate')

#: the wind's simulator settings (anafi_sim/config/sim.yaml, the flight-conditions profiles): one vocabulary for a
#: wind spec (``Engine(wind={...})``, a sweep's ``wind:``) and a sweep's CSV columns
WIND_KEYS = ('wind_x', 'wind_y', 'wind_z', 'gust_std_horizontal', 'gust_std_vertical', 'gust_time_constant')

Odom = collections.namedtuple('Odom', 'stamp position orientation twist')
"""A nav_msgs/Odometry in numbers: stamp [s], position [m], orientation (x, y, z, w), linear twist [m/s] in
the child (body) frame."""
Stamped = collections.namedtuple('Stamped', 'stamp values')
# a contract controller's command: ``ok`` False = a failsafe output (the monitor's hover commands)
Command = collections.namedtuple('Command', 'stamp values ok')
"""A stamped message: stamp [s], values (a waypoint's 7 numbers, a command's 4)."""

RunResult = collections.namedtuple('RunResult', 'name ok error summary info evaluation')
RunResult.__doc__ = ('One run: name, ok (final summary), error (why not), summary (the evaluator\'s dict, state '
                     '\'final\' or \'incomplete\'), info (run figures), evaluation (Evaluation or None).')

_FILES = {}


def _file_once(path, load, *args):
    """``load(*args)`` of the file ``path`` once per process while the file stays as it was (its modification
    time and size); a deep copy every call (a batch's workers run many engines: they parse each configuration,
    scenario and model file once). A file that cannot be read is not kept: ``load`` raises as it would."""
    try:
        st = os.stat(path)
        key = (os.path.abspath(path), load, repr(args), st.st_mtime_ns, st.st_size)
    except (OSError, TypeError, ValueError):
        return load(*args)
    if key not in _FILES:
        _FILES[key] = load(*args)
    return copy.deepcopy(_FILES[key])



def make_schedule(overrides=None):
    """DEFAULT_SCHEDULE updated with ``overrides`` (unknown keys and bad values raise ValueError)."""
    schedule = collections.OrderedDict(DEFAULT_SCHEDULE)
    for key, value in dict(overrides or {}).items():
        if key not in schedule:
            raise ValueError('unknown schedule parameter %r (known: %s)' % (key, ', '.join(schedule)))
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
            raise ValueError('schedule parameter %s must be a finite number, got %r' % (key, value))
        schedule[key] = value
    for key in _RATE_KEYS + ('preview_step', 'hold_period', 'monitor_period', 'ros_rtf', 'state_timeout', 'effort_timeout'):
        if not schedule[key] > 0:
            raise ValueError('schedule parameter %s must be > 0, got %r' % (key, schedule[key]))
    for key in schedule:
        if schedule[key] < 0:
            raise ValueError('schedule parameter %s must be >= 0, got %r' % (key, schedule[key]))
    if int(schedule['min_commands']) != schedule['min_commands']:
        raise ValueError('min_commands must be an integer, got %r' % (schedule['min_commands'],))
    return schedule


def wind_settings(wind):
    """Simulator settings of a wind spec: None, or {wind_x, wind_y, wind_z [m/s], gust_std_horizontal,
    gust_std_vertical [m/s std], gust_time_constant [s]} (the settings' own names; missing keys: sim.yaml's values)."""
    if not wind:
        return {}
    if not isinstance(wind, dict):
        raise ValueError('wind must be a mapping with keys %s, got %r' % (', '.join(WIND_KEYS), wind))
    unknown = sorted(set(wind) - set(WIND_KEYS))
    if unknown:
        raise ValueError('unknown wind key(s) %s (known: %s)' % (', '.join(unknown), ', '.join(WIND_KEYS)))
    return dict((k, float(v)) for k, v in wind.items())


def simulator_config(settings=None):
    """(mapping kwargs, model settings, seed) as anafi_sim_node.py reads anafi_sim/config/sim.yaml, with
    ``settings`` (keys of DEFAULT_SETTINGS) overriding the file."""
    path = paths.config_path('sim.yaml')
    config = _file_once(path, run_files.read_yaml, path, {})
    mapping = dict(max_tilt_deg=float(config.get('max_tilt_deg', MAX_TILT_DEG)),
                   max_vertical_speed=float(config.get('max_vertical_speed', MAX_VERTICAL_SPEED)),
                   max_yaw_rate_deg=float(config.get('max_yaw_rate_deg', MAX_YAW_RATE_DEG)))
    model_settings = dict((k, float(config.get(k, v))) for k, v in DEFAULT_SETTINGS.items())
    for key, value in dict(settings or {}).items():
        if key not in DEFAULT_SETTINGS:
            raise ValueError('unknown simulator setting %r (known: %s)' % (key, ', '.join(sorted(DEFAULT_SETTINGS))))
        model_settings[key] = float(value)
    return mapping, model_settings, int(config.get('seed', 0))


def waypoint_limits(config):
    """{'limits': the flight envelope (contract.Envelope)} of a node's parameters (the keys of
    contract.LIMIT_DEFAULTS), as anafi_sim.ros.conversions.waypoint_limits reads them; {} where the contract
    has no envelope."""
    if Envelope is None:
        return {}
    return {'limits': Envelope(**dict((k, config.get(k, v)) for k, v in LIMIT_DEFAULTS.items()))}


def controller_config(name, overrides=None):
    """The parameters of the registered controller ``name`` as its launch file loads them (its YAML under
    anafi_sim/config/, anafi_control.registry) with ``overrides`` on top; keys neither its core reads
    (``CONFIG_KEYS``) nor the node's wiring (contract.NODE_KEYS) raise ValueError."""
    entry = registry.get(name)
    path = paths.config_path(entry.config)
    config = _file_once(path, run_files.read_yaml, path, {})
    config.update(dict(overrides or {}))
    unknown = sorted(k for k in config if k not in entry.core_class().CONFIG_KEYS and k not in NODE_KEYS)
    if unknown:
        raise ValueError('unknown %s parameter(s) %s' % (name, ', '.join(unknown)))
    return config


def mpc_config(overrides=None):
    """The MPC node's parameters as mpc.launch loads them (anafi_sim/config/mpc.yaml) with ``overrides``:
    (flat MPC params, yaw config or None, tracking kwargs, rate [Hz])."""
    config = controller_config('mpc', overrides)
    params = dict((k, config[k]) for k in MPC_PARAM_NAMES if k in config)
    kwargs = dict((k, config.get(k, MPC_TRACKING_DEFAULTS[k])) for k in MPC_TRACKING_KEYS)
    kwargs.update(waypoint_limits(config))
    return params, config.get('yaw'), kwargs, float(config.get('rate', MPC_TRACKING_DEFAULTS['rate']))


def pid_config(overrides=None):
    """The PID framework's parameters as pid.launch loads them (anafi_sim/config/pid.yaml) with ``overrides``
    ({loop: {param: value}}, or top-level keys such as the waypoint limits): (loops config validated by
    ``anafi_control.pid_framework.make_config``, limits kwargs for the node that gates the inputs)."""
    path = paths.config_path('pid.yaml')
    config = _file_once(path, run_files.read_yaml, path, {})
    for key, value in dict(overrides or {}).items():
        if key in LOOP_NAMES:
            if not isinstance(value, dict):
                raise ValueError('PID loop overrides must be {loop: {param: value}}, got %r for %r' % (value, key))
            config.setdefault(key, {}).update(value)
        elif key in LIMIT_DEFAULTS:
            config[key] = value
        else:
            raise ValueError('unknown PID parameter %r (loops: %s; limits: %s)'
                             % (key, ', '.join(LOOP_NAMES), ', '.join(LIMIT_DEFAULTS) or 'none'))
    loops = dict((k, v) for k, v in config.items() if k in LOOP_NAMES)
    return make_config(loops), waypoint_limits(config)


def preview_config(overrides=None):
    """The preview MPC's parameters as experiment.launch loads them (anafi_sim/config/preview_mpc.yaml) with
    ``overrides``: (params for anafi_control.preview_mpc.PreviewMpc, limits kwargs)."""
    config = controller_config('preview_mpc', overrides)
    params = dict((k, v) for k, v in config.items() if k in PREVIEW_DEFAULTS and k not in LIMIT_DEFAULTS)
    return params, waypoint_limits(config)


# engine adapters by kind (a registry entry's ``engine``): (entry, overrides, model_params, mapping) -> a
# no-argument callable building the core with its ``from_config`` over its YAML (the node's reader too)
def _contract_factory(entry, params, model_params, mapping):
    """Any controller of the contract: its YAML + ``params``."""
    config, cls = controller_config(entry.name, params), entry.core_class()
    return lambda: cls.from_config(config)


def _pid_factory(entry, params, model_params, mapping):
    """The PID framework in one node: pid.yaml + ``params`` merged per loop (``pid_config``)."""
    loops, limits = pid_config(params)
    cls = entry.core_class()
    return lambda: cls.from_config(loops, **limits)


def _preview_factory(entry, params, model_params, mapping):
    """The preview MPC: its YAML + ``params``, the prediction model of ``model_params`` (anafi_model.yaml
    dict) and the bridge limits ``mapping`` (PilotingMapping kwargs)."""
    config, cls = controller_config(entry.name, params), entry.core_class()
    model = PredictionModel.from_params(model_params, mapping['max_tilt_deg'], mapping['max_vertical_speed'],
                                        mapping['max_yaw_rate_deg'])
    return lambda: cls.from_config(config, model=model)


#: engine adapters by kind (``pid_graph``: the distributed PID graph, wired by the Engine itself)
ENGINE_ADAPTERS = {registry.GENERIC: _contract_factory, 'pid_loops': _pid_factory, 'preview_model': _preview_factory,
                   'pid_graph': None}


def controller_factory(kind, params=None, model_params=None, mapping=None):
    """A no-argument callable building the contract.Controller ``kind`` (a name of anafi_control.registry run
    by one node, with its YAML and ``params``; or 'package.module:Class', built with ``params`` as keyword
    arguments). ``model_params`` / ``mapping``: the model and bridge limits of a controller that predicts
    with them (default anafi_model.yaml and sim.yaml's)."""
    params = dict(params or {})
    if isinstance(kind, str) and ':' in kind:
        module, _, name = kind.partition(':')
        cls = getattr(importlib.import_module(module), name)
        if not (isinstance(cls, type) and issubclass(cls, Controller)):
            raise ValueError('%s is not an anafi_control.contract.Controller subclass' % kind)
        return lambda: cls(**params)
    entry = registry.get(kind)
    adapter = ENGINE_ADAPTERS[entry.engine]
    if adapter is None:
        raise ValueError('controller %r is not one node (the engine wires it itself)' % kind)
    return adapter(entry, params, load_model_params() if model_params is None else model_params,
                   simulator_config()[0] if mapping is None else mapping)


class _Timing(object):
    """Wall seconds spent in the callbacks of one group of nodes (e.g. the controller's)."""

    def __init__(self):
        self.seconds = 0.0

    def wrap(self, callback):
        clock = time.perf_counter

        def timed(*args):
            t0 = clock()
            try:
                return callback(*args)
            finally:
                self.seconds += clock() - t0
        return timed


class World(object):
    """The shared pieces: event loop, node clock, topics by name, latencies [ns]."""

    def __init__(self, schedule):
        self.schedule = s = schedule
        self.loop = EventLoop()
        rtf = float(s['ros_rtf'])
        self.physics_period = to_ns(1.0 / s['physics_rate'])
        self.clock = NodeClock(self.loop, self.physics_period, to_ns(s['clock_latency'] * rtf))
        self.delay = to_ns(s['message_latency'] * rtf)
        self.latency = dict((k, to_ns(s[k] * rtf)) for k in WALL_KEYS)
        self.topics = {}

    def topic(self, name):
        topic = self.topics.get(name)
        if topic is None:
            topic = self.topics[name] = Topic(self.loop, name)
        return topic

    def timer(self, rate_or_period, callback, phase=0.0, first=1, order=TIMER, period=False):
        value = float(rate_or_period)
        return Timer(self.loop, self.clock, to_ns(value if period else 1.0 / value), callback,
                     start=to_ns(phase), first=first, order=order)


# ----------------------------------------------------------------------------------------------- nodes
class ControllerNode(object):
    """controller_node.py: any contract.Controller on ``state_topic`` and the waypoint; ``cycle`` every
    1/rate s, the command every cycle or every 1/command_rate s; commands leave ``latency`` ns after the
    cycle read the clock."""

    def __init__(self, world, core, rate, state_topic, phase, latency, timing, command_rate=None):
        self.world, self.core = world, core
        self.latency = latency
        self.command = world.topic(names.COMMAND)
        self.solve_times = []
        self.silent = 0           # command periods without a command (failsafe SILENT, warming up)
        world.topic(state_topic).subscribe(timing.wrap(self._on_state), world.delay)
        world.topic(names.WAYPOINT).subscribe(timing.wrap(self._on_waypoint), world.delay)
        if getattr(core, 'PREVIEW', False):
            world.topic(names.REFERENCE_PREVIEW).subscribe(timing.wrap(self._on_reference), world.delay)
        world.timer(rate, timing.wrap(self._on_cycle), phase)
        self.command_rate = command_rate
        if command_rate is not None:
            world.timer(command_rate, timing.wrap(self._on_command), phase)

    def _on_state(self, msg):
        self.core.on_state(self.world.clock.now_s(), msg.position, msg.orientation, msg.twist)

    def _on_waypoint(self, msg):
        self.core.on_waypoint(self.world.clock.now_s(), msg.values)

    def _on_reference(self, msg):
        self.core.on_reference(self.world.clock.now_s(), msg.values)

    def _on_cycle(self, now):
        out = self.core.cycle(to_s(now))
        result = out.result
        solve_time = getattr(result, 'solve_time', None)
        if solve_time is not None and math.isfinite(solve_time):
            self.solve_times.append(solve_time)
        if self.command_rate is None:
            self._publish(now, out.command, out.ok)

    def _on_command(self, now):
        self._publish(now, self.core.last.command, self.core.last.ok)

    def _publish(self, now, command, ok=True):
        if command is None:       # nothing to send: the firmware's hover brake acts
            self.silent += 1
            return
        self.command.publish(Command(to_s(now), tuple(command), bool(ok)), self.latency)


class RelativeStateNode(object):
    """pid_relative_state.py: the input gate and the relative state every 1/rate s -> the loops' setpoint /
    state topics (anafi_control.pid_wiring.LOOP_INPUTS), pid_enable false while gated (latched, from the
    start)."""

    def __init__(self, world, state_topic, rate, phase, timing, limits):
        s = world.schedule
        self.world = world
        self.gate = InputGate(s['state_timeout'], s['waypoint_timeout'], **limits)
        self.pubs = dict((name, world.topic(names.pid_topic(name))) for name in input_topics())
        self.enable = world.topic(names.pid_topic(names.PID_ENABLE))
        self.enabled = None
        self.published_cycles = 0
        self._set_enabled(False)
        world.topic(state_topic).subscribe(timing.wrap(self._on_state), world.delay)
        world.topic(names.WAYPOINT).subscribe(timing.wrap(self._on_waypoint), world.delay)
        world.timer(rate, timing.wrap(self._on_timer), phase)

    def _set_enabled(self, enabled):
        if enabled != self.enabled:
            self.enabled = enabled
            self.enable.publish(enabled)

    def _on_state(self, msg):
        self.gate.on_state(self.world.clock.now_s(), msg.position, msg.orientation, msg.twist)

    def _on_waypoint(self, msg):
        self.gate.on_waypoint(self.world.clock.now_s(), msg.values)

    def _on_timer(self, now):
        inputs, key, _ = self.gate.check(to_s(now))
        rel = None if inputs is None else relative_state(inputs.pos, inputs.vel, inputs.yaw, inputs.waypoint)
        self.gate.count_cycle(key)
        if rel is None:
            self._set_enabled(False)
            return
        self._set_enabled(True)
        for topic, value in loop_inputs(rel):
            self.pubs[topic].publish(value)
        self.published_cycles += 1


class PidLoopNode(object):
    """pid_controller.py (the pid package's controller): one computation ``coalesce`` ns after the message
    that woke it (state or setpoint, once both arrived), effort published ``latency`` ns later."""

    def __init__(self, world, loop, config, timing):
        self.world = world
        self.pid = PidController(**config)
        topics = loop_topics(loop)
        self.effort = world.topic(names.pid_topic(topics['topic_from_controller']))
        self.coalesce = world.latency['pid_coalesce']
        self.latency = world.latency['pid_latency']
        self.state = self.setpoint = None
        self.pending = self.scheduled = False
        self.computations = 0
        self._compute_timed = timing.wrap(self._compute)
        world.topic(names.pid_topic(topics['topic_from_plant'])).subscribe(timing.wrap(self._on_state), world.delay)
        world.topic(names.pid_topic(topics['setpoint_topic'])).subscribe(timing.wrap(self._on_setpoint), world.delay)
        world.topic(names.pid_topic(topics['pid_enable_topic'])).subscribe(timing.wrap(self.pid.set_enabled), world.delay)

    def _on_state(self, value):
        self.state = value
        self._mark()

    def _on_setpoint(self, value):
        self.setpoint = value
        self._mark()

    def _mark(self):
        if self.state is not None and self.setpoint is not None:
            self.pending = True
            if not self.scheduled:
                self.scheduled = True
                self.world.loop.after(self.coalesce, self._compute_timed)

    def _compute(self):
        self.scheduled = False
        if not self.pending:
            return
        self.pending = False
        now = self.world.clock.now_s()
        if now <= 0.0:
            return
        effort = self.pid.update(self.setpoint, self.state, now)
        self.computations += 1
        if effort is not None:
            self.effort.publish(effort, self.latency)


class PidCommandNode(object):
    """pid_command.py: the four command loops' efforts -> one PilotingCommand every 1/rate s."""

    def __init__(self, world, rate, phase, timing):
        self.world = world
        self.assembler = CommandAssembler(world.schedule['effort_timeout'])
        self.command = world.topic(names.COMMAND)
        for field, loop in COMMAND_LOOPS.items():
            world.topic(names.pid_topic('%s/control_effort' % loop)).subscribe(
                timing.wrap(lambda value, field=field: self.assembler.on_effort(field, self.world.clock.now_s(),
                                                                                value)), world.delay)
        world.topic(names.pid_topic(names.PID_ENABLE)).subscribe(timing.wrap(self.assembler.on_enable), world.delay)
        world.timer(rate, timing.wrap(self._on_timer), phase)

    def _on_timer(self, now):
        cmd, _ = self.assembler.command(to_s(now))
        if cmd is not None:       # None: no command, the firmware's hover brake acts
            self.command.publish(Stamped(to_s(now), tuple(cmd)))


# ----------------------------------------------------------------------------------------------- engine
class Engine(object):
    """One experiment (see the module doc).

    scenario: a ``Scenario``, a scenario name or a YAML path; controller: a name of anafi_control.registry
    ('mpc', 'pid' (distributed graph), 'pid_single', 'preview_mpc', ...: its YAML), 'package.module:Class'
    (a contract.Controller built with ``controller_params``
    as keyword arguments) or a no-argument callable returning a Controller; controller_params: its YAML's keys
    (mpc -> mpc.yaml keys, preview_mpc -> preview_mpc.yaml keys),
    pid / pid_single -> {loop: {pid param: value}}; seed: wind-gust seed (sim.yaml ``seed``: 0); wind: see
    ``wind_settings``; settings: more simulator settings (sim.yaml keys of the model); schedule: overrides of
    DEFAULT_SCHEDULE; model_params: the model dict (default anafi_model.yaml); state_source: 'estimate'
    (drone/odom, the paper) or 'truth' (ground_truth/odom); name: the run's name (default
    SCENARIO_CONTROLLER); max_sim_time: give up after this many simulated seconds (default: the scenario's
    duration + 120 s); actions: [(s > 0 after the scenario's start, fn(engine))], called at those simulated
    times before the physics step of that instant, whose state then shows the action (e.g. the fidelity
    replay's initial state, ``anafi_lab.engine.replay``); conditions: a flight-conditions profile NAME or
    PATH (``anafi_sim.sim.conditions_profile``: wind, gusts, the firmware's wind handling) under ``settings``
    and ``wind`` (None: sim.yaml as it is).
    """

    def __init__(self, scenario, controller='mpc', seed=None, wind=None, settings=None, controller_params=None,
                 schedule=None, model_params=None, state_source='estimate', name=None, max_sim_time=None,
                 actions=None, conditions=None):
        self.scenario = scenario if isinstance(scenario, Scenario) else \
            _file_once(scenario_path(str(scenario)), load_scenario, scenario)
        self.controller = controller
        label = controller if isinstance(controller, str) else getattr(controller, '__name__', 'controller')
        self.name = name or '%s_%s' % (self.scenario.name, label.split(':')[-1])
        self.schedule = make_schedule(schedule)
        self.conditions = conditions or None
        sim_settings = dict(load_conditions(conditions))
        sim_settings.update(settings or {})
        sim_settings.update(wind_settings(wind))
        self.mapping, self.settings, default_seed = simulator_config(sim_settings)
        self.seed = default_seed if seed is None else int(seed)
        self.wind = dict(wind or {})
        self.model_params = model_params if model_params is not None else \
            _file_once(DEFAULT_MODEL_FILE, load_model_params)
        if state_source not in ('estimate', 'truth'):
            raise ValueError("state_source must be 'estimate' or 'truth', got %r" % (state_source,))
        self.state_topic = names.ESTIMATE if state_source == 'estimate' else names.GROUND_TRUTH
        self.controller_params = controller_params
        if callable(controller) and not isinstance(controller, str):
            self._factory = controller
        elif isinstance(controller, str) and ':' not in controller and registry.get(controller).engine == 'pid_graph':
            self._factory = None
            self.pid_loops, self.pid_limits = pid_config(controller_params)
        else:
            self._factory = controller_factory(controller, controller_params, self.model_params, self.mapping)
        self.max_sim_time = float(max_sim_time) if max_sim_time is not None else self.scenario.duration + 120.0
        self.actions = []
        for offset, action in actions or ():
            offset = float(offset)
            if not (math.isfinite(offset) and offset > 0.0) or not callable(action):
                raise ValueError('actions: (seconds > 0 after the start, callable), got %r' % ((offset, action),))
            self.actions.append((offset, action))

    # ------------------------------------------------------------------------------------------ wiring
    def _build(self):
        s = self.schedule
        w = self.world = World(s)
        self.timing = _Timing()
        # the simulated Anafi (anafi_sim_node.py) and the interface's ground truth (interface_node.py)
        model = AnafiModel(self.model_params, mapping=PilotingMapping(**self.mapping), seed=self.seed,
                           settings=self.settings)
        self.sim = SimulatedAnafi(model, StateEstimate(model.params),
                                  SimClock(s['physics_rate'], 1.0, s['telemetry_rate'], s['estimate_rate']),
                                  server=None, auto_takeoff=True)
        self.interface = GroundTruthInterface(publish_rate=s['truth_rate'])
        self.estimate_topic = w.topic(names.ESTIMATE)
        self.truth_topic = w.topic(names.GROUND_TRUTH)
        self.state_out = w.topic(names.DRONE_STATE)
        self.waypoint_topic = w.topic(names.WAYPOINT)
        self.command_topic = w.topic(names.COMMAND)
        self.command_topic.subscribe(self._sim_command, w.delay)
        # the evaluator (evaluator.py), a recorder: stamps only
        self.evaluator = LiveEvaluator(name=self.name)
        self.t_end_ns = None
        self.waypoint_topic.subscribe(lambda m: self.evaluator.add_waypoint(m.stamp, m.values))
        # the monitor (experiment_monitor.py): hold at the start, the start rule, command figures
        self.monitor = ExperimentMonitor(self.scenario.duration, min_commands=int(s['min_commands']),
                                         ready_timeout=self.max_sim_time, end_margin=self.max_sim_time)
        self.state_out.subscribe(self.monitor.on_drone_state)
        self.command_topic.subscribe(lambda m: self.monitor.on_command(m.values, m.stamp,
                                                                       hover=(not m.ok) if hasattr(m, 'ok') else None))
        self.start_topic = w.topic(names.TRAJECTORY_COMMAND)
        self.reference_topic = w.topic(names.REFERENCE_PREVIEW)   # the generator's preview (PREVIEW controllers)
        self.hold = self.scenario.waypoint(0.0)
        self.last_hold = None
        w.timer(s['monitor_period'] * s['ros_rtf'], self._monitor_tick, period=True)
        # the trajectory generator (trajectory_generator.py): a Rate loop, first tick at its start
        self.generator = TrajectoryGenerator(self.scenario, hold_when_idle=True)
        self.generator_drone_state = ''
        self.pending_start = False
        self.started_at = None
        self.cpu_span = [0.0, None]      # controller callback seconds at the start and at the end
        self.state_out.subscribe(self._generator_state, w.delay)
        self.start_topic.subscribe(self._generator_command, w.delay)
        w.timer(s['generator_rate'], self._generator_tick, s['generator_phase'], first=0)
        # the controller
        self.controller_node = None
        if self._factory is None:
            self.relative_state = RelativeStateNode(w, self.state_topic, s['relative_state_rate'],
                                                    s['relative_state_phase'], self.timing, self.pid_limits)
            self.loops = [PidLoopNode(w, loop, self.pid_loops[loop], self.timing) for loop in LOOP_NAMES]
            PidCommandNode(w, s['pid_command_rate'], s['pid_command_phase'], self.timing)
        else:
            core = self._factory()
            if not isinstance(core, Controller):
                raise ValueError('the controller factory returned %r, not a contract.Controller' % (core,))
            latency = w.latency['mpc_latency' if isinstance(core, MpcTracking) else 'controller_latency']
            rate = core.RATE    # PreviewMpc: its params' rate (an instance attribute)
            if isinstance(core, MpcTracking):
                rate = mpc_config(self.controller_params)[3]
            self.controller_node = ControllerNode(w, core, rate, self.state_topic, s['controller_phase'], latency,
                                                  self.timing, core.COMMAND_RATE)
        # physics: one event per step, first at t = 1/rate (the step from 0)
        self.sim.start(0.0)
        w.loop.at(w.physics_period, self._physics, order=PHYSICS)
        self.failed = None

    # ------------------------------------------------------------------------------------------ simulator
    def _physics(self):
        w = self.world
        step = self.sim.step()
        t = step.t
        sample = step.sample
        if sample is not None and self.interface.on_sample(sample, t) is not None:
            truth = (sample.x, sample.y, sample.z, sample.vx, sample.vy, sample.vz, sample.roll, sample.pitch,
                     sample.yaw)
            self.evaluator.add_truth(t, truth)
            if self.truth_topic.subscribers:
                o = odometry(sample)
                self.truth_topic.publish(Odom(t, o.position, o.orientation, o.linear))
        estimate = step.estimate
        if estimate is not None:
            self.evaluator.add_estimate(t, self.sim.estimate.values())
            self.estimate_topic.publish(Odom(t, estimate.position, estimate.orientation, estimate.body_velocity))
            if self.t_end_ns is not None and self.evaluator.complete():
                w.loop.stop()                   # the evaluator is complete: an estimate at or after the end
        if step.state is not None:
            self.state_out.publish(step.state)
        w.loop.at(w.loop.now + w.physics_period, self._physics, order=PHYSICS)

    def _sim_command(self, msg):
        self.sim.on_command(*msg.values)

    # ------------------------------------------------------------------------------------------ monitor
    def _monitor_tick(self, now):
        t = to_s(now)
        for action, text in self.monitor.tick(t, t, t >= self.schedule['start_delay']):
            if action == 'start':
                self.start_topic.publish('start')
            elif action == 'fail':
                self.failed = text
                self.world.loop.stop()
        if self.monitor.holding and now > 0 and (self.last_hold is None or
                                                 now - self.last_hold >= to_ns(self.schedule['hold_period'])):
            self.last_hold = now
            wp = self.hold
            self.waypoint_topic.publish(Stamped(t, (wp.x, wp.y, wp.z, 0.0, 0.0, 0.0, wp.yaw)))

    # ------------------------------------------------------------------------------------------ generator
    def _generator_state(self, state):
        self.generator_drone_state = state

    def _generator_command(self, text):
        if text == 'start':
            self.pending_start = True

    def _generator_tick(self, now):
        t = to_s(now)
        gen = self.generator
        if self.pending_start and self.generator_drone_state == 'flying':
            self.pending_start = False
            self.started_at = t
            self.cpu_span = [self.timing.seconds, None]
            gen.start(t)
            for offset, action in self.actions:
                self.world.loop.at(max(self.world.loop.now, to_ns(t + offset)), action, self, order=ACTION)
        wp, events = gen.update(t)
        for ev in events:
            if ev.kind == 'begin':
                self.evaluator.begin(ev.time)
                self.monitor.on_begin(ev.time)
            elif ev.kind == 'end':
                self.evaluator.end(ev.time)
                self.monitor.on_end(ev.time, t)
                self.t_end_ns = to_ns(ev.time)
                self.cpu_span[1] = self.timing.seconds
        if wp is not None:
            self.waypoint_topic.publish(Stamped(t, tuple(wp)))
            if self.reference_topic.subscribers:    # a controller that takes a preview listens
                self.reference_topic.publish(Stamped(t, gen.preview(t, self.schedule['preview_horizon'],
                                                                    self.schedule['preview_step'])))
        if gen.state == DONE and self.evaluator.complete():
            self.world.loop.stop()

    # ------------------------------------------------------------------------------------------ run
    def run(self):
        """Run the experiment; returns the ``RunResult``."""
        wall0 = time.perf_counter()
        self._build()
        loop = self.world.loop
        limit = to_ns(self.max_sim_time)
        while True:
            stopped = loop.run(until=limit)
            if not stopped or self.failed or self.evaluator.complete():
                break
        wall = time.perf_counter() - wall0
        complete = self.evaluator.complete() and not self.failed
        error = ''
        if not complete:
            error = self.failed or ('the measured segment did not end within %.0f s of simulation time'
                                    % self.max_sim_time)
        result = self.evaluator.evaluate(to_s(loop.now))
        if result is None:
            summary = {'name': self.name, 'state': 'incomplete', 'samples': 0, 'counts': self.evaluator.counts()}
        else:
            summary = result.as_dict()
            summary['state'] = 'final' if complete else 'incomplete'
        return RunResult(self.name, complete, error, summary, self._info(wall), result)

    def _info(self, wall):
        """Run figures (like the monitor's run.yaml where they apply); wall-clock ones are not deterministic."""
        m = self.monitor
        sim_s = to_s(self.world.loop.now)
        scenario_sim = (m.ros_end - m.ros_start) if m.ros_start is not None and m.ros_end is not None else None
        solve = self.controller_node.solve_times if self.controller_node is not None else []

        def r(v, n=4):
            return None if v is None or not math.isfinite(v) else round(float(v), n)
        cpu = self.timing.seconds if self.cpu_span[1] is None else self.cpu_span[1] - self.cpu_span[0]
        info = dict([
            ('engine', 'inprocess'), ('state', 'final' if self.evaluator.complete() and not self.failed
                                      else 'failed'),
            ('reason', self.failed or ''), ('seed', self.seed), ('wind', dict(self.wind)),
            ('conditions', self.conditions),
            ('startup_sim_s', r(self.started_at, 3)), ('sim_s', r(sim_s, 3)),
            ('scenario_sim_s', r(scenario_sim, 3)), ('wall_s', r(wall, 3)),
            ('achieved_rtf', r(sim_s / wall if wall > 0 else None, 2)),
            ('events', self.world.loop.events), ('physics_steps', self.sim.clock.k),
            ('scenario_commands', m.scenario_commands), ('hover_commands', m.hover_commands),
            ('max_command_gap_s', r(m.max_command_gap, 3)), ('disturbed', m.disturbed()),
            ('controller_cpu_s', r(cpu, 3)),
            ('controller_cpu_per_sim_s', r(cpu / scenario_sim if scenario_sim else None, 4)),
            ('mpc_solve_time_mean_ms', r(1e3 * sum(solve) / len(solve), 3) if solve else None),
            ('mpc_solve_time_max_ms', r(1e3 * max(solve), 3) if solve else None),
            ('schedule', dict(self.schedule)),
        ])
        # the batch report's timing table reads these (the simulator never runs late in virtual time)
        info['scenario_wall_s'] = r(wall * scenario_sim / sim_s, 3) if scenario_sim and sim_s else None
        info['startup_wall_s'] = None
        info['sim_overruns'] = 0
        info['sim_reanchors'] = 0
        return info


def run(scenario, controller='mpc', **kwargs):
    """``Engine(scenario, controller, **kwargs).run()``."""
    return Engine(scenario, controller, **kwargs).run()
