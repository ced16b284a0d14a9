"""A fleet of Anafis in one world: fleet YAML -> per-drone settings -> the generated launch file (pure, no ROS).

Stage: experiments (on top of the trajectory scenarios, the model follower and the mirror's model names).
``fleet_launcher.py`` (started by launch/fleet.launch) uses it: ``load_fleet`` reads and checks a fleet file
(anafi_sim/config/fleets/*.yaml) or builds ``drones:=N`` identical drones in a row, ``drone_scenario`` gives
each drone its scenario shifted by its offset (written next to the generated launch file), ``launch_xml`` the
roslaunch XML that includes the per-drone launch files (sim.launch, spawn_anafi.launch, mpc.launch /
pid.launch, sphinx_gazebo.launch) once per drone namespace. Units: m, deg for yaw; world ENU frame.

Fleet file schema (every key optional except ``drones`` unless ``drones:=N`` is given)::

    name: circles                   # default: the file name
    description: text
    defaults: {controller: mpc, scenario: circle_r2_v1}   # every drone's settings unless it sets its own
    row: {spacing: 6.0, axis: y}    # drones:=N -> anafi1..anafiN, drone i at (i - 1) * spacing along axis
    layout: per_drone               # per_drone (a process per node) | shared (hosts: mission/fleet_layout.py)
    drones_per_host: {fleet_ground_truth: 10}   # shared layout: split a host by this many drones (default: the
                                    # machine's, each host within half a core: launch_check.machine_drones_per_host)
    drones:
      - name: anafi1                # a ROS name: namespace, tf prefix, models <name> and <name>_camera
        source: sim                 # sim (stand-in, default) | sphinx (the real Sphinx drone: at most one)
        start: {x: 0, y: 0, yaw: 0} # take-off point [m, deg]; default (offset x, offset y, 0)
        controller: mpc             # mpc | pid (the paper's 8 nodes) | pid_single | preview_mpc | none
        # exactly one of:
        scenario: circle_r2_v1      # a name in config/scenarios (sub/folder/name allowed), shifted by offset
        waypoint: [3, 2, 5, 0]      # a static target x, y, z [m], yaw [deg], shifted by offset
        target: {model: airship, offset_frame: heading, yaw_mode: heading}   # follow a Gazebo model
        offset: [0, 0, 0]           # scenario / waypoint: world shift [m]; target: the follower's offset
        telemetry_port: 9061        # default: a free port chosen at launch (Sphinx's own: 9060)
        telemetry_command: "tlm-data-logger -r 0 inet:127.0.0.1:9060"   # source sphinx only

A fleet file is untrusted input that becomes a launch file, and roslaunch substitutes ``$(...)`` in every
attribute value (XML quoting does not stop it). So every string field is checked against a strict pattern
(``NAME_RE`` for names and models, ``FLEET_NAME_RE`` for the fleet's name, ``SCENARIO_RE`` for scenarios:
package-relative names, no paths), the telemetry command against the allow-list, the description against
``TEXT_RE`` (no ``$``, no XML specials); ``launch_xml`` refuses any value holding ``$(`` and escapes the text
of its comments, so nothing a fleet file says is ever substituted or breaks out of the XML.
"""
import collections
import copy
import math
import os
import re
from xml.sax.saxutils import quoteattr

import yaml

from anafi_control import registry
from anafi_sim import paths
from anafi_sim.safe_yaml import load_yaml
from anafi_sim.mission.model_following import OFFSET_FRAMES, YAW_MODES
from anafi_sim.mission.trajectory import SCENARIO_DIR, airship_defaults, scenario_from_dict
from anafi_sim.gazebo.mirror import model_names
from anafi_sim.mission.fleet_layout import DEFAULT_LAYOUT, check_drones_per_host, check_layout
from anafi_sim.interface.telemetry_command import allowed_argv

FLEET_DIR = paths.config_path('fleets')
"""Directory of the shipped fleet files (anafi_sim/config/fleets)."""

SOURCES = ('sim', 'sphinx')
NO_CONTROLLER = 'none'
"""A drone's ``controller:`` without a controller; the others: the names of anafi_control.registry."""
DRONE_KEYS = ('name', 'source', 'start', 'controller', 'scenario', 'waypoint', 'target', 'offset',
              'telemetry_port', 'telemetry_command')
DEFAULT_KEYS = tuple(k for k in DRONE_KEYS if k not in ('name', 'start', 'telemetry_port'))
FLEET_KEYS = ('name', 'description', 'defaults', 'row', 'drones', 'layout', 'drones_per_host')
TARGET_KEYS = ('model', 'offset_frame', 'yaw_mode', 'yaw_offset')
RESERVED_MODELS = ('ground_plane', 'airship')
NAME_RE = re.compile(r'^[A-Za-z][A-Za-z0-9_]*$')
FLEET_NAME_RE = re.compile(r'^[A-Za-z0-9_]{1,64}$')
SCENARIO_RE = re.compile(r'^[A-Za-z0-9_]{1,64}(?:/[A-Za-z0-9_]{1,64}){0,4}(?:\.ya?ml)?$')
TEXT_RE = re.compile(r'^[^$<>&\x00-\x1f\x7f]{0,500}$')
WAYPOINT_DURATION = 3600.0   # s, the measured phase of a static waypoint target
MIN_SEPARATION = 1.0         # m, closest allowed take-off points

Drone = collections.namedtuple('Drone', 'name source start controller scenario waypoint target offset '
                                        'telemetry_port telemetry_command')
Drone.__doc__ = ('One drone of a fleet: name, source (sim | sphinx), start (x, y [m], yaw [deg]), controller, '
                 'scenario (name or path, or None), waypoint ((x, y, z [m], yaw [deg]) or None), target (dict '
                 'model, offset_frame, yaw_mode, yaw_offset, or None), offset (3 floats [m]), telemetry_port '
                 '(int or None = choose at launch), telemetry_command (sphinx source; \'\' = the interface\'s '
                 'default).')

Fleet = collections.namedtuple('Fleet', 'name description drones layout drones_per_host')
Fleet.__new__.__defaults__ = ({},)


def _short(value, limit=80):
    """``repr(value)`` cut to ``limit`` characters (a refused field is named, never copied whole)."""
    text = repr(value)
    return text if len(text) <= limit else text[:limit] + '...'


def _number(value, what):
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise ValueError('%s must be a finite number, got %r' % (what, value))
    return float(value)


def _vector(value, n, what):
    if not isinstance(value, (list, tuple)) or len(value) != n:
        raise ValueError('%s must be a list of %d numbers, got %r' % (what, n, value))
    return tuple(_number(v, '%s[%d]' % (what, i)) for i, v in enumerate(value))


def _check_keys(d, allowed, what):
    if not isinstance(d, dict):
        raise ValueError('%s must be a mapping, got %r' % (what, d))
    unknown = sorted(str(k) for k in set(d) - set(allowed))
    if unknown:
        raise ValueError('%s: unknown field(s) %s (allowed: %s)' % (what, ', '.join(unknown), ', '.join(allowed)))


def _start(value, offset, what):
    if value is None:
        return (offset[0], offset[1], 0.0)
    if isinstance(value, dict):
        _check_keys(value, ('x', 'y', 'yaw'), what)
        return tuple(_number(value.get(k, 0.0), '%s.%s' % (what, k)) for k in ('x', 'y', 'yaw'))
    if isinstance(value, (list, tuple)) and len(value) in (2, 3):
        s = _vector(list(value), len(value), what)
        return (s[0], s[1], s[2] if len(s) == 3 else 0.0)
    raise ValueError('%s must be {x, y, yaw} or [x, y(, yaw)] [m, deg], got %r' % (what, value))


def drone_from_dict(d, what='drone'):
    """A checked ``Drone`` from its mapping (defaults already merged in)."""
    _check_keys(d, DRONE_KEYS, what)
    name = d.get('name')
    if not isinstance(name, str) or not NAME_RE.match(name):
        raise ValueError('%s: name must be a ROS name ([A-Za-z][A-Za-z0-9_]*), got %s' % (what, _short(name)))
    what = 'drone %s' % name
    source = d.get('source', 'sim')
    if source not in SOURCES:
        raise ValueError('%s: source must be one of %s, got %r' % (what, ', '.join(SOURCES), source))
    controller = d.get('controller', 'mpc')
    known = registry.names() + (NO_CONTROLLER,)
    if controller not in known:
        raise ValueError('%s: controller must be one of %s, got %r' % (what, ', '.join(known), controller))
    offset = _vector(d.get('offset', [0.0, 0.0, 0.0]), 3, what + ': offset')
    kinds = [k for k in ('scenario', 'waypoint', 'target') if d.get(k) is not None]
    if len(kinds) != 1:
        raise ValueError('%s: give exactly one of scenario, waypoint, target (got %s)'
                         % (what, ', '.join(kinds) or 'none'))
    scenario = waypoint = target = None
    if kinds[0] == 'scenario':
        scenario = d['scenario']
        if not isinstance(scenario, str) or not SCENARIO_RE.match(scenario):
            raise ValueError('%s: scenario must be the name of a scenario of the package (config/scenarios, '
                             '[A-Za-z0-9_] words joined by /), got %s' % (what, _short(scenario)))
    elif kinds[0] == 'waypoint':
        w = d['waypoint']
        if not isinstance(w, (list, tuple)) or len(w) not in (3, 4):
            raise ValueError('%s: waypoint must be [x, y, z(, yaw)] [m, deg], got %r' % (what, w))
        w = _vector(list(w), len(w), what + ': waypoint')
        waypoint = w + ((0.0,) if len(w) == 3 else ())
    else:
        t = d['target']
        _check_keys(t, TARGET_KEYS, what + ': target')
        model = t.get('model')
        if not isinstance(model, str) or not NAME_RE.match(model):
            raise ValueError('%s: target.model must be a Gazebo model name ([A-Za-z][A-Za-z0-9_]*), got %s'
                             % (what, _short(model)))
        frame = t.get('offset_frame', 'heading')
        yaw_mode = t.get('yaw_mode', 'heading')
        if frame not in OFFSET_FRAMES:
            raise ValueError('%s: target.offset_frame must be one of %s' % (what, ', '.join(OFFSET_FRAMES)))
        if yaw_mode not in YAW_MODES:
            raise ValueError('%s: target.yaw_mode must be one of %s' % (what, ', '.join(YAW_MODES)))
        target = {'model': model, 'offset_frame': frame, 'yaw_mode': yaw_mode,
                  'yaw_offset': _number(t.get('yaw_offset', 0.0), what + ': target.yaw_offset')}
    port = d.get('telemetry_port')
    if port is not None and (isinstance(port, bool) or not isinstance(port, int) or not 1 <= port <= 65535):
        raise ValueError('%s: telemetry_port must be an integer in [1, 65535], got %r' % (what, port))
    command = d.get('telemetry_command', '')
    if not isinstance(command, str) or '$' in command:
        raise ValueError('%s: telemetry_command must be a string without $, got %s' % (what, _short(command)))
    if command and source != 'sphinx':
        raise ValueError('%s: telemetry_command is for source sphinx only (the stand-in gets its own)' % what)
    if command:
        try:
            allowed_argv(command, resolve_names=False)   # an allowed tool with its own arguments
        except ValueError as error:
            raise ValueError('%s: %s' % (what, error))
    start = _start(d.get('start'), offset, what + ': start')
    return Drone(name, source, start, controller, scenario, waypoint, target, offset, port, command)


def row_drones(defaults, count, spacing=6.0, axis='y', prefix='anafi'):
    """``count`` drone mappings anafi1..anafiN from ``defaults``, drone i shifted by (i - 1) * spacing [m]
    along ``axis`` (added to the defaults' offset)."""
    if isinstance(count, bool) or not isinstance(count, int) or count < 1:
        raise ValueError('drones must be an integer >= 1, got %r' % (count,))
    spacing = _number(spacing, 'row.spacing')
    if axis not in ('x', 'y'):
        raise ValueError("row.axis must be 'x' or 'y', got %r" % (axis,))
    base = _vector(defaults.get('offset', [0.0, 0.0, 0.0]), 3, 'defaults.offset')
    out = []
    for i in range(count):
        shift = [0.0, 0.0, 0.0]
        shift['xy'.index(axis)] = i * spacing
        d = dict(copy.deepcopy(defaults), name='%s%d' % (prefix, i + 1))
        d['offset'] = [b + s for b, s in zip(base, shift)]
        out.append(d)
    return out


def fleet_from_dict(data, name='fleet', drones=0, what=None):
    """A checked ``Fleet`` from the mapping of a fleet file; ``drones`` > 0: that many drones in a row
    (``row_drones`` from the file's defaults) instead of its drone list."""
    what = what or 'fleet %s' % name
    try:
        _check_keys(data, FLEET_KEYS, 'fleet file')
        defaults = data.get('defaults') or {}
        _check_keys(defaults, DEFAULT_KEYS, 'defaults')
        if drones:
            row = data.get('row') or {}
            _check_keys(row, ('spacing', 'axis'), 'row')
            entries = row_drones(defaults, drones, row.get('spacing', 6.0), row.get('axis', 'y'))
        else:
            entries = data.get('drones')
            if not isinstance(entries, list) or not entries:
                raise ValueError('drones must be a non-empty list (or give drones:=N)')
            entries = [dict(copy.deepcopy(defaults), **e) if isinstance(e, dict) else e for e in entries]
        layout = data.get('layout', DEFAULT_LAYOUT)
        fleet_name, description = data.get('name', name), data.get('description', '')
        if not isinstance(fleet_name, str) or not FLEET_NAME_RE.match(fleet_name):
            raise ValueError('name must be [A-Za-z0-9_]+ (at most 64), got %s' % _short(fleet_name))
        if not isinstance(description, str) or not TEXT_RE.match(description):
            raise ValueError('description must be text of at most 500 characters without $ < > & or '
                             'control characters, got %s' % _short(description))
        fleet = Fleet(fleet_name, description,
                      tuple(drone_from_dict(e, 'drone %d' % (i + 1)) for i, e in enumerate(entries)),
                      check_layout(layout) if isinstance(layout, str) else check_layout(_short(layout)),
                      check_drones_per_host(data.get('drones_per_host')))
        check_fleet(fleet)
        return fleet
    except ValueError as e:
        raise ValueError('%s: %s' % (what, e))


def launch_problem(value, given):
    """The launch check's rule for ``fleet:=`` (anafi_sim/launch_check.py, fleet.launch): None when the fleet
    file ``value`` is good and its drone list fits the fleet cap of its layout (``layout:=`` or the file's;
    ``drones:=N`` is the drones rule's); else the fleet launcher's refusal, one line."""
    from anafi_sim.launch_check import CPU_PER_DRONE, DEFAULT_LAYOUT as CAP_LAYOUT, fleet_size_problem
    from anafi_sim.numeric import parse_integer
    count = parse_integer(given.get('drones', '0')) or 0
    try:
        loaded = load_fleet(value, max(count, 0))
    except ValueError as error:
        text = (str(error).splitlines() or ['refused'])[0]
        return text if len(text) <= 400 else text[:400] + '...'
    if count > 0:
        return None      # drones:=N: the launch check's drones rule holds it to the cap
    layout = given.get('layout') or loaded.layout
    return fleet_size_problem(len(loaded.drones), max(parse_integer(given.get('max_drones', '0')) or 0, 0),
                              layout=layout if layout in CPU_PER_DRONE else CAP_LAYOUT)


def check_fleet(fleet, min_separation=MIN_SEPARATION):
    """ValueError when drones would clash: names / Gazebo models / ports taken twice, more than one Sphinx
    drone (Sphinx simulates one), take-off points closer than ``min_separation`` [m]."""
    models = {}
    for drone in fleet.drones:
        for model in model_names(drone.name):
            if model in RESERVED_MODELS:
                raise ValueError('drone %s: model name %s is taken by the scene' % (drone.name, model))
            if model in models:
                raise ValueError('drones %s and %s: both need the Gazebo model %s'
                                 % (models[model], drone.name, model))
            models[model] = drone.name
    ports = [d.telemetry_port for d in fleet.drones if d.telemetry_port is not None]
    if len(set(ports)) != len(ports):
        raise ValueError('telemetry ports given twice: %s' % sorted(p for p in ports if ports.count(p) > 1))
    if sum(1 for d in fleet.drones if d.source == 'sphinx') > 1:
        raise ValueError('at most one drone can come from Sphinx (it simulates one Anafi)')
    for i, a in enumerate(fleet.drones):
        for b in fleet.drones[i + 1:]:
            gap = math.hypot(a.start[0] - b.start[0], a.start[1] - b.start[1])
            if gap < min_separation:
                raise ValueError('drones %s and %s take off %.2f m apart (< %.1f m)'
                                 % (a.name, b.name, gap, min_separation))


#: former names of shipped fleets -> their names now (a fleet's name does not count its drones: drones:=N changes
#: that count)
FLEET_ALIASES = {'three_circles': 'circles'}


def fleet_path(name_or_path):
    """Path of a fleet file given a path or a name in ``FLEET_DIR`` (or a former name, ``FLEET_ALIASES``)."""
    if os.sep in name_or_path or name_or_path.endswith(('.yaml', '.yml')):
        return name_or_path
    return os.path.join(FLEET_DIR, FLEET_ALIASES.get(name_or_path, name_or_path) + '.yaml')


def load_fleet(name_or_path, drones=0):
    """``fleet_from_dict`` of a fleet file (path or name in ``FLEET_DIR``); errors name the file and field."""
    path = fleet_path(name_or_path)
    if not os.path.isfile(path):
        raise ValueError('no fleet file %s' % path)
    data = load_yaml(path)
    name = re.sub(r'[^A-Za-z0-9_]', '_', os.path.splitext(os.path.basename(path))[0])[:64] or 'fleet'
    return fleet_from_dict(data, name, drones, what=path)


# ---------------------------------------------------------------------------------------- scenarios
def _shift_component(c, dv):
    if isinstance(c, (int, float)) and not isinstance(c, bool):
        return c + dv
    c = dict(c)
    key = {'constant': 'value', 'ramp': 'start', 'sine': 'offset'}.get(c.get('type'))
    if key is None:
        raise ValueError('cannot shift axis component %r' % (c,))
    c[key] = c.get(key, 0.0) + dv
    return c


def offset_trajectory_dict(traj, offset):
    """The trajectory mapping of a scenario moved by ``offset`` (dx, dy, dz) [m] in the world frame."""
    traj = copy.deepcopy(traj)
    kind = traj.get('type') if isinstance(traj, dict) else None
    key = {'static': 'position', 'line': 'start', 'circle': 'centre', 'vertical': 'centre'}.get(kind)
    if key is not None:
        traj[key] = [float(v) + o for v, o in zip(traj[key], offset)]
    elif kind == 'per_axis':
        for axis, o in zip('xyz', offset):
            traj[axis] = _shift_component(traj.get(axis, 0.0), o)
    elif kind == 'airship':          # the followed target's path moves: its centre and altitude
        path = dict(airship_defaults(), **(traj.get('path') or {}))
        path['center'] = [float(path['center'][0]) + offset[0], float(path['center'][1]) + offset[1]]
        path['altitude'] = float(path['altitude']) + offset[2]
        traj['path'] = path
    else:
        raise ValueError('cannot shift a trajectory of type %r' % (kind,))
    return traj


def offset_scenario_dict(data, offset):
    """A scenario mapping moved by ``offset`` [m]: trajectory and an explicit start point."""
    data = copy.deepcopy(data)
    data['trajectory'] = offset_trajectory_dict(data['trajectory'], offset)
    start = data.get('start')
    if isinstance(start, dict):
        start = dict(start)
        for axis, o in zip('xyz', offset):
            start[axis] = start.get(axis, 0.0) + o
        data['start'] = start
    elif isinstance(start, (list, tuple)):
        data['start'] = [float(v) + o for v, o in zip(start[:3], offset)] + list(start[3:])
    return data


def drone_scenario(drone, scenario_dir=None):
    """The scenario mapping drone ``drone`` flies (its scenario or static waypoint, shifted by its offset),
    checked by the trajectory module (ValueError); None for a model target."""
    if drone.target is not None:
        return None
    if drone.scenario is not None:
        if not SCENARIO_RE.match(drone.scenario):
            raise ValueError('drone %s: scenario must be a name of the package\'s scenarios' % drone.name)
        name = drone.scenario if drone.scenario.endswith(('.yaml', '.yml')) else drone.scenario + '.yaml'
        path = os.path.join(scenario_dir or SCENARIO_DIR, name)
        if not os.path.isfile(path):
            raise ValueError('drone %s: no scenario file %s' % (drone.name, path))
        data = load_yaml(path, what='drone %s: scenario %s' % (drone.name, drone.scenario))
        if not isinstance(data, dict):
            raise ValueError('drone %s: scenario %s is not a mapping' % (drone.name, drone.scenario))
        data.setdefault('name', os.path.splitext(os.path.basename(path))[0])
    else:
        x, y, z, yaw = drone.waypoint
        data = {'name': 'waypoint', 'start': 'trajectory',
                'trajectory': {'type': 'static', 'position': [x, y, z], 'yaw': yaw},
                'phases': [{'name': 'hold', 'duration': WAYPOINT_DURATION, 'measure': True}]}
    data = offset_scenario_dict(data, drone.offset)
    if any(drone.offset):
        data['description'] = ('%s (shifted by %s m for %s)'
                               % (data.get('description', ''), list(drone.offset), drone.name)).strip()
    try:
        scenario_from_dict(data, what='drone %s: scenario %s' % (drone.name, data.get('name')))
    except ValueError as e:
        raise ValueError(str(e))
    return data


# ---------------------------------------------------------------------------------------- launch XML
LAUNCH = '$(find anafi_sim)/anafi_sim/launch/'


def _value(value):
    """An attribute value, quoted; ValueError when it holds ``$(`` (roslaunch would substitute it)."""
    text = str(value)
    if '$(' in text or '$ (' in text:
        raise ValueError('refused to write %s into the launch file: roslaunch would substitute it' % _short(text))
    return quoteattr(text)


def comment_text(text):
    """``text`` safe inside an XML comment: no ``--`` (so no ``-->``), no trailing ``-``, printable."""
    text = ''.join(c if c.isprintable() else ' ' for c in str(text))
    while '--' in text:
        text = text.replace('--', '- -')
    return text + ' ' if text.endswith('-') else text


def _arg(name, value):
    return '    <arg name=%s value=%s/>' % (quoteattr(name), _value(value))


def _param(name, value, indent='      '):
    return '%s<param name=%s value=%s/>' % (indent, quoteattr(name), _value(value))


def _include(launch, args, comment=None):
    lines = ['  <!-- %s -->' % comment_text(comment)] if comment else []
    path = launch if os.path.isabs(launch) or launch.startswith('$(') else LAUNCH + launch
    lines.append('  <include file=%s>' % quoteattr(path))
    lines += [_arg(k, v) for k, v in args]
    lines.append('  </include>')
    return lines


def launch_document(includes, body=(), head=()):
    """A roslaunch XML document: the lines ``head``, one ``<include>`` per (launch file, [(arg, value), ...]) of
    ``includes`` (a bare file name is one of the package's launch files, else a path), then the lines ``body``."""
    lines = ['<launch>'] + list(head)
    for launch, args in includes:
        lines += _include(launch, args)
    return '\n'.join(lines + list(body) + ['</launch>']) + '\n'


def _fmt(v):
    return repr(float(v))


def drone_launch_lines(drone, port, scenario_file, options):
    """The launch XML lines of one drone (see ``launch_xml`` for ``options``)."""
    n = drone.name
    out = ['', '  <!-- ======== %s -->' % comment_text('%s: %s, controller %s, %s' % (n, 'real Sphinx drone' if drone.source == 'sphinx' else 'simulated Anafi (stand-in)',
              drone.controller, describe_task(drone)))]
    if drone.source == 'sim':
        out += _include('sim.launch', [('drone_name', n), ('telemetry_port', port), ('use_sim_time', 'false'),
                                       ('initial_x', _fmt(drone.start[0])), ('initial_y', _fmt(drone.start[1])),
                                       ('initial_yaw', _fmt(math.radians(drone.start[2]))),
                                       ('output', options['output'])]
                       + ([('conditions', options['conditions'])] if options.get('conditions') else []))
        if options['mirror'] == 'true':
            out += _include('spawn_anafi.launch', [('drone_name', n), ('rate', _fmt(options['mirror_rate'])),
                                                   ('output', options['output'])])
    else:
        args = [('drone_name', n), ('world', 'false'), ('use_sim_time', 'false'), ('mirror', options['mirror'])]
        if drone.telemetry_command:
            args.append(('telemetry_command', drone.telemetry_command))
        out += _include('sphinx_gazebo.launch', args, 'the real Sphinx drone: its telemetry + mirror (no world)')
    if drone.controller != NO_CONTROLLER:    # its launch file (anafi_control.registry)
        entry = registry.get(drone.controller)
        out += _include(entry.launch, [('drone_name', n), ('output', options['output'])] + list(entry.launch_args))
    out.append('  <group ns=%s>' % quoteattr(n))
    if drone.target is None:
        out.append('    <node pkg="anafi_sim" type="trajectory_generator.py" name="trajectory_generator" '
                   'output=%s>' % quoteattr(options['output']))
        out.append(_param('scenario_file', scenario_file))
        out.append(_param('autostart', 'true'))
        out.append(_param('wait_for_flying', 'true'))
        out.append('    </node>')
    else:
        t = drone.target
        out.append('    <node pkg="anafi_sim" type="model_follower.py" name="model_follower" output=%s>'
                   % quoteattr(options['output']))
        out.append(_param('model_name', t['model']))
        out.append('      <rosparam param="offset">%s</rosparam>' % list(drone.offset))
        out.append(_param('offset_frame', t['offset_frame']))
        out.append(_param('yaw_mode', t['yaw_mode']))
        out.append(_param('yaw_offset', _fmt(t['yaw_offset'])))
        out.append('    </node>')
    if options['evaluate']:
        base = os.path.join(options['out_dir'], n)
        out.append('    <node pkg="anafi_sim" type="evaluator.py" name="evaluator" output="log">')
        out.append(_param('name', '%s_%s' % (n, drone.controller)))
        out.append(_param('publish_period', '5.0'))
        out.append(_param('summary_file', base + '.yaml'))
        out.append(_param('csv_file', base + '.csv'))
        out.append(_param('csv_window', 'all'))
        out.append('    </node>')
    out.append('  </group>')
    if options.get('rviz'):
        out += _include('rviz.launch', [('drone_name', n), ('gui', 'false'),
                                        ('markers_topic', 'visualisation/markers')],
                        'rviz: model description, tf and this drone\'s markers (rviz itself: the end of the file)')
    return out


def describe_task(drone):
    """What the drone flies, in words."""
    shift = ' + offset %s m' % list(drone.offset) if any(drone.offset) else ''
    if drone.scenario is not None:
        return 'scenario %s%s' % (drone.scenario, shift)
    if drone.waypoint is not None:
        return 'waypoint %s%s' % (list(drone.waypoint), shift)
    return 'follows model %s at offset %s m (%s frame)' % (drone.target['model'], list(drone.offset),
                                                            drone.target['offset_frame'])


def launch_xml(fleet, ports, scenario_files, out_dir, evaluate=True, mirror=True, mirror_rate=100.0,
               output='log', source='', aggregator_file='', rviz=False, rviz_file='', conditions='', world=False):
    """The roslaunch XML of every drone of ``fleet``: ``ports`` {name: telemetry
    port}, ``scenario_files`` {name: path} (drones with a scenario or waypoint), ``out_dir`` for the
    evaluators' files (``evaluate``), ``mirror`` (spawn_anafi.launch per drone at ``mirror_rate`` Hz),
    ``output`` (screen | log) of the nodes; ``aggregator_file``: a YAML of ``aggregator_analyzers`` -> a
    diagnostic_aggregator node with diagnostics_aggregator.yaml + it ('' = none); ``rviz``: rviz.launch
    (gui false) per drone: robot description, robot_state_publisher, the markers on /<drone>/visualisation/markers;
    ``rviz_file``: rviz on that config (the fleet's view, rviz_config.fleet_rviz; '' = no rviz window);
    ``conditions``: a flight-conditions profile NAME for every simulated drone ('' = none); ``world``: the
    kinematic world too (world.launch drone:=false; False: the world is fleet.launch's or already runs)."""
    options = {'evaluate': bool(evaluate), 'mirror': 'true' if mirror else 'false', 'mirror_rate': mirror_rate,
               'output': output, 'out_dir': out_dir, 'rviz': bool(rviz), 'conditions': conditions or ''}
    if conditions:
        from anafi_sim.sim.conditions_profile import NAME
        if not NAME.match(conditions):
            raise ValueError('conditions must be a profile NAME (anafi_sim/config/conditions), got %r'
                             % (conditions,))
    if output not in ('screen', 'log'):
        raise ValueError('output must be screen or log, got %r' % (output,))
    lines = ['<?xml version="1.0"?>',
             '<!-- %s -->' % comment_text('Generated by fleet_launcher.py%s: fleet %s, %d drone(s). Do not edit; '
                                          'edit the fleet file.' % (' from ' + source if source else '', fleet.name,
                                                                    len(fleet.drones))),
             '<launch>']
    if world:
        lines += _include('world.launch', [('drone', 'false')], 'the kinematic world (our Gazebo stand-in)')
    for drone in fleet.drones:
        if drone.source == 'sim' and drone.name not in ports:
            raise ValueError('drone %s: no telemetry port' % drone.name)
        lines += drone_launch_lines(drone, ports.get(drone.name), scenario_files.get(drone.name), options)
    if aggregator_file:
        lines += ['', '  <!-- diagnostics by component and by drone (diagnostic_aggregator, ROS Noetic) -->',
                  '  <node pkg="diagnostic_aggregator" type="aggregator_node" name="diagnostic_aggregator">',
                  '    <rosparam command="load" file=%s/>'
                  % quoteattr('$(find anafi_sim)/anafi_sim/config/diagnostics_aggregator.yaml'),
                  '    <rosparam command="load" file=%s ns="analyzers"/>' % _value(aggregator_file),
                  '  </node>']
    if rviz and rviz_file:
        lines += ['', '  <!-- rviz on the fleet\'s generated view: a model and markers per drone, the fleet framed -->',
                  '  <node pkg="rviz" type="rviz" name="rviz" args=%s output="log"/>' % _value('-d ' + rviz_file)]
    lines.append('</launch>')
    return '\n'.join(lines) + '\n'


# ---------------------------------------------------------------------------------------- diagnostics
AGGREGATOR_CONFIG = paths.config_path('diagnostics_aggregator.yaml')
DRONE_PATTERN = '[A-Za-z][A-Za-z0-9_]*'
"""The drone-name part of the regexes in diagnostics_aggregator.yaml (replaced per drone)."""


def aggregator_analyzers(fleet, config=None):
    """diagnostic_aggregator ``analyzers`` grouping each drone's statuses: Drones/<name>/<component>, from the
    component analyzers of diagnostics_aggregator.yaml (``config``: its mapping) with the drone part of each
    regex (``DRONE_PATTERN``) replaced by the drone's name."""
    if config is None:
        with open(AGGREGATOR_CONFIG) as f:
            config = yaml.safe_load(f)
    components = config['analyzers']['components']['analyzers']
    drones = {}
    for drone in fleet.drones:
        group = {}
        for key, analyzer in components.items():
            if DRONE_PATTERN not in analyzer['regex']:
                raise ValueError('analyzer %s: its regex has no drone part %s' % (key, DRONE_PATTERN))
            group[key] = dict(analyzer, regex=analyzer['regex'].replace(DRONE_PATTERN, re.escape(drone.name)))
        drones[drone.name] = {'type': 'diagnostic_aggregator/AnalyzerGroup', 'path': drone.name, 'analyzers': group}
    return {'drones': {'type': 'diagnostic_aggregator/AnalyzerGroup', 'path': 'Drones', 'analyzers': drones}}
