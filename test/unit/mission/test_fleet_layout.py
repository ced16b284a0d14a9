"""The shared layout of a fleet (anafi_sim/mission/fleet_layout.py): which nodes a host runs, the XML, the
parameters; a host's ~instances."""
import xml.etree.ElementTree as ET

import pytest
import yaml

from anafi_sim.mission import fleet_layout as fl
from anafi_sim.mission.fleet import load_fleet
from conftest import repo_path


def node(type_, name, ns='/anafi1/', package='anafi_sim', **kw):
    fields = dict(package=package, type=type_, name=name, namespace=ns, args='', output='log', respawn=True,
                  respawn_delay=1.0, required=False, launch_prefix=None, cwd=None, env_args=[], remap_args=[])
    fields.update(kw)
    return fl.NodeSpec(**fields)


def test_hosts_run_hostable_types_each_once_and_their_classes_exist():
    types = [t for ts in fl.HOSTS.values() for t in ts]
    assert len(types) == len(set(types))
    assert set(types) == set(fl.HOSTABLE)
    for script, (module, cls, _) in fl.HOSTABLE.items():
        with open(repo_path(*module.split('.')) + '.py') as f:
            assert 'class %s(' % cls in f.read(), (module, cls)
        with open(repo_path('anafi_sim', 'scripts', script)) as f:     # the type is the script of that node
            assert 'from %s import main' % module in f.read(), (script, module)


def test_host_of_keeps_nodes_with_their_own_settings_apart():
    assert fl.host_of(node('interface_node.py', 'interface')) == 'fleet_ground_truth'
    assert fl.host_of(node('anafi_sim_node.py', 'anafi_sim')) == 'fleet_drones'
    assert fl.host_of(node('evaluator.py', 'evaluator')) is None
    assert fl.host_of(node('pid_controller.py', 'x_outer')) is None
    assert fl.host_of(node('interface_node.py', 'interface', remap_args=[('a', 'b')])) is None
    assert fl.host_of(node('interface_node.py', 'interface', launch_prefix='gdb')) is None
    assert fl.host_of(node('interface_node.py', 'interface', args='--x')) is None
    assert fl.host_of(node('interface_node.py', 'interface', package='other')) is None


def test_shared_layout_xml_hosts_instances_in_launch_order_and_keeps_the_rest():
    nodes = [node('anafi_sim_node.py', 'anafi_sim'), node('interface_node.py', 'interface'),
             node('evaluator.py', 'evaluator', respawn=False, remap_args=[('x', 'y')]),
             node('anafi_sim_node.py', 'anafi_sim', ns='/anafi2/')]
    params = {'/anafi1/anafi_sim/rate': 200.0, '/anafi2/anafi_sim/rate': 200.0, '/use_sim_time': False}
    xml, document = fl.shared_layout(nodes, params, '/tmp/p.yaml', title='fleet t')
    root = ET.fromstring(xml.split('\n', 1)[1])
    assert root.find('rosparam').get('file') == '/tmp/p.yaml'
    hosts = dict((n.get('name'), yaml.safe_load(n.find('rosparam').text)) for n in root.findall('node')
                 if n.get('type') == 'fleet_host.py')
    assert hosts == {'fleet_drones': [{'name': '/anafi1/anafi_sim', 'type': 'anafi_sim_node.py'},
                                      {'name': '/anafi2/anafi_sim', 'type': 'anafi_sim_node.py'}],
                     'fleet_ground_truth': [{'name': '/anafi1/interface', 'type': 'interface_node.py'}]}
    others = [n for n in root.findall('node') if n.get('type') != 'fleet_host.py']
    assert [(n.get('type'), n.get('ns'), n.find('remap').get('to')) for n in others] == [
        ('evaluator.py', '/anafi1/', 'y')]
    assert others[0].get('respawn') is None
    assert document == {'anafi1': {'anafi_sim': {'rate': 200.0}}, 'anafi2': {'anafi_sim': {'rate': 200.0}},
                        'use_sim_time': False}


def test_a_host_with_no_instance_is_not_started():
    xml, _ = fl.shared_layout([node('interface_node.py', 'interface')], {}, 'p.yaml')
    assert 'fleet_drones' not in xml.split('-->', 1)[1] and 'name="fleet_ground_truth"' in xml


@pytest.mark.parametrize('raw, problem', [
    (None, 'non-empty list'), ([], 'non-empty list'), (['x'], '{name, type}'),
    ([{'name': 'anafi1/interface', 'type': 'interface_node.py'}], 'global ROS name'),
    ([{'name': '/a/i', 'type': 'interface_node.py'}, {'name': '/a/i', 'type': 'interface_node.py'}], 'given once'),
    ([{'name': '/a/i', 'type': 'evaluator.py'}], 'type must be one of'),
    ([{'name': '/a/i', 'type': 'interface_node.py', 'extra': 1}], '{name, type}')])
def test_read_instances_refuses_bad_entries(raw, problem):
    with pytest.raises(ValueError, match=problem):
        fl.read_instances(raw)
    assert fl.read_instances([{'name': '/a/i', 'type': 'interface_node.py'}]) == [('/a/i', 'interface_node.py')]


def test_layout_in_the_fleet_file(tmp_path):
    path = tmp_path / 'f.yaml'
    path.write_text('drones: [{name: a1, waypoint: [0, 0, 1, 0]}]\nlayout: shared\n')
    assert load_fleet(str(path)).layout == 'shared'
    assert load_fleet('circles').layout == 'per_drone'
    path.write_text('drones: [{name: a1, waypoint: [0, 0, 1, 0]}]\nlayout: pooled\n')
    with pytest.raises(ValueError, match='layout must be one of per_drone, shared'):
        load_fleet(str(path))


def _ground_truth(n, world=True):
    out = [{'name': '/kinematic_world', 'type': 'kinematic_world_node.py'}] if world else []
    for i in range(1, n + 1):
        out += [{'name': '/anafi%d/interface' % i, 'type': 'interface_node.py'},
                {'name': '/anafi%d/gazebo_mirror' % i, 'type': 'gazebo_mirror_node.py'}]
    return out


def test_the_ground_truth_host_splits_by_its_limit_with_the_world_in_the_first():
    ten = {'fleet_ground_truth': 10, 'fleet_drones': 10}
    hosts = fl.split_by_drone({'fleet_ground_truth': _ground_truth(10)}, ten)
    assert list(hosts) == ['fleet_ground_truth'] and len(hosts['fleet_ground_truth']) == 21   # fits: one host
    assert list(fl.split_by_drone({'fleet_ground_truth': _ground_truth(25)})) == ['fleet_ground_truth']  # no limit
    hosts = fl.split_by_drone({'fleet_ground_truth': _ground_truth(25)}, ten)
    assert list(hosts) == ['fleet_ground_truth_1', 'fleet_ground_truth_2', 'fleet_ground_truth_3']
    first = [i['name'] for i in hosts['fleet_ground_truth_1']]
    assert first[0] == '/kinematic_world' and len(first) == 21 and '/anafi10/gazebo_mirror' in first
    assert [i['name'] for i in hosts['fleet_ground_truth_3']] == \
        ['/anafi%d/%s' % (d, r) for d in range(21, 26) for r in ('interface', 'gazebo_mirror')]
    every = [i['name'] for h in hosts.values() for i in h]
    assert sorted(every) == sorted(i['name'] for i in _ground_truth(25))           # each instance once
    # a world that comes after the drones in launch order still goes with the first group, counted as no drone
    late = _ground_truth(4, world=False) + [{'name': '/kinematic_world', 'type': 'kinematic_world_node.py'}]
    hosts = fl.split_by_drone({'fleet_ground_truth': late}, {'fleet_ground_truth': 2})
    assert [i['name'] for i in hosts['fleet_ground_truth_1']][-1] == '/kinematic_world'
    assert len(hosts['fleet_ground_truth_2']) == 4
    assert list(fl.split_by_drone({'fleet_ground_truth': late}, {'fleet_ground_truth': 4})) == ['fleet_ground_truth']


def test_drones_per_host_in_the_fleet_file(tmp_path):
    path = tmp_path / 'f.yaml'
    path.write_text('drones: [{name: a1, waypoint: [0, 0, 1, 0]}]\nlayout: shared\n'
                    'drones_per_host: {fleet_ground_truth: 2}\n')
    assert load_fleet(str(path)).drones_per_host == {'fleet_ground_truth': 2}
    assert load_fleet('circles').drones_per_host == {}
    for bad, problem in (('{fleet_world: 2}', 'not a host split by drone'), ('{fleet_drones: 0}', '>= 1'),
                         ('[2]', 'a mapping'), ('{fleet_drones: 2.5}', 'an integer')):
        path.write_text('drones: [{name: a1, waypoint: [0, 0, 1, 0]}]\ndrones_per_host: %s\n' % bad)
        with pytest.raises(ValueError, match=problem):
            load_fleet(str(path))


def test_the_file_wins_over_the_machine_per_host():
    machine = {'fleet_drones': 7, 'fleet_ground_truth': 8}
    assert fl.split_limits(machine) == machine
    assert fl.split_limits(machine, {'fleet_ground_truth': 2}) == {'fleet_drones': 7, 'fleet_ground_truth': 2}
    assert fl.split_limits(None, {'fleet_drones': 3}) == {'fleet_drones': 3}
