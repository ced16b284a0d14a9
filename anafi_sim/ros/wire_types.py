"""Message types that stand in for packages we must not ship (no rospy import).

``olympe_bridge/PilotingCommand`` (anafi_ros's piloting command) and ``sphinx_with_gazebo/Sphinx`` (the
reference implementation's telemetry message on ``/<drone>/sphinx/drone_data``, no header; definition and
md5 from ``shared/interfaces/sphinx_telemetry.md``).

``olympe_bridge`` (anafi_ros) is not installable here, and a workspace
package of that name would shadow the real one on a machine that has it.
So the real type is imported when it exists, and otherwise built at run time
from its definition with ``genpy.dynamic``: same type name, same fields,
same md5sum, hence wire-identical (``rostopic info`` on a real bridge matches).
"""
import importlib

import genpy.dynamic

_HEADER = """================================================================================
MSG: std_msgs/Header
uint32 seq
time stamp
string frame_id
"""

PILOTING_COMMAND_TYPE = 'olympe_bridge/PilotingCommand'
PILOTING_COMMAND_MD5 = '38956f4c725541081234f467b900164a'
PILOTING_COMMAND_DEFINITION = """std_msgs/Header header
float32 roll
float32 pitch
float32 yaw
float32 gaz
""" + _HEADER

SPHINX_TYPE = 'sphinx_with_gazebo/Sphinx'
SPHINX_MD5 = '85390efb41e38eee13815912075e2a5a'
#: field names in the reference implementation's order (all float64 except timeStamp, float32)
SPHINX_FIELDS = ('velXABC', 'velYABC', 'velZABC', 'angVelXABC', 'angVelYABC', 'angVelZABC',
                 'velXENU', 'velYENU', 'velZENU', 'posX', 'posY', 'posZ', 'attitudeX', 'attitudeY', 'attitudeZ',
                 'timeStamp', 'accXABC', 'accYABC', 'accZABC', 'angAccXABC', 'angAccYABC', 'angAccZABC',
                 'gimbalPitchMotorAngle', 'gimbalRollMotorAngle')
SPHINX_DEFINITION = ''.join('%s %s\n' % ('float32' if f == 'timeStamp' else 'float64', f) for f in SPHINX_FIELDS)

_cache = {}


def load_message_class(type_name, definition):
    """The class of ``type_name`` ('pkg/Name'): the installed one if its package exists, else a dynamic one."""
    if type_name in _cache:
        return _cache[type_name]
    package, name = type_name.split('/')
    cls = None
    try:
        cls = getattr(importlib.import_module(package + '.msg'), name)
    except (ImportError, AttributeError):
        cls = genpy.dynamic.generate_dynamic(type_name, definition)[type_name]
    _cache[type_name] = cls
    return cls


def piloting_command_class():
    """``olympe_bridge/PilotingCommand`` (md5 38956f4c725541081234f467b900164a)."""
    return load_message_class(PILOTING_COMMAND_TYPE, PILOTING_COMMAND_DEFINITION)


def sphinx_class():
    """``sphinx_with_gazebo/Sphinx`` (md5 85390efb41e38eee13815912075e2a5a)."""
    return load_message_class(SPHINX_TYPE, SPHINX_DEFINITION)


def class_from_connection_header(header):
    """The message class a publisher announced in its connection header (dict of str -> str).

    Every ROS publisher sends its type name (``type``), md5 (``md5sum``) and full definition
    (``message_definition``) when a subscriber connects; this builds the class from them, so a type whose
    package is not installed here (``olympe_bridge/PilotingCommand`` from a real bridge, ``gazebo_msgs``)
    can still be decoded. Raises ValueError when the header lacks them or the built class's md5 differs.
    """
    type_name = header.get('type', '')
    definition = header.get('message_definition', '')
    if '/' not in type_name or not definition:
        raise ValueError('connection header without type / message_definition: %r' % sorted(header))
    key = (type_name, definition)
    if key not in _cache:
        _cache[key] = genpy.dynamic.generate_dynamic(type_name, definition)[type_name]
    cls = _cache[key]
    md5 = header.get('md5sum', cls._md5sum)
    if md5 != '*' and md5 != cls._md5sum:
        raise ValueError('%s: md5 %s in the header, %s from its definition' % (type_name, md5, cls._md5sum))
    return cls


def decode(header, buffer):
    """Deserialize one message (bytes ``buffer``) of the type announced in ``header`` (see above)."""
    return class_from_connection_header(header)().deserialize(buffer)


# --- the reference implementation's own message package ``anafi_control`` (its waypoint and state) --------
# Not to be confused with this project's control library of the same name (README, "The anafi_control name
# clash"): the classes below are the real ones when their message package is importable as
# ``anafi_control.msg`` (our package extends its path, so theirs is found behind ours), else built at run
# time with the same type names, fields and md5sums (definitions from shared/interfaces/anafi_ros.md).
_SEPARATOR = '=' * 80 + '\n'


def _definition(text, *dependencies):
    """``text`` followed by its dependencies ((type, text) pairs) in the ``gendeps --cat`` layout."""
    return text + ''.join('%sMSG: %s\n%s' % (_SEPARATOR, name, body) for name, body in dependencies)


_STD_HEADER = ('std_msgs/Header', 'uint32 seq\ntime stamp\nstring frame_id\n')
_VECTOR3_STAMPED = ('geometry_msgs/Vector3Stamped', 'std_msgs/Header header\ngeometry_msgs/Vector3 vector\n')
_VECTOR3 = ('geometry_msgs/Vector3', 'float64 x\nfloat64 y\nfloat64 z\n')
_TWIST_MODIFIED = ('anafi_control/TwistModified',
                   'geometry_msgs/Vector3Stamped linear\ngeometry_msgs/Vector3Stamped angular\n')
_TWIST_STAMPED_MODIFIED = ('anafi_control/TwistStampedModified',
                           'std_msgs/Header header\nanafi_control/TwistModified twist\n')

PAPER_WAYPOINT_TYPE = 'anafi_control/Waypoint'
PAPER_WAYPOINT_MD5 = 'c72c4e4d66b8cdce8f9bcb0dbae36dca'
PAPER_WAYPOINT_FIELDS = ('x', 'y', 'z', 'v_x', 'v_y', 'v_z', 'yaw')
PAPER_WAYPOINT_DEFINITION = ''.join('float64 %s\n' % f for f in PAPER_WAYPOINT_FIELDS)

PAPER_STATE_TYPE = 'anafi_control/State'
PAPER_STATE_MD5 = 'e65cd25dc6c41d22d5b47104c1dfbd7b'
PAPER_STATE_DEFINITION = _definition(
    'std_msgs/Header header\ngeometry_msgs/PoseStamped pose\nanafi_control/TwistStampedModified twist\n',
    _STD_HEADER,
    ('geometry_msgs/PoseStamped', 'std_msgs/Header header\ngeometry_msgs/Pose pose\n'),
    ('geometry_msgs/Pose', 'geometry_msgs/Point position\ngeometry_msgs/Quaternion orientation\n'),
    ('geometry_msgs/Point', 'float64 x\nfloat64 y\nfloat64 z\n'),
    ('geometry_msgs/Quaternion', 'float64 x\nfloat64 y\nfloat64 z\nfloat64 w\n'),
    _TWIST_STAMPED_MODIFIED, _TWIST_MODIFIED, _VECTOR3_STAMPED, _VECTOR3)
PAPER_TWIST_STAMPED_MODIFIED_MD5 = '953cf8d869ec497d6eb74723a9307a2e'
PAPER_TWIST_MODIFIED_MD5 = '2d3ab5e2b924162f6809bed7c278f6b8'


def paper_waypoint_class():
    """``anafi_control/Waypoint`` of the reference implementation (md5 c72c4e4d66b8cdce8f9bcb0dbae36dca)."""
    return load_message_class(PAPER_WAYPOINT_TYPE, PAPER_WAYPOINT_DEFINITION)


def paper_state_class():
    """``anafi_control/State`` of the reference implementation (md5 e65cd25dc6c41d22d5b47104c1dfbd7b)."""
    return load_message_class(PAPER_STATE_TYPE, PAPER_STATE_DEFINITION)
