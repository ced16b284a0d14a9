"""gazebo_msgs stand-in types: real names, field layout and md5sums; requests/responses round-trip."""
import io
import os
import re
import sys

import genpy
import pytest
from geometry_msgs.msg import Pose, Twist

from anafi_sim.ros import gazebo_types
from conftest import ROOT

# md5sums of the real Noetic gazebo_msgs (copied from shared/interfaces/gazebo_msgs.md).
EXPECTED = {
    'gazebo_msgs/ModelState': '9330fd35f2fcd82d457e54bd54e10593',
    'gazebo_msgs/ModelStates': '48c080191eb15c41858319b4d8a609c2',
    'gazebo_msgs/SpawnModel': '9ed9c82c96abe1a00c3e8cdaeee24413',
    'gazebo_msgs/DeleteModel': '9ce56b4e9e54616de25d796dc972a262',
    'gazebo_msgs/SetModelState': '5b3ab0281d4f5445def017e3a2e4a07b',
    'gazebo_msgs/GetModelState': '4c515e936d3319c9610c559c60bfc3d4',
    'gazebo_msgs/GetModelProperties': '5717f7bd34ed990fa80e28b3015027a3',
}
SERVICES = ['SpawnModel', 'DeleteModel', 'SetModelState', 'GetModelState', 'GetModelProperties']
MESSAGES = ['ModelState', 'ModelStates']
DOC = os.path.join(os.path.dirname(ROOT), 'shared', 'interfaces', 'gazebo_msgs.md')

FIELDS = {
    'gazebo_msgs/ModelState': ['model_name', 'pose', 'twist', 'reference_frame'],
    'gazebo_msgs/ModelStates': ['name', 'pose', 'twist'],
    'gazebo_msgs/SpawnModelRequest': ['model_name', 'model_xml', 'robot_namespace', 'initial_pose',
                                      'reference_frame'],
    'gazebo_msgs/SpawnModelResponse': ['success', 'status_message'],
    'gazebo_msgs/DeleteModelRequest': ['model_name'],
    'gazebo_msgs/DeleteModelResponse': ['success', 'status_message'],
    'gazebo_msgs/SetModelStateRequest': ['model_state'],
    'gazebo_msgs/SetModelStateResponse': ['success', 'status_message'],
    'gazebo_msgs/GetModelStateRequest': ['model_name', 'relative_entity_name'],
    'gazebo_msgs/GetModelStateResponse': ['header', 'pose', 'twist', 'success', 'status_message'],
    'gazebo_msgs/GetModelPropertiesRequest': ['model_name'],
    'gazebo_msgs/GetModelPropertiesResponse': ['parent_model_name', 'canonical_body_name', 'body_names',
                                               'geom_names', 'joint_names', 'child_model_names', 'is_static',
                                               'success', 'status_message'],
}


def all_classes():
    classes = [gazebo_types.message_class(n) for n in MESSAGES]
    for name in SERVICES:
        srv = gazebo_types.service_class(name)
        classes += [srv._request_class, srv._response_class]
    return classes


@pytest.mark.parametrize('name', MESSAGES)
def test_message_type_and_md5(name):
    cls = gazebo_types.message_class(name)
    assert cls._type == 'gazebo_msgs/' + name
    assert cls._md5sum == EXPECTED[cls._type]


@pytest.mark.parametrize('name', SERVICES)
def test_service_type_md5_and_classes(name):
    srv = gazebo_types.service_class(name)
    assert srv._type == 'gazebo_msgs/' + name
    assert srv._md5sum == EXPECTED[srv._type]
    assert srv._request_class._type == 'gazebo_msgs/%sRequest' % name
    assert srv._response_class._type == 'gazebo_msgs/%sResponse' % name
    assert issubclass(srv._request_class, genpy.Message) and issubclass(srv._response_class, genpy.Message)


def test_convenience_accessors_return_the_same_classes():
    assert gazebo_types.model_state_class() is gazebo_types.message_class('ModelState')
    assert gazebo_types.model_states_class() is gazebo_types.message_class('ModelStates')
    assert gazebo_types.spawn_model_class() is gazebo_types.service_class('SpawnModel')
    assert gazebo_types.delete_model_class() is gazebo_types.service_class('DeleteModel')
    assert gazebo_types.set_model_state_class() is gazebo_types.service_class('SetModelState')
    assert gazebo_types.get_model_state_class() is gazebo_types.service_class('GetModelState')
    assert gazebo_types.get_model_properties_class() is gazebo_types.service_class('GetModelProperties')


def test_md5s_equal_the_shared_document():
    if not os.path.isfile(DOC):
        pytest.skip('shared interface document %s absent' % DOC)
    text = open(DOC).read()
    documented = dict(re.findall(r'^(gazebo_msgs/\w+)(?: \(srv\))?\s+md5 ([0-9a-f]{32})', text, re.M))
    assert set(documented) == set(EXPECTED)
    for name in MESSAGES:
        cls = gazebo_types.message_class(name)
        assert cls._md5sum == documented[cls._type]
    for name in SERVICES:
        srv = gazebo_types.service_class(name)
        assert srv._md5sum == documented[srv._type]


def test_field_names_and_order():
    for cls in all_classes():
        assert list(cls.__slots__) == FIELDS[cls._type], cls._type


def test_a_changed_definition_changes_the_service_md5():
    # the md5 recipe is sensitive to field types and order (so the matches above are not accidental)
    request, response = gazebo_types.SERVICES['DeleteModel']
    good = gazebo_types._srv_md5(request[0], response[0])
    assert good == EXPECTED['gazebo_msgs/DeleteModel']
    assert gazebo_types._srv_md5(request[0], 'string status_message\nbool success\n') != good
    assert gazebo_types._srv_md5('string name\n', response[0]) != good


def roundtrip(msg):
    buff = io.BytesIO()
    msg.serialize(buff)
    out = type(msg)()
    out.deserialize(buff.getvalue())
    return out


def pose(x, y, z, qx=0.0, qy=0.0, qz=0.0, qw=1.0):
    p = Pose()
    p.position.x, p.position.y, p.position.z = x, y, z
    p.orientation.x, p.orientation.y, p.orientation.z, p.orientation.w = qx, qy, qz, qw
    return p


def twist(vx, vy, vz, wx=0.0, wy=0.0, wz=0.0):
    t = Twist()
    t.linear.x, t.linear.y, t.linear.z = vx, vy, vz
    t.angular.x, t.angular.y, t.angular.z = wx, wy, wz
    return t


def test_model_state_and_states_roundtrip():
    ModelState = gazebo_types.model_state_class()
    msg = ModelState(model_name='anafi', pose=pose(1.0, -2.0, 3.5, 0.0, 0.0, 0.6, 0.8),
                     twist=twist(0.1, 0.2, -0.3, 0.0, 0.0, 0.5), reference_frame='world')
    out = roundtrip(msg)
    assert out.model_name == 'anafi' and out.reference_frame == 'world'
    assert (out.pose.position.z, out.pose.orientation.z, out.twist.linear.z, out.twist.angular.z) == \
        (3.5, 0.6, -0.3, 0.5)
    ModelStates = gazebo_types.model_states_class()
    msg = ModelStates(name=['a', 'b'], pose=[pose(1, 2, 3), pose(4, 5, 6)], twist=[twist(0, 0, 1), twist(0, 1, 0)])
    out = roundtrip(msg)
    assert out.name == ['a', 'b']
    assert [p.position.y for p in out.pose] == [2.0, 5.0]
    assert [t.linear.y for t in out.twist] == [0.0, 1.0]


def test_service_requests_and_responses_roundtrip():
    spawn = gazebo_types.service_class('SpawnModel')
    req = roundtrip(spawn._request_class('anafi', '<robot name="x"/>', '/anafi', pose(0, 0, 1), 'world'))
    assert (req.model_name, req.model_xml, req.robot_namespace, req.initial_pose.position.z, req.reference_frame) \
        == ('anafi', '<robot name="x"/>', '/anafi', 1.0, 'world')
    res = roundtrip(spawn._response_class(False, 'SpawnModel: Failure - model name anafi already exist.'))
    assert res.success is False and 'already exist' in res.status_message

    delete = gazebo_types.service_class('DeleteModel')
    assert roundtrip(delete._request_class('cam')).model_name == 'cam'
    assert roundtrip(delete._response_class(True, 'ok')).success is True

    set_state = gazebo_types.service_class('SetModelState')
    req = set_state._request_class()
    req.model_state.model_name = 'anafi'
    req.model_state.pose = pose(1, 2, 3)
    req.model_state.twist = twist(4, 5, 6)
    out = roundtrip(req)
    assert (out.model_state.model_name, out.model_state.pose.position.y, out.model_state.twist.linear.z) == \
        ('anafi', 2.0, 6.0)

    get_state = gazebo_types.service_class('GetModelState')
    req = roundtrip(get_state._request_class('anafi', 'airship'))
    assert (req.model_name, req.relative_entity_name) == ('anafi', 'airship')
    res = get_state._response_class()
    res.header.stamp = genpy.Time(12, 500)
    res.header.frame_id = 'airship'
    res.pose, res.twist, res.success, res.status_message = pose(7, 8, 9), twist(1, 0, 0), True, 'done'
    out = roundtrip(res)
    assert (out.header.stamp, out.header.frame_id, out.pose.position.x, out.twist.linear.x, out.success) == \
        (genpy.Time(12, 500), 'airship', 7.0, 1.0, True)

    props = gazebo_types.service_class('GetModelProperties')
    res = props._response_class('', 'base_link', ['base_link', 'camera_link'], [], ['cam_joint'], [], False,
                                True, 'GetModelProperties: got properties')
    out = roundtrip(res)
    assert out.body_names == ['base_link', 'camera_link'] and out.geom_names == [] and out.is_static is False
    assert out.canonical_body_name == 'base_link' and out.joint_names == ['cam_joint']


def test_no_module_named_gazebo_msgs_is_created():
    import importlib.util
    installed = importlib.util.find_spec('gazebo_msgs') is not None
    all_classes()
    if not installed:
        assert 'gazebo_msgs' not in sys.modules
        assert importlib.util.find_spec('gazebo_msgs') is None
    for root, dirs, files in os.walk(ROOT):
        dirs[:] = [d for d in dirs if not d.startswith('.')]
        assert 'gazebo_msgs' not in dirs and 'gazebo_msgs.py' not in files, root
