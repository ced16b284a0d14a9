"""The rviz pieces that need no display: anafi_sim.mission.visualisation (trail, marker specs), its
parameter file, anafi_sim/config/anafi.rviz and rviz.launch agreeing with them. The screenshot itself:
test/ros/test_rviz.py."""
import math
import os
import xml.etree.ElementTree as ET

import pytest
import yaml

from anafi_sim import paths
from anafi_sim.mission.visualisation import COLOURS, DEFAULTS, Trail, markers
from conftest import ROOT


def test_trail_keeps_a_point_per_spacing():
    t = Trail(spacing=0.25, length=100.0, max_points=100)
    for i in range(40):                          # 40 samples 0.125 m apart (exact in binary): 5 m
        t.add(float(i), (0.125 * i, 0.0, 5.0))
    assert [p[0] for p in t.points()] == [0.25 * k for k in range(20)]


def test_trail_forgets_old_points_and_bounds_its_size():
    t = Trail(spacing=0.0, length=10.0, max_points=1000)
    for i in range(30):
        t.add(float(i), (float(i), 0.0, 0.0))
    assert [p[0] for p in t.points()] == [float(i) for i in range(19, 30)]   # the last 10 s, ends included
    for i in range(30, 100):                     # hovering at the last point: the trail stays
        t.add(float(i), (29.0, 0.0, 0.0))
    assert len(t) == 11
    small = Trail(spacing=0.0, length=100.0, max_points=5)
    for i in range(20):
        small.add(float(i), (float(i), 0.0, 0.0))
    assert [p[0] for p in small.points()] == [15.0, 16.0, 17.0, 18.0, 19.0]


def test_trail_refuses_garbage_and_clears_when_time_goes_back():
    t = Trail(spacing=0.0)
    assert t.add(1.0, (0.0, 0.0, 1.0))
    assert not t.add(2.0, (float('nan'), 0.0, 1.0))
    assert not t.add(float('inf'), (0.0, 0.0, 1.0))
    assert t.refused == 2 and len(t) == 1
    t.add(3.0, (1.0, 0.0, 1.0))
    assert t.add(0.5, (2.0, 0.0, 1.0))           # simulation restarted
    assert t.cleared == 1 and t.points() == [(2.0, 0.0, 1.0)]
    with pytest.raises(ValueError):
        Trail(spacing=-1.0)


def test_marker_specs_of_a_drone():
    trail, ref = Trail(spacing=0.0), Trail(spacing=0.0)
    for i in range(3):
        trail.add(float(i), (i, 0.0, 1.0))
        ref.add(float(i), (i, 1.0, 1.0))
    specs = markers('anafi2', trail, ref, predicted=[(0, 0, 1), (1, 1, 1)], waypoint=((1.0, 2.0, 3.0), math.pi / 2))
    by = dict(((s.ns, s.id), s) for s in specs)
    assert set(by) == {('anafi2/trail', 0), ('anafi2/reference', 0), ('anafi2/predicted', 0),
                       ('anafi2/waypoint', 0), ('anafi2/waypoint', 1)}
    assert by[('anafi2/trail', 0)].points == trail.points() and by[('anafi2/trail', 0)].colour == COLOURS['trail']
    assert by[('anafi2/waypoint', 0)].kind == 'sphere' and by[('anafi2/waypoint', 0)].points == [(1.0, 2.0, 3.0)]
    tail, head = by[('anafi2/waypoint', 1)].points       # yaw 90 deg: the arrow points along +y (ENU)
    assert head[0] == pytest.approx(tail[0]) and head[1] == pytest.approx(tail[1] + 1.0)
    # nothing to draw: no specs (a single point is no line)
    lone = Trail()
    lone.add(0.0, (0.0, 0.0, 0.0))
    assert markers('anafi', lone, Trail()) == []


def test_colours_are_told_apart_by_the_screenshot_test():
    """test_rviz.py counts pixels within 40 per channel of each colour: the colours must be further apart,
    and from the tf axes' pure red / green / blue."""
    rgb = dict((k, [255 * c for c in v[:3]]) for k, v in COLOURS.items())
    rgb.update(axis_red=[255, 0, 0], axis_green=[0, 255, 0], axis_blue=[0, 0, 255])
    names = sorted(rgb)
    for i, a in enumerate(names):
        for b in names[i + 1:]:
            assert max(abs(x - y) for x, y in zip(rgb[a], rgb[b])) > 2 * 40, (a, b)


def test_parameter_file_agrees_with_the_defaults():
    with open(paths.config_path('visualisation.yaml')) as f:
        assert yaml.safe_load(f) == DEFAULTS


def test_rviz_config_shows_the_markers_model_and_frames():
    with open(paths.config_path('anafi.rviz')) as f:
        config = yaml.safe_load(f)
    manager = config['Visualization Manager']
    assert manager['Global Options']['Fixed Frame'] == 'world'
    displays = dict((d['Class'], d) for d in manager['Displays'])
    assert displays['rviz/MarkerArray']['Marker Topic'] == '/visualisation/markers'
    assert displays['rviz/RobotModel']['Robot Description'] == '/anafi/robot_description'
    assert displays['rviz/RobotModel']['TF Prefix'] == 'anafi'
    assert displays['rviz/TF']['Enabled']
    launch = ET.parse(os.path.join(ROOT, 'anafi_sim', 'launch', 'rviz.launch')).getroot()
    nodes = dict((n.get('type'), n) for n in launch.iter('node'))
    assert {'robot_state_publisher', 'visualisation_node.py', 'rviz'} <= set(nodes)
    assert 'anafi.rviz' in launch.find("arg[@name='config']").get('default')
    assert 'anafi.urdf' in launch.find("arg[@name='urdf_file']").get('default')
