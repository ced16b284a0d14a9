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
