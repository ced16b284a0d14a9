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
