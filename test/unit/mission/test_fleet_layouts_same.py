"""Both layouts of a fleet start the same nodes with the same parameters (fleet_launcher.generate, expanded by
roslaunch's own loader; no ROS master).

The circles fleet is generated in the per-drone and in the shared layout into one directory (the same
scenario files, telemetry ports from one fixed sequence), each launch file is expanded with
``roslaunch.config.load_config_default`` and ``differences`` lists what the shared layout changes beyond
moving nodes into hosts: every hosted instance's parameters in ``fleet.params.yaml`` (under its name) must
equal the per-drone node's private parameters exactly (values and types), every per-drone node must be hosted
(in the ``~instances`` of exactly one host, with its type) or still a node with the same settings, and the
shared launch must start nothing else and set no other parameter.
"""
import copy
import itertools
import os

import pytest
import yaml

from anafi_sim.mission import fleet_layout

roslaunch_config = pytest.importorskip('roslaunch.config', reason='roslaunch not importable (source env.bash)')

#: roslaunch's own parameters (set by the loader, not by our launch files)
ROSLAUNCH_PARAMS = ('/rosdistro', '/rosversion')


def _launcher():
    from anafi_sim.nodes import fleet_launcher
    return fleet_launcher


def _strict(value):
    """``value`` with the type of every leaf attached: 1 != 1.0 != True != '1'."""
    if isinstance(value, dict):
        return dict((k, _strict(v)) for k, v in value.items())
    if isinstance(value, (list, tuple)):
        return [_strict(v) for v in value]
    return (type(value).__name__, value)


def _under(params, name):
    """{key below name/: value} of a flat {global name: value}."""
    prefix = name.rstrip('/') + '/'
    return dict((k[len(prefix):], v) for k, v in params.items() if k.startswith(prefix))


def _flat(document, prefix=''):
    """A nested rosparam document -> {relative name: value} (the inverse of fleet_layout.nested)."""
    out = {}
    for key, value in document.items():
        if isinstance(value, dict) and value:
            out.update(_flat(value, prefix + key + '/'))
        else:
            out[prefix + key] = value
    return out


def _at(document, name):
    """The sub-document of ``document`` at the global name ``name`` ({} when absent)."""
    d = document
    for part in [p for p in name.split('/') if p]:
        d = d.get(part, {}) if isinstance(d, dict) else {}
    return d if isinstance(d, dict) else {}


def _settings(node):
    """Everything roslaunch starts a node with, except its name."""
    return (node.package, node.type, node.args, node.respawn, node.respawn_delay, node.required,
            node.launch_prefix, node.cwd, sorted(node.env_args), list(node.remap_args), node.output)


def differences(per_drone, shared, document):
    """What the shared layout changes beyond moving nodes into hosts, as readable lines ([] = the same).

    ``per_drone`` / ``shared``: {'nodes': [roslaunch Node], 'params': {global name: value}} of the expanded
    launch files; ``document``: the shared layout's fleet.params.yaml as loaded."""
    problems = []
    pd_nodes = dict((fleet_layout.full_name(n), n) for n in per_drone['nodes'])
    hosts, shared_nodes = {}, {}
    for n in shared['nodes']:
        name = fleet_layout.full_name(n)
        if n.type == 'fleet_host.py':
            hosts[name] = fleet_layout.read_instances(shared['params'].get(name + '/instances'))
        else:
            shared_nodes[name] = n
    hosted = {}
    for host, instances in sorted(hosts.items()):
        if host.lstrip('/') not in fleet_layout.HOSTS:
            problems.append('%s: a host the layout does not define' % host)
        for name, kind in instances:
            hosted.setdefault(name, []).append((host, kind))
    for name, node in pd_nodes.items():
        where = hosted.get(name, [])
        if name in shared_nodes:
            if where:
                problems.append('%s: both a node and hosted by %s' % (name, ', '.join(h for h, _ in where)))
            if _settings(shared_nodes[name]) != _settings(node):
                problems.append('%s: started with other settings: %r != %r'
                                % (name, _settings(shared_nodes[name]), _settings(node)))
        elif len(where) != 1:
            problems.append('%s: hosted %d times (%s), not once' % (name, len(where), where))
        elif where[0][1] != node.type:
            problems.append('%s: hosted as %s, is %s' % (name, where[0][1], node.type))
        else:
            private = _under(per_drone['params'], name)
            instance = _flat(_at(document, name))
            if _strict(instance) != _strict(private):
                keys = sorted(k for k in set(instance) | set(private)
                              if _strict(instance.get(k, KeyError)) != _strict(private.get(k, KeyError)))
                problems.append('%s: fleet.params.yaml differs from its per-drone private parameters at %s'
                                % (name, ', '.join('%s (%r != %r)' % (k, instance.get(k, '<missing>'),
                                                                      private.get(k, '<missing>'))
                                                   for k in keys)))
    for name in sorted(set(shared_nodes) - set(pd_nodes)):
        problems.append('%s: a node the per-drone layout does not start' % name)
    for name in sorted(set(hosted) - set(pd_nodes)):
        problems.append('%s: an instance the per-drone layout does not start' % name)
    # every parameter, the instances' and everyone else's, as in the per-drone layout (plus the hosts' ~instances)
    instances = set(h + '/instances' for h in hosts)
    pd_params = dict((k, v) for k, v in per_drone['params'].items() if k not in ROSLAUNCH_PARAMS)
    sh_params = dict((k, v) for k, v in shared['params'].items() if k not in ROSLAUNCH_PARAMS and k not in instances)
    for key in sorted(set(pd_params) | set(sh_params)):
        if _strict(pd_params.get(key, KeyError)) != _strict(sh_params.get(key, KeyError)):
            problems.append('parameter %s: %r in the shared layout, %r per drone'
                            % (key, sh_params.get(key, '<missing>'), pd_params.get(key, '<missing>')))
    return problems


def _expand(path):
    config = roslaunch_config.load_config_default([path], None, verbose=False)
    return {'nodes': list(config.nodes), 'params': dict((k, p.value) for k, p in config.params.items())}


@pytest.fixture(scope='module')
def both_layouts(tmp_path_factory):
    """circles generated per drone and shared into one directory: (per_drone, shared, document, out)."""
    launcher = _launcher()
    out = str(tmp_path_factory.mktemp('layouts'))
    expanded = {}
    for layout in fleet_layout.LAYOUTS:
        ports = itertools.count(47001)      # the same telemetry ports in both layouts
        launcher.free_port = lambda: next(ports)
        path = launcher.generate('circles', 0, out, True, True, 100.0, 'log', False, log=lambda text: None,
                                 layout=layout)
        expanded[layout] = _expand(path)
        with open(path) as f:
            expanded[layout]['xml'] = f.read()
    with open(os.path.join(out, 'fleet.params.yaml')) as f:
        document = yaml.safe_load(f)
    return expanded['per_drone'], expanded['shared'], document, out


def test_the_shared_layout_starts_the_per_drone_nodes_with_their_parameters(both_layouts):
    per_drone, shared, document, out = both_layouts
    assert differences(per_drone, shared, document) == []
    # what the comparison covered: three drones, every simulator, interface, mirror, controller and generator
    # hosted; the evaluators still processes; the per-drone launch the shared one was made from is the same
    hosted = [n for n in per_drone['nodes'] if fleet_layout.host_of(n)]
    assert len(per_drone['nodes']) == 18 and len(hosted) == 15
    assert sorted(fleet_layout.full_name(n) for n in shared['nodes']) == [
        '/anafi1/evaluator', '/anafi2/evaluator', '/anafi3/evaluator', '/fleet_drones', '/fleet_ground_truth']
    assert all(_under(per_drone['params'], fleet_layout.full_name(n)) for n in hosted)
    with open(os.path.join(out, 'fleet.per_drone.launch')) as f:
        assert f.read() == per_drone['xml']


def _mutated(both_layouts, change):
    per_drone, shared, document, _ = copy.deepcopy(both_layouts)
    change(per_drone, shared, document)
    return differences(per_drone, shared, document)


def _set_gain(per_drone, shared, document):
    document['anafi2']['pid_framework']['x_outer']['Kp'] += 0.01


def _int_for_float(per_drone, shared, document):
    sim = document['anafi3']['anafi_sim']
    sim['brake_altitude_gain'] = int(sim['brake_altitude_gain'])     # 1.0 -> 1: the same number, another type


def _drop_instance(per_drone, shared, document):
    key = '/fleet_ground_truth/instances'
    shared['params'][key] = [i for i in shared['params'][key] if i['name'] != '/anafi3/gazebo_mirror']


def _host_twice(per_drone, shared, document):
    key = '/fleet_ground_truth/instances'
    shared['params'][key] = shared['params'][key] + [{'name': '/anafi1/anafi_sim', 'type': 'anafi_sim_node.py'}]


def _extra_node(per_drone, shared, document):
    shared['nodes'].append(copy.copy(shared['nodes'][-1]))
    shared['nodes'][-1].namespace = '/anafi4/'


def _other_setting(per_drone, shared, document):
    evaluator = next(n for n in shared['nodes'] if n.type == 'evaluator.py')
    evaluator.respawn = True


def _other_param(per_drone, shared, document):
    shared['params']['/anafi1/evaluator/out_dir'] = '/elsewhere'


@pytest.mark.parametrize('change, problem', [
    (_set_gain, 'pid_framework: fleet.params.yaml differs from its per-drone private parameters at x_outer/Kp'),
    (_int_for_float, '/anafi3/anafi_sim: fleet.params.yaml differs'),
    (_drop_instance, '/anafi3/gazebo_mirror: hosted 0 times'),
    (_host_twice, '/anafi1/anafi_sim: hosted 2 times'),
    (_extra_node, '/anafi4/evaluator: a node the per-drone layout does not start'),
    (_other_setting, 'evaluator: started with other settings'),
    (_other_param, 'parameter /anafi1/evaluator/out_dir'),
])
def test_the_comparison_catches_a_changed_layout(both_layouts, change, problem):
    found = _mutated(both_layouts, change)
    assert any(problem in line for line in found), found
