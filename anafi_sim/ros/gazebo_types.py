"""gazebo_msgs types for the Gazebo stage, wire-identical to gazebo_ros (pure: genpy/genmsg, no rospy).

Stage: (mirror | kinematic world) — the messages and services of the
``gazebo_ros`` API subset we use (see ``/work/shared/interfaces/gazebo_msgs.md``):
ModelState, ModelStates; SpawnModel, DeleteModel, SetModelState,
GetModelState, GetModelProperties.

On a Noetic machine with ``gazebo_msgs`` installed the real classes are
returned. Otherwise they are built at run time from their definitions with
``genpy.dynamic``: same type names, field types, names and order, hence the
same md5sums. A service class is assembled the way genpy generates one
(``_type``, ``_md5sum``, ``_request_class``, ``_response_class``) so it works
with ``rospy.Service`` and ``rospy.ServiceProxy``; its md5 is computed as
genmsg does for a .srv (md5 over the request md5 text followed by the
response md5 text). No module or package called ``gazebo_msgs`` is created,
so the real one is never shadowed.

Usage: ``ModelState = message_class('ModelState')``,
``SpawnModel = service_class('SpawnModel')`` then ``SpawnModel._request_class()``.
"""
import hashlib
import importlib

import genmsg
import genmsg.msg_loader
import genpy.dynamic

from anafi_sim.ros.wire_types import load_message_class

PACKAGE = 'gazebo_msgs'
_SEPARATOR = '=' * 80 + '\n'

# Dependencies (standard ROS definitions; std_msgs/geometry_msgs never change).
_DEPENDENCIES = {
    'std_msgs/Header': 'uint32 seq\ntime stamp\nstring frame_id\n',
    'geometry_msgs/Point': 'float64 x\nfloat64 y\nfloat64 z\n',
    'geometry_msgs/Quaternion': 'float64 x\nfloat64 y\nfloat64 z\nfloat64 w\n',
    'geometry_msgs/Vector3': 'float64 x\nfloat64 y\nfloat64 z\n',
    'geometry_msgs/Pose': 'Point position\nQuaternion orientation\n',
    'geometry_msgs/Twist': 'Vector3  linear\nVector3  angular\n',
    'gazebo_msgs/ModelState': ('string model_name\n'
                               'geometry_msgs/Pose pose\n'
                               'geometry_msgs/Twist twist\n'
                               'string reference_frame\n'),
}
# Which dependencies each definition pulls in (in the order gendeps --cat writes them).
_POSE = ['geometry_msgs/Pose', 'geometry_msgs/Point', 'geometry_msgs/Quaternion']
_TWIST = ['geometry_msgs/Twist', 'geometry_msgs/Vector3']

MESSAGES = {
    'ModelState': (_DEPENDENCIES['gazebo_msgs/ModelState'], _POSE + _TWIST),
    'ModelStates': ('string[] name\ngeometry_msgs/Pose[] pose\ngeometry_msgs/Twist[] twist\n', _POSE + _TWIST),
}

SERVICES = {
    'SpawnModel': (
        ('string model_name\nstring model_xml\nstring robot_namespace\n'
         'geometry_msgs/Pose initial_pose\nstring reference_frame\n', _POSE),
        ('bool success\nstring status_message\n', [])),
    'DeleteModel': (
        ('string model_name\n', []),
        ('bool success\nstring status_message\n', [])),
    'SetModelState': (
        ('gazebo_msgs/ModelState model_state\n', ['gazebo_msgs/ModelState'] + _POSE + _TWIST),
        ('bool success\nstring status_message\n', [])),
    'GetModelState': (
        ('string model_name\nstring relative_entity_name\n', []),
        ('Header header\ngeometry_msgs/Pose pose\ngeometry_msgs/Twist twist\n'
         'bool success\nstring status_message\n', ['std_msgs/Header'] + _POSE + _TWIST)),
    'GetModelProperties': (
        ('string model_name\n', []),
        ('string parent_model_name\nstring canonical_body_name\nstring[] body_names\nstring[] geom_names\n'
         'string[] joint_names\nstring[] child_model_names\nbool is_static\nbool success\n'
         'string status_message\n', [])),
}

EXPECTED_MD5 = {
    'gazebo_msgs/ModelState': '9330fd35f2fcd82d457e54bd54e10593',
    'gazebo_msgs/ModelStates': '48c080191eb15c41858319b4d8a609c2',
    'gazebo_msgs/SpawnModel': '9ed9c82c96abe1a00c3e8cdaeee24413',
    'gazebo_msgs/DeleteModel': '9ce56b4e9e54616de25d796dc972a262',
    'gazebo_msgs/SetModelState': '5b3ab0281d4f5445def017e3a2e4a07b',
    'gazebo_msgs/GetModelState': '4c515e936d3319c9610c559c60bfc3d4',
    'gazebo_msgs/GetModelProperties': '5717f7bd34ed990fa80e28b3015027a3',
}
"""md5sums of the real gazebo_msgs (Noetic), from the shared interface document."""

_service_cache = {}


def _full_text(text, dependencies):
    """Definition text plus its dependencies, in the ``gendeps --cat`` layout genpy.dynamic reads."""
    parts = [text]
    for dep in dependencies:
        parts.append('MSG: %s\n%s' % (dep, _DEPENDENCIES[dep]))
    return ('\n' + _SEPARATOR).join(parts)


def message_class(name):
    """Message class ``gazebo_msgs/<name>`` (name in MESSAGES): the installed one, else a genpy.dynamic one."""
    text, dependencies = MESSAGES[name]
    return load_message_class('%s/%s' % (PACKAGE, name), _full_text(text, dependencies))


def _srv_md5(request_text, response_text):
    """md5 of a .srv as genmsg computes it (request md5 text then response md5 text)."""
    context = genmsg.msg_loader.MsgContext.create_default()
    for dep_type, dep_text in _DEPENDENCIES.items():
        context.register(dep_type, genmsg.msg_loader.load_msg_from_string(context, dep_text, dep_type))
    md5 = hashlib.md5()
    for suffix, text in (('Request', request_text), ('Response', response_text)):
        spec = genmsg.msg_loader.load_msg_from_string(context, text, '%s/Srv%s' % (PACKAGE, suffix))
        md5.update(genmsg.compute_md5_text(context, spec).encode())
    return md5.hexdigest()


def service_class(name):
    """Service class ``gazebo_msgs/<name>`` (name in SERVICES): installed, else assembled from dynamic classes."""
    if name in _service_cache:
        return _service_cache[name]
    cls = None
    try:
        cls = getattr(importlib.import_module(PACKAGE + '.srv'), name)
    except (ImportError, AttributeError):
        (request_text, request_deps), (response_text, response_deps) = SERVICES[name]
        classes = []
        for suffix, text, deps in (('Request', request_text, request_deps),
                                   ('Response', response_text, response_deps)):
            type_name = '%s/%s%s' % (PACKAGE, name, suffix)
            classes.append(genpy.dynamic.generate_dynamic(type_name, _full_text(text, deps))[type_name])
        request_class, response_class = classes
        cls = type(name, (object,), {
            '__doc__': 'gazebo_msgs/%s service (built at run time, wire-identical).' % name,
            '_type': '%s/%s' % (PACKAGE, name),
            '_md5sum': _srv_md5(request_text, response_text),
            '_request_class': request_class,
            '_response_class': response_class,
        })
        request_class._service_class = cls
        response_class._service_class = cls
    _service_cache[name] = cls
    return cls


def model_state_class():
    """``gazebo_msgs/ModelState`` (md5 9330fd35f2fcd82d457e54bd54e10593)."""
    return message_class('ModelState')


def model_states_class():
    """``gazebo_msgs/ModelStates`` (md5 48c080191eb15c41858319b4d8a609c2)."""
    return message_class('ModelStates')


def spawn_model_class():
    """``gazebo_msgs/SpawnModel`` service (used by /gazebo/spawn_urdf_model and /gazebo/spawn_sdf_model)."""
    return service_class('SpawnModel')


def delete_model_class():
    """``gazebo_msgs/DeleteModel`` service."""
    return service_class('DeleteModel')


def set_model_state_class():
    """``gazebo_msgs/SetModelState`` service."""
    return service_class('SetModelState')


def get_model_state_class():
    """``gazebo_msgs/GetModelState`` service."""
    return service_class('GetModelState')


def get_model_properties_class():
    """``gazebo_msgs/GetModelProperties`` service."""
    return service_class('GetModelProperties')
