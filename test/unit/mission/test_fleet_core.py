"""anafi_sim.mission.fleet: fleet files -> drones, shifted scenarios, the generated launch XML, aggregator."""
import os
import re
import shutil
import subprocess
import sys
import xml.etree.ElementTree as ET

import pytest
import yaml

from anafi_sim.mission import fleet as fl
from anafi_sim.mission.trajectory import list_scenarios, load_scenario, scenario_from_dict
from conftest import repo_path


def drones_of(d, drones=0):
    return fl.fleet_from_dict(d, 'test', drones).drones


def test_every_shipped_fleet_file_loads():
    names = sorted(os.path.splitext(f)[0] for f in os.listdir(fl.FLEET_DIR) if f.endswith('.yaml'))
    assert {'circles', 'airship_formation', 'mixed_sphinx'} <= set(names)
    for name in names:
        fleet = fl.load_fleet(name)
        assert fleet.drones
        for drone in fleet.drones:
            fl.drone_scenario(drone)   # checked by the trajectory module


def test_defaults_fill_in_and_drone_keys_win():
    d = drones_of({'defaults': {'controller': 'pid', 'scenario': 'static_wp0'},
                   'drones': [{'name': 'a'}, {'name': 'b', 'controller': 'mpc', 'start': [0, 5]}]})
    assert [x.controller for x in d] == ['pid', 'mpc']
    assert d[0].scenario == d[1].scenario == 'static_wp0'
    assert d[1].start == (0.0, 5.0, 0.0)


def test_start_defaults_to_the_offset():
    d = drones_of({'drones': [{'name': 'a', 'waypoint': [1, 2, 3], 'offset': [4, -5, 1]}]})
    assert d[0].start == (4.0, -5.0, 0.0)
    assert d[0].waypoint == (1.0, 2.0, 3.0, 0.0)


def test_row_of_n_identical_drones():
    d = drones_of({'defaults': {'scenario': 'circle_r2_v1', 'offset': [1, 0, 0]}, 'row': {'spacing': 4.0}}, 5)
    assert [x.name for x in d] == ['anafi%d' % i for i in range(1, 6)]
    assert [x.offset for x in d] == [(1.0, 4.0 * i, 0.0) for i in range(5)]
    assert [x.start[:2] for x in d] == [(1.0, 4.0 * i) for i in range(5)]


@pytest.mark.parametrize('bad, message', [
    ({'drones': [{'name': 'a', 'scenario': 'static_wp0', 'waypoint': [1, 2, 3]}]}, 'exactly one of'),
    ({'drones': [{'name': 'a'}]}, 'exactly one of'),
    ({'drones': [{'name': '1a', 'scenario': 'x'}]}, 'ROS name'),
    ({'drones': [{'name': 'a', 'scenario': 'static_wp0', 'controller': 'lqr'}]}, 'controller'),
    ({'drones': [{'name': 'a', 'scenario': 'static_wp0', 'colour': 'red'}]}, 'unknown field'),
    ({'drones': [{'name': 'a', 'scenario': 'static_wp0'}, {'name': 'a', 'scenario': 'static_wp0',
                                                          'start': [5, 0]}]}, 'Gazebo model a'),
    ({'drones': [{'name': 'a', 'scenario': 'static_wp0'}, {'name': 'a_camera', 'scenario': 'static_wp0',
                                                          'start': [5, 0]}]}, 'Gazebo model a_camera'),
    ({'drones': [{'name': 'airship', 'scenario': 'static_wp0'}]}, 'taken by the scene'),
    ({'drones': [{'name': 'a', 'scenario': 'static_wp0'}, {'name': 'b', 'scenario': 'static_wp0',
                                                          'start': [0.5, 0]}]}, 'apart'),
    ({'drones': [{'name': 'a', 'scenario': 'static_wp0', 'telemetry_port': 9061},
                 {'name': 'b', 'scenario': 'static_wp0', 'start': [5, 0], 'telemetry_port': 9061}]}, 'ports'),
    ({'drones': [{'name': 'a', 'scenario': 'static_wp0', 'source': 'sphinx'},
                 {'name': 'b', 'scenario': 'static_wp0', 'start': [5, 0], 'source': 'sphinx'}]}, 'at most one'),
    ({'drones': [{'name': 'a', 'scenario': 'static_wp0', 'telemetry_command': 'x'}]}, 'sphinx only'),
    ({'drones': [{'name': 'a', 'scenario': 'static_wp0', 'source': 'sphinx',
                  'telemetry_command': "sh -c 'id > /tmp/pwned'"}]}, "refused to run 'sh'"),
    ({'drones': [{'name': 'a', 'scenario': 'static_wp0', 'source': 'sphinx',
                  'telemetry_command': 'tlm-data-logger -r 0 inet:127.0.0.1:9060 --exec id'}]}, 'inet:HOST:PORT'),
    ({'drones': [{'name': 'a', 'target': {'model': 'airship', 'yaw_mode': 'spin'}}]}, 'yaw_mode'),
    ({'drones': [{'name': 'a', 'waypoint': [1, 2, float('nan')]}]}, 'finite'),
    ({'drones': []}, 'non-empty'),
])
def test_bad_fleets_are_refused_with_a_reason(bad, message):
    with pytest.raises(ValueError, match=message):
        fl.fleet_from_dict(bad, 'bad')


def test_a_missing_scenario_is_refused():
    drone = drones_of({'drones': [{'name': 'a', 'scenario': 'no_such_scenario'}]})[0]
    with pytest.raises(ValueError, match='no scenario file'):
        fl.drone_scenario(drone)


@pytest.mark.parametrize('name', list_scenarios())
def test_a_shifted_scenario_is_the_scenario_moved_by_the_offset(name):
    offset = (3.0, -7.5, 1.25)
    drone = drones_of({'drones': [{'name': 'a', 'scenario': name, 'offset': list(offset)}]})[0]
    original = load_scenario(name)
    shifted = scenario_from_dict(fl.drone_scenario(drone))
    assert shifted.duration == original.duration
    assert shifted.measure_window == original.measure_window
    for k in range(60):
        t = k * original.duration / 59.0
        a, b = original.waypoint(t), shifted.waypoint(t)
        assert b.x == pytest.approx(a.x + offset[0]) and b.y == pytest.approx(a.y + offset[1])
        assert b.z == pytest.approx(a.z + offset[2])
        assert (b.vx, b.vy, b.vz, b.yaw) == pytest.approx((a.vx, a.vy, a.vz, a.yaw))


def test_per_axis_trajectories_shift_every_component_kind():
    traj = {'type': 'per_axis', 'x': 1.0, 'y': {'type': 'ramp', 'start': 2.0, 'speed': 1.0},
            'z': {'type': 'sine', 'offset': 5.0, 'amplitude': 1.0, 'omega': 1.0}}
    moved = fl.offset_trajectory_dict(traj, (1.0, 2.0, 3.0))
    assert moved['x'] == 2.0 and moved['y']['start'] == 4.0 and moved['z']['offset'] == 8.0
    only_x = fl.offset_trajectory_dict({'type': 'per_axis', 'x': 0.0}, (0.0, 2.0, 0.0))
    assert only_x['y'] == 2.0 and only_x['z'] == 0.0
    with pytest.raises(ValueError):
        fl.offset_trajectory_dict({'type': 'spiral'}, (0.0, 0.0, 0.0))


def test_a_waypoint_becomes_a_static_scenario_at_the_shifted_point():
    drone = drones_of({'drones': [{'name': 'a', 'waypoint': [1, 2, 3, 90], 'offset': [10, 0, 0]}]})[0]
    scenario = scenario_from_dict(fl.drone_scenario(drone))
    w = scenario.waypoint(100.0)
    assert (w.x, w.y, w.z, w.yaw) == (11.0, 2.0, 3.0, 90.0)


def _generated(fleet, **kw):
    ports = dict((d.name, 9100 + i) for i, d in enumerate(fleet.drones) if d.source == 'sim')
    files = dict((d.name, '/tmp/%s.scenario.yaml' % d.name) for d in fleet.drones if d.target is None)
    return ET.fromstring(fl.launch_xml(fleet, ports, files, '/tmp/out', **kw))


def _includes(root, launch):
    return [dict((a.get('name'), a.get('value')) for a in inc.findall('arg'))
            for inc in root.findall('include') if inc.get('file').endswith('/' + launch)]


def test_the_launch_xml_includes_each_drones_launch_files_in_its_namespace():
    fleet = fl.load_fleet('circles')
    root = _generated(fleet)
    sims = _includes(root, 'sim.launch')
    assert [s['drone_name'] for s in sims] == ['anafi1', 'anafi2', 'anafi3']
    assert [s['telemetry_port'] for s in sims] == ['9100', '9101', '9102']
    assert [float(s['initial_y']) for s in sims] == [0.0, 6.0, 12.0]
    assert [m['drone_name'] for m in _includes(root, 'spawn_anafi.launch')] == ['anafi1', 'anafi2', 'anafi3']
    assert [m['drone_name'] for m in _includes(root, 'mpc.launch')] == ['anafi1', 'anafi3']
    assert _includes(root, 'pid.launch') == [{'drone_name': 'anafi2', 'output': 'log', 'mode': 'single'}]
    groups = root.findall('group')
    assert [g.get('ns') for g in groups] == ['anafi1', 'anafi2', 'anafi3']
    for g in groups:
        gen = g.find("node[@type='trajectory_generator.py']")
        assert gen.find("param[@name='scenario_file']").get('value') == '/tmp/%s.scenario.yaml' % g.get('ns')
        ev = g.find("node[@type='evaluator.py']")
        assert ev.find("param[@name='csv_file']").get('value') == '/tmp/out/%s.csv' % g.get('ns')
    bare = _generated(fleet, evaluate=False, mirror=False)
    assert not bare.findall(".//node[@type='evaluator.py']") and not _includes(bare, 'spawn_anafi.launch')
    assert not root.findall(".//node[@name='diagnostic_aggregator']")


def test_targets_run_a_model_follower_and_sphinx_drones_the_sphinx_chain():
    root = _generated(fl.load_fleet('airship_formation'))
    followers = root.findall(".//node[@type='model_follower.py']")
    assert len(followers) == 3 and not root.findall(".//node[@type='trajectory_generator.py']")
    offsets = [yaml.safe_load(f.find('rosparam').text) for f in followers]
    assert offsets == [[0.0, 6.0, -2.0], [0.0, -6.0, -2.0], [-8.0, 0.0, -2.0]]
    mixed = _generated(fl.load_fleet('mixed_sphinx'))
    sphinx = _includes(mixed, 'sphinx_gazebo.launch')
    assert len(sphinx) == 1 and sphinx[0]['drone_name'] == 'sphinx' and sphinx[0]['world'] == 'false'
    assert 'tlm-data-logger' in sphinx[0]['telemetry_command']
    assert [s['drone_name'] for s in _includes(mixed, 'sim.launch')] == ['anafi2', 'anafi3']


def test_a_preview_mpc_drone_gets_the_preview_mpc_launch():
    fleet = fl.fleet_from_dict({'defaults': {'scenario': 'circle_r2_v1'},
                                'drones': [{'name': 'a', 'controller': 'preview_mpc'}, {'name': 'b', 'start': [0, 6]}]}, 'pv')
    root = _generated(fleet)
    assert [i['drone_name'] for i in _includes(root, 'preview_mpc.launch')] == ['a']
    assert [i['drone_name'] for i in _includes(root, 'mpc.launch')] == ['b']


def test_launch_xml_needs_a_port_per_simulated_drone():
    fleet = fl.load_fleet('circles')
    with pytest.raises(ValueError, match='telemetry port'):
        fl.launch_xml(fleet, {}, {}, '/tmp')


# ------------------------------------------------------------------------------------------ diagnostics
STATUS_NAMES = {   # the names the nodes give their statuses (docs/nodes.md), for drone NAME
    'simulator': ['anafi_sim: simulated Anafi (NAME)'],
    'interface': ['/NAME/interface: ground truth interface'],
    'mirror': ['/NAME/gazebo_mirror: gazebo mirror'],
    'controller': ['mpc_controller: /NAME/mpc_controller', 'pid_framework: /NAME/pid_framework',
                   'preview_mpc: /NAME/preview_mpc_controller',
                   'pid_controller: /NAME/pid/x_outer', 'pid_command: /NAME/pid_command',
                   'pid_relative_state: /NAME/pid_relative_state'],
    'target': ['trajectory_generator: /NAME/trajectory_generator', '/NAME/model_follower: following airship',
               '/NAME/evaluator: tracking error'],
}


def test_the_aggregator_groups_each_drones_components_and_only_its_own():
    fleet = fl.fleet_from_dict({'defaults': {'scenario': 'static_wp0'}}, 'agg', drones=11)
    analyzers = fl.aggregator_analyzers(fleet)['drones']['analyzers']
    assert sorted(analyzers) == sorted(d.name for d in fleet.drones)
    for name, group in analyzers.items():
        for component, analyzer in group['analyzers'].items():
            pattern = re.compile(analyzer['regex'])
            for other in ('anafi1', 'anafi11', name):
                for status in STATUS_NAMES[component]:
                    matched = bool(pattern.match(status.replace('NAME', other)))
                    assert matched == (other == name), (component, analyzer['regex'], other)
            for comp2, statuses in STATUS_NAMES.items():
                if comp2 != component:
                    assert not any(pattern.match(s.replace('NAME', name)) for s in statuses)


def test_the_component_analyzers_match_every_drone():
    with open(fl.AGGREGATOR_CONFIG) as f:
        config = yaml.safe_load(f)
    for component, analyzer in config['analyzers']['components']['analyzers'].items():
        for status in STATUS_NAMES[component]:
            assert re.match(analyzer['regex'], status.replace('NAME', 'left'))
    assert re.match(config['analyzers']['world']['regex'], 'kinematic_world: world')


def test_the_generated_launch_starts_the_aggregator_when_asked():
    fleet = fl.load_fleet('circles')
    root = _generated(fleet, aggregator_file='/tmp/agg.yaml')
    node = root.find("node[@name='diagnostic_aggregator']")
    assert node.get('pkg') == 'diagnostic_aggregator'
    files = [r.get('file') for r in node.findall('rosparam')]
    assert files[0].endswith('config/diagnostics_aggregator.yaml') and files[1] == '/tmp/agg.yaml'


# ------------------------------------------------------------------------------------------ the launcher tool
SCRIPT = repo_path('anafi_sim', 'scripts', 'fleet_launcher.py')


@pytest.mark.skipif(shutil.which('roslaunch') is None, reason='roslaunch not on PATH (source env.bash)')
@pytest.mark.parametrize('fleet, drones, nodes', [
    ('circles', 0, ['/anafi1/anafi_sim', '/anafi2/pid_framework', '/anafi3/mpc_controller']),
    ('circles', 5, ['/anafi5/gazebo_mirror', '/anafi5/trajectory_generator']),
    ('airship_formation', 0, ['/left/model_follower', '/right/mpc_controller', '/behind/evaluator']),
    # mixed mode: the Sphinx drone has an interface and a mirror but no simulator
    ('mixed_sphinx', 0, ['/sphinx/interface', '/sphinx/gazebo_mirror', '/anafi2/anafi_sim']),
])
def test_the_generated_launch_file_parses_with_roslaunch(tmp_path, fleet, drones, nodes):
    out = subprocess.run([sys.executable, SCRIPT, fleet, '--drones', str(drones), '--out-dir', str(tmp_path),
                          '--write-only', '--aggregator', 'true', '--max-drones', '10'],   # the cap is the machine's own
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, universal_newlines=True, check=True)
    path = out.stdout.strip()
    listed = subprocess.run(['roslaunch', '--nodes', path], stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                            universal_newlines=True)
    assert listed.returncode == 0, listed.stdout
    names = listed.stdout.split()
    for node in nodes + ['/diagnostic_aggregator']:
        assert node in names
    if fleet == 'mixed_sphinx':
        assert '/sphinx/anafi_sim' not in names


def test_the_launcher_tool_refuses_a_bad_fleet_file(tmp_path):
    bad = tmp_path / 'bad.yaml'
    bad.write_text('drones: [{name: a}]\n')
    out = subprocess.run([sys.executable, SCRIPT, str(bad), '--print'], stdout=subprocess.PIPE,
                         stderr=subprocess.PIPE, universal_newlines=True)
    assert out.returncode == 2 and 'exactly one of' in out.stderr and not out.stdout


def test_a_former_fleet_name_still_loads():
    assert fl.fleet_path('three_circles') == fl.fleet_path('circles')
    assert fl.load_fleet('three_circles', 4).name == fl.load_fleet('circles', 4).name == 'circles'
