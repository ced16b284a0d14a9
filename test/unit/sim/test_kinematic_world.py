"""KinematicWorld (stand-in for Gazebo): spawn/delete/set/get, gravity sag, contacts, properties, SDF."""
import math
import os

import pytest

from anafi_sim.gazebo import kinematic_world as kw
from anafi_sim.gazebo.kinematic_world import KinematicWorld
from conftest import repo_path

G = 9.81
URDF_DIR = repo_path('anafi_sim', 'urdf')


def box_robot(name='box', gravity=None, collision=True, legacy_off=False, static=False, size='0.2 0.2 0.2'):
    gz = ''
    if gravity is not None:
        gz += '<gazebo reference="base_link"><gravity>%s</gravity></gazebo>' % gravity
    if legacy_off:
        gz += '<gazebo reference="base_link"><turnGravityOff>true</turnGravityOff></gazebo>'
    if static:
        gz += '<gazebo><static>true</static></gazebo>'
    col = '<collision><geometry><box size="%s"/></geometry></collision>' % size if collision else ''
    return ('<?xml version="1.0"?><robot name="%s"><link name="base_link"><inertial><mass value="0.3"/>'
            '</inertial><visual><geometry><box size="%s"/></geometry></visual>%s</link>%s</robot>'
            % (name, size, col, gz))


def run(world, seconds, dt=0.001):
    events = []
    for _ in range(int(round(seconds / dt))):
        events.append(world.step(dt))
    return events


def z_of(world, name):
    return world.get_state(name)[1].position[2]


def test_spawn_get_delete_and_duplicate_name():
    world = KinematicWorld()
    result = world.spawn('anafi', box_robot(gravity=0), (1.0, 2.0, 3.0), (0.0, 0.0, 0.0, 2.0))
    assert result.success and 'Successfully' in result.status_message
    ok, state = world.get_state('anafi')
    assert ok.success
    assert state.position == pytest.approx((1.0, 2.0, 3.0))
    assert state.orientation == pytest.approx((0.0, 0.0, 0.0, 1.0))  # normalised
    dup = world.spawn('anafi', box_robot(gravity=0))
    assert not dup.success and dup.status_message == 'SpawnModel: Failure - entity already exists.'
    assert world.names() == ['anafi']
    assert world.delete('anafi').success
    assert world.names() == []
    assert not world.delete('anafi').success
    result, state = world.get_state('anafi')
    assert not result.success and state is None
    assert world.counters['spawned'] == 1 and world.counters['deleted'] == 1 and world.counters['rejected'] == 3  # dup spawn, delete, get


def test_empty_name_takes_the_name_in_the_xml():
    world = KinematicWorld()
    assert world.spawn('', box_robot(name='from_xml')).success
    assert world.names() == ['from_xml']


def test_bad_model_xml_and_non_finite_inputs_are_rejected_not_raised():
    world = KinematicWorld()
    for xml in ('', 'not xml <', '<world/>', '<robot name="x"/>',
                '<robot name="x"><link name="a"><collision><geometry><box size="1 1"/></geometry></collision>'
                '</link></robot>'):
        result = world.spawn('m', xml)
        assert not result.success and result.status_message.startswith('SpawnModel: Failure'), xml
    assert not world.spawn('m', box_robot(), (0.0, float('nan'), 0.0)).success
    assert world.names() == []
    assert world.spawn('m', box_robot(gravity=0), (0.0, 0.0, 1.0)).success
    assert not world.set_state('m', (float('inf'), 0, 0), (0, 0, 0, 1)).success
    assert not world.set_state('m', (0, 0, 0), (0, 0, 0, 1), reference_frame='nowhere').success
    assert not world.set_state('ghost', (0, 0, 0), (0, 0, 0, 1)).success
    assert z_of(world, 'm') == 1.0
    assert not world.set_state('m', (0, 0, 0), (0, 0, 0, 1), (float('inf'), -float('inf'), 0)).success
    assert not world.set_state('m', ('1', 0, 0), (0, 0, 0, 1)).success
    assert not world.set_state('m', (0, 0, 0, 0), (0, 0, 1)).success    # 13 numbers, not a pose and a twist
    big = 1e308                                  # finite, although their sum overflows
    assert world.set_state('m', (big, big, 1.0), (0, 0, 0, 1), (big, big, 0.0)).success
    assert world.get_state('m')[1].position == (big, big, 1.0)
    assert z_of(world, 'm') == 1.0
    with pytest.raises(ValueError):
        world.step(float('nan'))
    with pytest.raises(ValueError):
        KinematicWorld(gravity=-1.0)


def test_set_state_then_kinematic_extrapolation_with_twist():
    world = KinematicWorld()
    world.spawn('m', box_robot(gravity=0))
    quarter = (0.0, 0.0, math.sin(math.pi / 8), math.cos(math.pi / 8))  # yaw 45 deg
    assert world.set_state('m', (1.0, 0.0, 2.0), quarter, (0.5, -1.0, 0.2), (0.0, 0.0, math.pi / 4)).success
    run(world, 1.0, dt=0.01)
    state = world.get_state('m')[1]
    assert state.position == pytest.approx((1.5, -1.0, 2.2), abs=1e-9)
    # 45 deg + 45 deg/s * 1 s = yaw 90 deg
    assert state.orientation == pytest.approx((0.0, 0.0, math.sin(math.pi / 4), math.cos(math.pi / 4)), abs=1e-9)
    assert state.linear == pytest.approx((0.5, -1.0, 0.2))


def test_gravity_on_link_sags_between_updates_gravity_off_does_not():
    world = KinematicWorld(gravity=G)
    world.spawn('on', box_robot(collision=False))
    world.spawn('off', box_robot(gravity=0, collision=False))
    # a 100 Hz mirror stream commanding hover at z = 5 m, integrated at 1 kHz in between
    worst = {'on': 0.0, 'off': 0.0}
    for _ in range(50):
        for name in worst:
            assert world.set_state(name, (0.0, 0.0, 5.0), (0, 0, 0, 1)).success
        for _ in range(10):
            world.step(0.001)
            for name in worst:
                worst[name] = max(worst[name], 5.0 - z_of(world, name))
    assert worst['off'] == 0.0
    assert worst['on'] == pytest.approx(0.5 * G * 0.01 ** 2, rel=1e-6)  # 0.49 mm just before each update
    assert world.report('on')['max_sag'] == pytest.approx(worst['on'])
    assert world.report('off')['max_sag'] == 0.0
    assert world.report('on')['gravity_links'] == ['base_link'] and world.report('off')['gravity_links'] == []
    # set_state resets the velocity to the commanded twist (gravity does not accumulate across updates)
    world.set_state('on', (0.0, 0.0, 5.0), (0, 0, 0, 1), (0.0, 0.0, 0.0))
    assert world.get_state('on')[1].linear == (0.0, 0.0, 0.0)
    # without updates the gravity-on model falls freely
    run(world, 1.0, dt=0.01)
    assert z_of(world, 'on') == pytest.approx(5.0 - 0.5 * G, abs=1e-9)
    assert z_of(world, 'off') == 5.0


def test_legacy_turn_gravity_off_and_gravity_true():
    world = KinematicWorld()
    world.spawn('legacy', box_robot(legacy_off=True, collision=False))
    world.spawn('explicit_on', box_robot(gravity='true', collision=False))
    run(world, 0.1, dt=0.01)
    assert z_of(world, 'legacy') == 0.0
    assert z_of(world, 'explicit_on') < -0.04


def test_gravity_scales_with_the_mass_on_gravity_on_links():
    two_links = ('<robot name="two"><link name="a"><inertial><mass value="3"/></inertial></link>'
                 '<link name="b"><inertial><mass value="1"/></inertial></link>'
                 '<joint name="j" type="fixed"><parent link="a"/><child link="b"/></joint>'
                 '<gazebo reference="a"><gravity>0</gravity></gazebo></robot>')
    world = KinematicWorld()
    world.spawn('two', two_links)
    assert world.report('two')['gravity_acceleration'] == pytest.approx(G / 4)


def test_static_model_never_moves_but_can_be_teleported():
    world = KinematicWorld()
    world.spawn('s', box_robot(static=True), (0.0, 0.0, 3.0))
    run(world, 0.5, dt=0.01)
    assert z_of(world, 's') == 3.0
    world.set_state('s', (1.0, 0.0, 3.0), (0, 0, 0, 1), (1.0, 0.0, 0.0))
    run(world, 0.5, dt=0.01)
    assert world.get_state('s')[1].position == (1.0, 0.0, 3.0)
    assert world.properties('s')[1].is_static


def test_properties_geoms_only_when_collisions():
    world = KinematicWorld()
    world.spawn('ghost', box_robot(gravity=0, collision=False))
    world.spawn('solid', box_robot(gravity=0))
    result, props = world.properties('ghost')
    assert result.success and result.status_message == 'GetModelProperties: got properties'
    assert props.geom_names == [] and props.body_names == ['base_link'] and props.canonical_body_name == 'base_link'
    assert props.is_static is False and props.parent_model_name == '' and props.child_model_names == []
    assert world.properties('solid')[1].geom_names == ['base_link_collision']
    result, props = world.properties('nothing')
    assert not result.success and props is None


def test_shipped_anafi_and_camera_urdfs_have_no_geoms_and_gravity_off():
    names = [n for n in ('anafi.urdf', 'anafi_camera.urdf') if os.path.isfile(os.path.join(URDF_DIR, n))]
    if not names:
        pytest.skip('anafi_sim/urdf models not present yet')
    world = KinematicWorld()
    for n in names:
        assert world.spawn(n, open(os.path.join(URDF_DIR, n)).read(), (0.0, 0.0, 1.0)).success, n
        assert world.properties(n)[1].geom_names == []
        assert world.report(n)['gravity_links'] == []
    run(world, 0.2, dt=0.01)
    assert all(z_of(world, n) == 1.0 for n in names)


def test_contacts_only_between_models_with_collision_geometry():
    world = KinematicWorld()
    world.spawn('a', box_robot(gravity=0), (0.0, 0.0, 1.0))
    world.spawn('b', box_robot(gravity=0), (1.0, 0.0, 1.0))
    world.spawn('ghost', box_robot(gravity=0, collision=False), (0.5, 0.0, 1.0))
    assert world.step(0.01).begun == []
    # b flies through a (0.2 m boxes) and the collision-free ghost at 1 m/s
    world.set_state('b', (1.0, 0.0, 1.0), (0, 0, 0, 1), (-1.0, 0.0, 0.0))
    begun, ended = [], []
    for _ in range(200):
        events = world.step(0.01)
        begun += events.begun
        ended += events.ended
    assert [(c.model_a, c.model_b, c.geom_a, c.geom_b) for c in begun] == \
        [('a', 'b', 'base_link_collision', 'base_link_collision')]
    assert ended == [('a', 'b')]
    assert world.counters['contact_events'] == 1
    assert world.report('ghost')['contact_events'] == 0 and world.report('a')['contact_events'] == 1
    assert world.contacts() == []


def test_contact_while_overlapping_reports_depth_and_ends_on_delete():
    world = KinematicWorld()
    world.spawn('a', box_robot(gravity=0), (0.0, 0.0, 1.0))
    world.spawn('b', box_robot(gravity=0), (0.15, 0.0, 1.0))
    events = world.step(0.01)
    assert len(events.begun) == 1 and events.begun[0].depth == pytest.approx(0.05)
    assert world.step(0.01).begun == []  # an ongoing contact is one event
    assert len(world.contacts()) == 1
    world.delete('b')
    assert world.contacts() == []


def test_falling_collision_model_touches_ground_plane():
    world = KinematicWorld(ground_plane=True)
    assert world.names() == ['ground_plane'] and world.properties('ground_plane')[1].is_static
    world.spawn('falls', box_robot(), (0.0, 0.0, 0.5))
    world.spawn('falls_ghost', box_robot(collision=False), (2.0, 0.0, 0.5))
    contacts = []
    for _ in range(100):
        contacts += world.step(0.01).begun
    assert [(c.model_a, c.model_b) for c in contacts] == [('falls', 'ground_plane')]


def test_sphere_and_cylinder_collisions():
    sphere = ('<robot name="s"><link name="l"><collision name="ball"><origin xyz="0 0 0.5"/><geometry>'
              '<sphere radius="0.1"/></geometry></collision></link>'
              '<gazebo reference="l"><gravity>0</gravity></gazebo></robot>')
    world = KinematicWorld()
    world.spawn('s1', sphere, (0.0, 0.0, 0.0))
    world.spawn('s2', sphere, (0.15, 0.15, 0.0))  # 0.212 m apart: bounding boxes overlap, spheres do not
    assert world.properties('s1')[1].geom_names == ['l_collision_ball']
    assert world.step(0.01).begun == []
    world.set_state('s2', (0.15, 0.0, 0.0), (0, 0, 0, 1))
    begun = world.step(0.01).begun
    assert len(begun) == 1 and begun[0].depth == pytest.approx(0.05)
    # the collision origin follows the model's rotation: rolled 90 deg, the ball sits at -y 0.5 m
    cylinder = ('<robot name="c"><link name="l"><collision><geometry><cylinder radius="0.05" length="1.0"/>'
                '</geometry></collision></link><gazebo reference="l"><gravity>0</gravity></gazebo></robot>')
    world = KinematicWorld()
    world.spawn('s', sphere, (0.0, 0.0, 0.0), (math.sin(math.pi / 4), 0.0, 0.0, math.cos(math.pi / 4)))
    world.spawn('c', cylinder, (0.0, -0.5, 0.7))  # vertical pole from z 0.2 to 1.2: misses the rotated ball
    assert world.step(0.01).begun == []
    world.set_state('c', (0.0, -0.5, 0.5), (0, 0, 0, 1))  # pole from z 0 to 1.0: hits the ball at z 0
    assert len(world.step(0.01).begun) == 1


def test_joint_origins_place_child_collisions():
    robot = ('<robot name="r"><link name="base"/><link name="arm"><collision><geometry><box size="0.1 0.1 0.1"/>'
             '</geometry></collision></link><joint name="j" type="fixed"><parent link="base"/><child link="arm"/>'
             '<origin xyz="1 0 0" rpy="0 0 1.5707963267948966"/></joint>'
             '<gazebo reference="base"><gravity>0</gravity></gazebo>'
             '<gazebo reference="arm"><gravity>0</gravity></gazebo></robot>')
    description = kw.describe_model(robot)
    geom = description.links[1].geoms[0]
    assert geom.xyz == pytest.approx((1.0, 0.0, 0.0)) and geom.rpy[2] == pytest.approx(math.pi / 2)
    assert description.joint_names == ['j']
    world = KinematicWorld()
    world.spawn('r', robot, (0.0, 0.0, 0.0), (0.0, 0.0, 1.0, 0.0))  # yaw 180 deg: the arm is at x = -1
    world.spawn('probe', box_robot(gravity=0, size='0.1 0.1 0.1'), (-1.05, 0.0, 0.0))
    assert len(world.step(0.01).begun) == 1


def test_minimal_sdf_spawn():
    sdf = ('<sdf version="1.6"><model name="airship"><pose>9 9 9 0 0 0</pose><link name="hull">'
           '<pose>0 0 1 0 0 0</pose><gravity>false</gravity><inertial><mass>2.0</mass></inertial>'
           '<collision name="hull_col"><geometry><cylinder><radius>0.5</radius><length>2</length></cylinder>'
           '</geometry></collision></link><link name="gondola"><gravity>0</gravity></link></model></sdf>')
    world = KinematicWorld()
    assert world.spawn('', sdf, (0.0, 0.0, 10.0)).success
    assert world.names() == ['airship']
    props = world.properties('airship')[1]
    assert props.body_names == ['hull', 'gondola'] and props.geom_names == ['hull_col']
    assert world.get_state('airship')[1].position == (0.0, 0.0, 10.0)  # spawn pose wins over the SDF's <pose>
    description = kw.describe_model(sdf)
    assert description.format == 'sdf' and description.links[0].geoms[0].xyz == (0.0, 0.0, 1.0)
    run(world, 0.2, dt=0.01)
    assert z_of(world, 'airship') == 10.0  # gravity off in SDF
    falling = '<sdf version="1.6"><model name="rock"><link name="l"/></model></sdf>'
    world.spawn('rock', falling, (0.0, 0.0, 10.0))
    run(world, 0.1, dt=0.01)
    assert z_of(world, 'rock') < 10.0  # SDF default: gravity on
    assert not world.spawn('x', '<sdf version="1.6"><world name="w"/></sdf>').success


def test_reference_frames_for_set_and_get():
    world = KinematicWorld()
    world.spawn('base', box_robot(gravity=0, collision=False), (10.0, 0.0, 0.0), (0.0, 0.0, 1.0, 0.0))  # yaw 180
    world.spawn('m', box_robot(gravity=0, collision=False))
    assert world.set_state('m', (1.0, 0.0, 2.0), (0, 0, 0, 1), (1.0, 0.0, 0.0), reference_frame='base').success
    state = world.get_state('m')[1]
    assert state.position == pytest.approx((9.0, 0.0, 2.0))
    assert state.linear == pytest.approx((-1.0, 0.0, 0.0))
    relative = world.get_state('m', 'base')[1]
    assert relative.position == pytest.approx((1.0, 0.0, 2.0))
    assert relative.linear == pytest.approx((1.0, 0.0, 0.0))
    assert world.get_state('m', 'world')[1].position == pytest.approx((9.0, 0.0, 2.0))
    assert not world.get_state('m', 'nowhere')[0].success


def test_advance_substeps_and_returns_contact_events_of_every_substep():
    world = KinematicWorld()
    world.spawn('a', box_robot('a', gravity='0'), position=(0.0, 0.0, 1.0))
    world.spawn('b', box_robot('b', gravity='0'), position=(1.0, 0.0, 1.0))
    world.set_state('a', (0.0, 0.0, 1.0), (0.0, 0.0, 0.0, 1.0), linear=(20.0, 0.0, 0.0))
    events = world.advance(0.1, 0.01)                          # 10 substeps of 0.2 m: a passes through b
    assert world.time == pytest.approx(0.1)
    assert [e.event for e in events] == ['begin', 'end']
    assert all(e.time == pytest.approx(0.1) for e in events)   # stamped at the end of the advance
    assert (events[0].model_a, events[0].model_b) == ('a', 'b') and events[0].depth > 0.0
    record = kw.contact_record(events[1])
    assert record == {'event': 'end', 'time': 0.1, 'model_a': 'a', 'model_b': 'b', 'geom_a': '', 'geom_b': '',
                      'depth': 0.0}
    world.advance(0.025, 0.01)                                 # 3 equal substeps of 8.3 ms
    assert world.time == pytest.approx(0.125)


def test_health_of_the_world_and_each_model():
    from anafi_sim.interface.ground_truth import OK, WARN
    world = KinematicWorld(ground_plane=True)
    world.spawn('anafi', box_robot('anafi', gravity='0', collision=False))
    health = dict(world.health([('rate', 100.0), ('cycles', 3)], overruns=0))
    assert list(health) == ['world', 'model ground_plane', 'model anafi']
    assert health['world'].level == OK and health['world'].message == '2 models, 0 contacts now, 0 contact events'
    values = dict(health['world'].values)
    assert values['rate'] == '100' and values['cycles'] == '3' and values['models'] == 'ground_plane,anafi'
    assert values['spawned'] == '2' and values['time'] == '0'
    anafi = health['model anafi']
    assert anafi.level == OK and anafi.message == 'gravity off, no collision geometry'
    assert dict(anafi.values)['gravity_links'] == '' and dict(anafi.values)['is_static'] == 'False'
    assert health['model ground_plane'].message == 'gravity ON (link), collision geoms collision, static'
    world_status = dict(world.health(overruns=2))['world']
    assert world_status.level == WARN and world_status.message.endswith(', 2 overruns (running slower than rtf)')
