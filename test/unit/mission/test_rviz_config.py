"""The fleet's rviz view (anafi_sim.mission.rviz_config, fleet_launcher.py --rviz): one model and one marker
display per drone, a camera that frames the whole fleet. anafi.rviz alone is drawn for the drone 'anafi': with
anafi1..3 its model display has no robot description (red) and its view orbits anafi/base_link (absent: the
origin). The screenshot under Xvfb: test/ros/test_fleet_rviz.py."""
import math
import os
import xml.etree.ElementTree as ET

import pytest
import yaml

from anafi_sim import paths
from anafi_sim.mission import rviz_config
from anafi_sim.mission.fleet import drone_scenario, launch_xml, load_fleet
from anafi_sim.mission.trajectory import scenario_from_dict
from conftest import ROOT



def fleet_and_scenarios(name='circles', drones=0):
    fleet = load_fleet(name, drones)
    scenarios = {}
    for drone in fleet.drones:
        data = drone_scenario(drone)
        if data is not None:
            scenarios[drone.name] = scenario_from_dict(data)
    return fleet, scenarios


def displays_by_drone(config):
    groups = [d for d in config['Visualization Manager']['Displays'] if d['Class'] == 'rviz/Group']
    return dict((g['Name'], dict((d['Class'], d) for d in g['Displays'])) for g in groups)


def test_the_single_drone_config_does_not_show_a_fleet():
    """The finding: anafi.rviz binds its one model to /anafi and orbits anafi/base_link."""
    with open(paths.config_path('anafi.rviz')) as f:
        config = yaml.safe_load(f)
    models = [d for d in config['Visualization Manager']['Displays'] if d['Class'] == 'rviz/RobotModel']
    assert [m['Robot Description'] for m in models] == ['/anafi/robot_description']
    assert config['Visualization Manager']['Views']['Current']['Target Frame'] == 'anafi/base_link'


@pytest.mark.parametrize('name,drones', [('circles', 0), ('circles', 3), ('circles', 5),
                                         ('airship_formation', 0)])
def test_fleet_config_has_a_model_and_markers_per_drone_and_a_fixed_view(name, drones):
    fleet, scenarios = fleet_and_scenarios(name, drones)
    text, view = rviz_config.fleet_rviz(fleet, scenarios)
    config = yaml.safe_load(text)
    by_drone = displays_by_drone(config)
    assert sorted(by_drone) == sorted(d.name for d in fleet.drones)
    for drone, displays in by_drone.items():
        assert displays['rviz/RobotModel']['Robot Description'] == '/%s/robot_description' % drone
        assert displays['rviz/RobotModel']['TF Prefix'] == drone
        assert displays['rviz/MarkerArray']['Marker Topic'] == '/%s/visualisation/markers' % drone
    top = [d['Class'] for d in config['Visualization Manager']['Displays']]
    assert 'rviz/RobotModel' not in top and 'rviz/MarkerArray' not in top      # only inside the groups
    current = config['Visualization Manager']['Views']['Current']
    assert current['Target Frame'] == '<Fixed Frame>'
    assert config['Visualization Manager']['Global Options']['Fixed Frame'] == 'world'
    assert current['Distance'] == pytest.approx(view['distance'], abs=1e-3)


@pytest.mark.parametrize('drones', [0, 2, 3, 8])
def test_every_drone_and_its_path_is_inside_the_view(drones):
    """Projected with rviz's camera (45 deg vertical field of view) into the 3D view's size, every take-off
    point and every waypoint of every drone lands inside the view, and the drones are apart on the screen."""
    fleet, scenarios = fleet_and_scenarios('circles', drones)
    text, view = rviz_config.fleet_rviz(fleet, scenarios)
    width, height = rviz_config.view_size(yaml.safe_load(text))
    points = rviz_config.fleet_points(fleet, scenarios)
    for p in points:
        pixel = rviz_config.project(view, p, (width, height))
        assert pixel is not None and 0 <= pixel[0] <= width and 0 <= pixel[1] <= height, (p, pixel)
    starts = [rviz_config.project(view, (d.start[0], d.start[1], 1.0), (width, height)) for d in fleet.drones]
    gaps = [math.hypot(a[0] - b[0], a[1] - b[1]) for i, a in enumerate(starts) for b in starts[i + 1:]]
    assert min(gaps) > 30.0, starts        # px: each drone's model found on its own


def test_projection_puts_the_focal_point_in_the_middle_and_keeps_left_and_right():
    view = {'focal': (0.0, 6.0, 3.0), 'distance': 10.0, 'yaw': math.pi, 'pitch': 0.5}
    assert rviz_config.project(view, view['focal'], (800, 600)) == pytest.approx((400.0, 300.0))
    left = rviz_config.project(view, (0.0, 8.0, 3.0), (800, 600))    # eye at -x looking +x: +y is on the left
    assert left[0] < 400.0
    up = rviz_config.project(view, (0.0, 6.0, 5.0), (800, 600))
    assert up[1] < 300.0
    behind = (view['focal'][0] - 20.0, 6.0, 3.0)                      # behind the eye
    assert rviz_config.project(view, behind, (800, 600)) is None


def test_fleet_view_refuses_nonsense():
    with pytest.raises(ValueError):
        rviz_config.fleet_view([], 1.5)
    with pytest.raises(ValueError):
        rviz_config.fleet_view([(0.0, float('nan'), 1.0)], 1.5)
    with pytest.raises(ValueError):
        rviz_config.fleet_config([], [(0.0, 0.0, 1.0)])
    one = rviz_config.fleet_view([(0.0, 0.0, 1.0)], 1.5)
    assert one['distance'] == rviz_config.MIN_DISTANCE


def test_generated_launch_starts_rviz_once_on_the_fleet_view(tmp_path):
    fleet = load_fleet('circles', 3)
    ports = dict((d.name, 9100 + i) for i, d in enumerate(fleet.drones))
    files = dict((d.name, str(tmp_path / ('%s.yaml' % d.name))) for d in fleet.drones)
    rviz_file = str(tmp_path / 'fleet.rviz')
    root = ET.fromstring(launch_xml(fleet, ports, files, str(tmp_path), rviz=True, rviz_file=rviz_file))
    rviz_nodes = [n for n in root.iter('node') if n.get('pkg') == 'rviz']
    assert len(rviz_nodes) == 1 and rviz_nodes[0].get('args') == '-d ' + rviz_file
    includes = [i for i in root.iter('include') if i.get('file').endswith('rviz.launch')]
    assert len(includes) == 3
    for inc in includes:
        args = dict((a.get('name'), a.get('value')) for a in inc.iter('arg'))
        assert args['gui'] == 'false' and args['markers_topic'] == 'visualisation/markers'
    off = ET.fromstring(launch_xml(fleet, ports, files, str(tmp_path), rviz=False))
    assert not [n for n in off.iter('node') if n.get('pkg') == 'rviz']
    # fleet.launch has no rviz of its own (it would show anafi.rviz, drawn for the drone 'anafi')
    static = ET.parse(os.path.join(ROOT, 'anafi_sim', 'launch', 'fleet.launch')).getroot()
    assert not [n for n in static.iter('node') if n.get('pkg') == 'rviz']


def test_fleet_launcher_writes_the_view(tmp_path):
    import subprocess
    import sys
    script = os.path.join(ROOT, 'anafi_sim', 'scripts', 'fleet_launcher.py')
    out = subprocess.run([sys.executable, script, 'circles', '--drones', '3', '--rviz', 'true', '--out-dir',
                          str(tmp_path), '--write-only'], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                         universal_newlines=True, check=True)
    assert out.stdout.strip() == str(tmp_path / 'fleet.launch')
    with open(str(tmp_path / 'fleet.rviz')) as f:
        config = yaml.safe_load(f)
    assert sorted(displays_by_drone(config)) == ['anafi1', 'anafi2', 'anafi3']
