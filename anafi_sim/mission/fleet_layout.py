"""A fleet's process layout: the per-drone launch expanded -> the shared layout's hosts (pure, no ROS).

Stage: experiments (beside mission/fleet.py, which writes the per-drone launch). Two layouts:

- ``per_drone`` (the paper's, and the default): every node of every drone is a process of its own.
- ``shared``: the nodes of the types in ``HOSTS`` run as instances inside a few host processes
  (anafi_sim/nodes/fleet_host.py): ``fleet_drones`` hosts every drone's simulator, controller and trajectory generator
  (their estimate, command and waypoint messages stay in the process), ``fleet_ground_truth`` every drone's
  interface and mirror, and the kinematic world when the fleet runs ours (the 100 Hz ground truth reaches the
  mirror, and the mirror's model states the world, in the process); both split by drone so that each host stays
  within half a core of the machine it runs on (SPLIT_HOSTS, ``split_limits``: ``fleet_drones_1``,
  ``fleet_drones_2``, ..., ``fleet_ground_truth_1``, ... the world in the first).
  Everything else (the
  distributed PID nodes, evaluators, model followers, rviz helpers, the telemetry CLIs the interfaces
  supervise) stays a process of its own, as does any node a launch file gives remappings, a launch prefix or
  environment of its own.

``shared_layout`` takes the nodes and parameters roslaunch expands the per-drone launch file into, so both
layouts run the same launch files with the same parameters: the instances read them under their own names.
"""
import collections
from xml.sax.saxutils import quoteattr

import yaml

from anafi_sim.launch_check import CPU_PER_DRONE, DEFAULT_LAYOUT

LAYOUTS = tuple(sorted(CPU_PER_DRONE))     # per_drone, shared

#: host name -> the node types it runs (the per-drone launch files' ``type``s)
HOSTS = collections.OrderedDict([
    ('fleet_drones', ('anafi_sim_node.py', 'controller_node.py', 'trajectory_generator.py')),
    ('fleet_ground_truth', ('interface_node.py', 'gazebo_mirror_node.py', 'kinematic_world_node.py')),
])

#: node type (the script's file name) -> (the module of its node class, the class, its arguments before the
#: NodeContext): what the fleet host (anafi_sim/nodes/fleet_host.py) imports and builds for an instance of that
#: type. Names only: this core imports no node.
HOSTABLE = {
    'anafi_sim_node.py': ('anafi_sim.nodes.anafi_sim_node', 'AnafiSimNode', ()),
    'interface_node.py': ('anafi_sim.nodes.interface_node', 'InterfaceNode', ()),
    'gazebo_mirror_node.py': ('anafi_sim.nodes.gazebo_mirror_node', 'GazeboMirrorNode', ()),
    'kinematic_world_node.py': ('anafi_sim.nodes.kinematic_world_node', 'KinematicWorldNode', ()),
    'controller_node.py': ('anafi_sim.nodes.controller_node', 'ControllerNode', (None,)),
    'trajectory_generator.py': ('anafi_sim.nodes.trajectory_generator', 'TrajectoryGeneratorNode', ()),
}

SPLIT_HOSTS = ('fleet_drones', 'fleet_ground_truth')
"""Hosts split by drone: at most so many drones' instances in one such host (<host>_1, <host>_2, ...). One
interpreter runs one thread at a time: in fleet_drones each simulator step's telemetry send and each controller's
solve wait for it, fleet_ground_truth runs every interface and mirror at 100 Hz, and a host near a whole core falls
behind real time before the cores are full. How many drones: ``split_limits`` (the machine's, each host within
launch_check.HOST_CORE_BUDGET of a core: launch_check.machine_drones_per_host; a fleet file's ``drones_per_host``
wins). An instance outside the drones' namespaces (the kinematic world) goes to the first host of the split: the
mirrors there reach it in the process, the others through its topic."""

NodeSpec = collections.namedtuple('NodeSpec', 'package type name namespace args output respawn respawn_delay '
                                              'required launch_prefix cwd env_args remap_args')
"""One node of the expanded launch (roslaunch.core.Node's fields that the layout keeps)."""


def check_layout(layout):
    """``layout`` if it is one of LAYOUTS, else ValueError."""
    if layout not in LAYOUTS:
        raise ValueError('layout must be one of %s, got %r' % (', '.join(LAYOUTS), layout))
    return layout


def read_instances(raw):
    """A host's ``~instances`` -> [(name, type)]; ValueError naming the entry that is not {name: /global/name,
    type: a HOSTABLE type} or a name given twice."""
    if not isinstance(raw, list) or not raw:
        raise ValueError('~instances must be a non-empty list of {name, type}, got %r' % (raw,))
    out, seen = [], set()
    for i, entry in enumerate(raw):
        if not isinstance(entry, dict) or set(entry) != {'name', 'type'}:
            raise ValueError('~instances[%d] must be {name, type}, got %r' % (i, entry))
        name, kind = entry['name'], entry['type']
        if not isinstance(name, str) or not name.startswith('/') or name in seen:
            raise ValueError('~instances[%d]: name must be a global ROS name given once, got %r' % (i, name))
        if kind not in HOSTABLE:
            raise ValueError('~instances[%d] (%s): type must be one of %s, got %r'
                             % (i, name, ', '.join(sorted(HOSTABLE)), kind))
        seen.add(name)
        out.append((name, kind))
    return out


def full_name(node):
    return (node.namespace.rstrip('/') + '/' + node.name) if node.namespace else '/' + node.name


def host_of(node):
    """The host that runs ``node`` in the shared layout, None when it stays a process of its own."""
    if node.package != 'anafi_sim' or node.remap_args or node.launch_prefix or node.env_args or node.args:
        return None
    for host, types in HOSTS.items():
        if node.type in types:
            return host
    return None


def drone_of(instance_name):
    """'/anafi1/mpc_controller' -> 'anafi1'; '' for a name at the root (the world)."""
    parts = instance_name.strip('/').split('/')
    return parts[0] if len(parts) > 1 else ''


def check_drones_per_host(value):
    """A fleet file's ``drones_per_host`` ({host: drones >= 1}, hosts of SPLIT_HOSTS) -> a dict; ValueError
    naming what is wrong."""
    if value is None:
        return {}
    if not isinstance(value, dict):
        raise ValueError('drones_per_host must be a mapping {host: drones}, got %r' % (value,))
    for host, limit in value.items():
        if host not in SPLIT_HOSTS:
            raise ValueError('drones_per_host: %r is not a host split by drone (%s)'
                             % (host, ', '.join(sorted(SPLIT_HOSTS))))
        if isinstance(limit, bool) or not isinstance(limit, int) or limit < 1:
            raise ValueError('drones_per_host.%s must be an integer >= 1, got %r' % (host, limit))
    return dict(value)


def split_limits(machine, fleet_file=None):
    """{host: drones} the hosts split by: the machine's (launch_check.machine_drones_per_host), a fleet file's
    ``drones_per_host`` winning per host."""
    return dict(machine or {}, **(fleet_file or {}))


def split_by_drone(hosted, drones_per_host=None):
    """{host: instances} with each host of ``drones_per_host`` ({host: drones}, ``split_limits``) split into
    <host>_1, <host>_2, ... of at most that many drones each (one name unchanged when it fits, or without a
    limit), the drones in launch order; instances outside the drones' namespaces (the world) go with the first
    group."""
    limits = dict(drones_per_host or {})
    out = collections.OrderedDict()
    for host, instances in hosted.items():
        limit = limits.get(host)
        drones = []
        for inst in instances:
            drone = drone_of(inst['name'])
            if drone and drone not in drones:
                drones.append(drone)
        if not limit or len(drones) <= limit:
            out[host] = instances
            continue
        for k in range(0, len(drones), limit):
            group = set(drones[k:k + limit]) | ({''} if k == 0 else set())
            out['%s_%d' % (host, k // limit + 1)] = [i for i in instances if drone_of(i['name']) in group]
    return out


def nested(params):
    """{'/a/b/c': value} -> {'a': {'b': {'c': value}}} (a rosparam file loaded at /)."""
    out = {}
    for key in sorted(params):
        parts = [p for p in key.split('/') if p]
        d = out
        for part in parts[:-1]:
            d = d.setdefault(part, {})
        d[parts[-1]] = params[key]
    return out


def _node_xml(node, indent='  '):
    attrs = [('pkg', node.package), ('type', node.type), ('name', node.name)]
    if node.namespace and node.namespace != '/':
        attrs.append(('ns', node.namespace))
    for key, value in (('args', node.args), ('output', node.output), ('launch-prefix', node.launch_prefix),
                       ('cwd', node.cwd)):
        if value:
            attrs.append((key, value))
    if node.respawn:
        attrs += [('respawn', 'true'), ('respawn_delay', '%g' % (node.respawn_delay or 0.0))]
    if node.required:
        attrs.append(('required', 'true'))
    head = '%s<node %s' % (indent, ' '.join('%s=%s' % (k, quoteattr(str(v))) for k, v in attrs))
    inner = ['%s  <remap from=%s to=%s/>' % (indent, quoteattr(a), quoteattr(b)) for a, b in node.remap_args]
    inner += ['%s  <env name=%s value=%s/>' % (indent, quoteattr(a), quoteattr(b)) for a, b in node.env_args]
    if not inner:
        return [head + '/>']
    return [head + '>'] + inner + ['%s</node>' % indent]


def shared_layout(nodes, params, params_file, output='log', title='', drones_per_host=None):
    """The shared layout of an expanded per-drone launch: (launch XML, params document).

    ``nodes``: NodeSpecs; ``params``: {global name: value} (every parameter the launch sets, nodes' private
    ones included); ``params_file``: where the caller writes the params document (the XML loads it);
    ``drones_per_host``: {host: drones} the hosts are split by (``split_limits``; none: not split).
    The XML loads every parameter, starts each host with ``~instances`` (its nodes, in launch order; a host
    with none is not started) and every other node as it was."""
    hosted = collections.OrderedDict((host, []) for host in HOSTS)
    others = []
    for node in nodes:
        host = host_of(node)
        if host is None:
            others.append(node)
        else:
            hosted[host].append({'name': full_name(node), 'type': node.type})
    hosted = split_by_drone(hosted, drones_per_host)
    lines = ['<?xml version="1.0"?>',
             '<!-- Generated by fleet_launcher.py: %s, shared layout (hosts: %s). Do not edit; edit the fleet file. -->'
             % (title or 'fleet', ', '.join(h for h, i in hosted.items() if i)),
             '<launch>',
             '  <!-- every parameter of the per-drone layout, hosted instances\' included -->',
             '  <rosparam command="load" file=%s/>' % quoteattr(params_file)]
    for host, instances in hosted.items():
        if not instances:
            continue
        kinds = sorted(set(i['type'] for i in instances))
        lines += ['', '  <!-- %s: %d instances (%s) -->' % (host, len(instances), ', '.join(kinds)),
                  '  <node pkg="anafi_sim" type="fleet_host.py" name=%s output=%s respawn="true" respawn_delay="1">'
                  % (quoteattr(host), quoteattr(output)),
                  '    <rosparam param="instances">%s</rosparam>'
                  % yaml.safe_dump(instances, default_flow_style=True, width=1 << 20).strip(),
                  '  </node>']
    if others:
        lines += ['', '  <!-- nodes that stay processes of their own -->']
        for node in others:
            lines += _node_xml(node)
    lines.append('</launch>')
    return '\n'.join(lines) + '\n', nested(params)
