"""anafi_sim.ros.wire_types: the stand-in olympe_bridge/PilotingCommand is wire-identical to the real one."""
from anafi_sim.ros.wire_types import PILOTING_COMMAND_TYPE, piloting_command_class


def test_piloting_command_md5_and_type():
    cls = piloting_command_class()
    assert cls._md5sum == '38956f4c725541081234f467b900164a'
    assert cls._type == PILOTING_COMMAND_TYPE == 'olympe_bridge/PilotingCommand'
    assert cls.__slots__[1:] == ['roll', 'pitch', 'yaw', 'gaz']


def test_piloting_command_round_trip():
    import io
    cls = piloting_command_class()
    msg = cls()
    msg.roll, msg.pitch, msg.yaw, msg.gaz = 1.5, -2.0, 45.0, 0.25
    buf = io.BytesIO()
    msg.serialize(buf)
    back = cls().deserialize(buf.getvalue())
    assert (back.roll, back.pitch, back.yaw, back.gaz) == (1.5, -2.0, 45.0, 0.25)
    assert piloting_command_class() is cls           # cached: one class per process


def _header_and_bytes(msg):
    import io
    buf = io.BytesIO()
    msg.serialize(buf)
    header = {'type': msg._type, 'md5sum': msg._md5sum, 'message_definition': msg._full_text,
              'callerid': '/anafi/mpc_controller', 'topic': '/anafi/drone/rpyt'}
    return header, buf.getvalue()


def test_decode_from_the_publishers_connection_header():
    """echo.py's core: a PilotingCommand decoded with only what the publisher sent (type, md5, definition)."""
    from anafi_sim.ros import wire_types
    msg = piloting_command_class()()
    msg.header.seq, msg.header.frame_id = 7, 'anafi/body'
    msg.roll, msg.pitch, msg.yaw, msg.gaz = 3.0, -4.5, 10.0, -0.5
    header, data = _header_and_bytes(msg)
    back = wire_types.decode(header, data)
    assert back._type == 'olympe_bridge/PilotingCommand'
    assert back._md5sum == '38956f4c725541081234f467b900164a'
    assert (back.roll, back.pitch, back.yaw, back.gaz) == (3.0, -4.5, 10.0, -0.5)
    assert back.header.frame_id == 'anafi/body' and back.header.seq == 7
    import genpy.message
    text = genpy.message.strify_message(back)
    assert 'pitch: -4.5' in text and 'frame_id: "anafi/body"' in text


def test_decode_a_gazebo_type_and_reject_bad_headers():
    import pytest
    from anafi_sim.ros import gazebo_types, wire_types
    states = gazebo_types.model_states_class()()
    states.name = ['anafi', 'anafi_camera']
    header, data = _header_and_bytes(states)
    assert wire_types.decode(header, data).name == ['anafi', 'anafi_camera']
    with pytest.raises(ValueError):
        wire_types.class_from_connection_header({'type': 'olympe_bridge/PilotingCommand'})  # no definition
    bad = dict(header, md5sum='0' * 32)
    with pytest.raises(ValueError):
        wire_types.class_from_connection_header(bad)
