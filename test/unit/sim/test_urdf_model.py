"""URDF parsing: gravity / collision flags and sensors of the shipped models and of crafted strings."""
import os

import pytest

from anafi_sim.gazebo import urdf_model
from conftest import ROOT

URDF_DIR = os.path.join(ROOT, 'anafi_sim', 'urdf')


def _read(name):
    with open(os.path.join(URDF_DIR, name)) as f:
        return f.read()


def _robot(body):
    return '<?xml version="1.0"?><robot name="r">%s</robot>' % body


BOX = '<geometry><box size="0.1 0.2 0.3"/></geometry>'


@pytest.mark.parametrize('name', ['anafi.urdf', 'anafi_camera.urdf', 'airship.urdf'])
def test_shipped_models_have_gravity_off_and_no_collision(name):
    model = urdf_model.parse_urdf(_read(name))
    assert model.link_names, name
    assert model.gravity_links == []
    assert model.collision_links == []
    assert not model.has_gravity and not model.has_collisions
    massive = [link for link in model.links.values() if link.mass is not None]
    assert massive and all(0 < link.mass <= 0.01 and all(abs(v) <= 1e-4 for v in link.inertia) for link in massive)
    for link in model.links.values():     # a link shows something, or only holds the inertia of its parent
        assert link.visuals or (link.mass is not None and not link.collisions), link.name


def test_the_anafi_root_link_has_no_inertia_for_robot_state_publisher():
    """KDL (robot_state_publisher, rviz.launch) warns about a root link with an inertia: it is on a fixed child."""
    model = urdf_model.parse_urdf(_read('anafi.urdf'))
    assert model.root_link == 'base_link' and model.links['base_link'].mass is None
    assert model.links['base_link_inertia'].mass == 0.001 and not model.links['base_link_inertia'].visuals


def test_anafi_body_envelope_is_about_018_by_024_by_007():
    model = urdf_model.parse_urdf(_read('anafi.urdf'))
    lo = [float('inf')] * 3
    hi = [-float('inf')] * 3
    for g in model.links['base_link'].visuals:
        (x, y, z), rpy = g.origin
        if g.type == 'box':
            half = [s / 2.0 for s in g.size]
            if rpy[2]:  # yawed arms: bound by their half length in x and y
                half = [g.size[0] / 2.0, g.size[0] / 2.0, g.size[2] / 2.0]
        elif g.type == 'cylinder':
            half = [g.size[0], g.size[0], g.size[1] / 2.0]
        else:
            half = [g.size[0]] * 3
        for i, c in enumerate((x, y, z)):
            lo[i] = min(lo[i], c - half[i])
            hi[i] = max(hi[i], c + half[i])
    size = [h - l for h, l in zip(hi, lo)]
    assert size[0] == pytest.approx(0.18, abs=0.02)
    assert size[1] == pytest.approx(0.24, abs=0.02)
    assert size[2] == pytest.approx(0.07, abs=0.015)


def test_camera_model_carries_a_gazebo_ros_camera_with_anafi_like_intrinsics():
    model = urdf_model.parse_urdf(_read('anafi_camera.urdf'))
    assert len(model.sensors) == 1
    sensor = model.sensors[0]
    assert sensor.type == 'camera'
    assert sensor.link == 'camera_link'
    assert 'libgazebo_ros_camera.so' in sensor.plugins
    assert sensor.camera['horizontal_fov'] == pytest.approx(1.2043, abs=0.01)  # 69 deg
    assert sensor.camera['width'] * 9 == sensor.camera['height'] * 16
    assert sensor.update_rate == pytest.approx(30.0)


def test_gravity_defaults_on_without_a_gazebo_block():
    model = urdf_model.parse_urdf(_robot('<link name="a"/>'))
    assert model.links['a'].gravity is True
    assert model.has_gravity


@pytest.mark.parametrize('tag, value, expected', [
    ('gravity', '0', False), ('gravity', 'false', False), ('gravity', '1', True), ('gravity', 'true', True),
    ('gravity', ' 0 ', False),
    ('turnGravityOff', 'true', False), ('turnGravityOff', 'false', True), ('turnGravityOff', '1', False),
])
def test_gravity_tags_including_the_legacy_one(tag, value, expected):
    xml = _robot('<link name="a"/><link name="b"/>'
                 '<gazebo reference="a"><%s>%s</%s></gazebo>' % (tag, value, tag))
    model = urdf_model.parse_urdf(xml)
    assert model.links['a'].gravity is expected
    assert model.links['b'].gravity is True  # untouched link keeps the default


def test_gravity_block_for_another_link_or_the_model_does_not_apply():
    xml = _robot('<link name="a"/><gazebo reference="b"><gravity>0</gravity></gazebo>'
                 '<gazebo><gravity>0</gravity><static>true</static></gazebo>')
    model = urdf_model.parse_urdf(xml)
    assert model.links['a'].gravity is True
    assert model.is_static is True


def test_bad_gravity_value_is_an_error():
    with pytest.raises(urdf_model.UrdfError):
        urdf_model.parse_urdf(_robot('<link name="a"/><gazebo reference="a"><gravity>off</gravity></gazebo>'))


def test_collision_geometry_detected_with_origin_and_shapes():
    xml = _robot('<link name="a"><visual>%s</visual></link>'
                 '<link name="b"><collision><origin xyz="1 2 3" rpy="0 0 1.5"/>%s</collision>'
                 '<collision><geometry><sphere radius="0.5"/></geometry></collision></link>'
                 '<link name="c"><collision><geometry><cylinder radius="0.2" length="0.4"/></geometry>'
                 '</collision></link>'
                 '<joint name="j" type="fixed"><parent link="a"/><child link="b"/></joint>' % (BOX, BOX))
    model = urdf_model.parse_urdf(xml)
    assert model.collision_links == ['b', 'c']
    b = model.links['b'].collisions
    assert b[0] == urdf_model.Geometry('box', (0.1, 0.2, 0.3), ((1.0, 2.0, 3.0), (0.0, 0.0, 1.5)))
    assert b[1].type == 'sphere' and b[1].size == (0.5,)
    assert model.links['c'].collisions[0].size == (0.2, 0.4)
    assert model.links['a'].collisions == ()
    assert model.root_link == 'a'
    assert model.joints == [('j', 'fixed', 'a', 'b')]


@pytest.mark.parametrize('xml', [
    'not xml at all <',
    '<sdf version="1.6"><model name="m"/></sdf>',
    '<robot name="r"/>',
    '<robot name="r"><link name="a"/><link name="a"/></robot>',
    '<robot name="r"><link name="a"><collision><geometry><box size="1 2"/></geometry></collision></link></robot>',
    '<robot name="r"><link name="a"><collision></collision></link></robot>',
    '<robot name="r"><link name="a"><inertial><mass value="heavy"/></inertial></link></robot>',
])
def test_unreadable_urdf_raises_urdf_error(xml):
    with pytest.raises(urdf_model.UrdfError):
        urdf_model.parse_urdf(xml)


@pytest.mark.parametrize('name', ['anafi.urdf', 'anafi_camera.urdf'])
def test_set_gravity_builds_a_gravity_on_copy_and_back(name):
    on = urdf_model.set_gravity(_read(name), True)
    model_on = urdf_model.parse_urdf(on)
    assert model_on.gravity_links == model_on.link_names
    assert model_on.collision_links == []  # only gravity changes
    off = urdf_model.parse_urdf(urdf_model.set_gravity(on, False))
    assert off.gravity_links == []


def test_set_gravity_replaces_legacy_tag_and_covers_links_without_a_block():
    xml = _robot('<link name="a"/><link name="b"/>'
                 '<gazebo reference="a"><turnGravityOff>true</turnGravityOff><material>x</material></gazebo>')
    on = urdf_model.parse_urdf(urdf_model.set_gravity(xml, True))
    assert on.links['a'].gravity and on.links['b'].gravity
    off = urdf_model.parse_urdf(urdf_model.set_gravity(xml, False))
    assert off.gravity_links == []
    assert 'turnGravityOff' not in urdf_model.set_gravity(xml, False)
