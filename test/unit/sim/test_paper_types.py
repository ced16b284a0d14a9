"""The reference implementation's own message types (anafi_control/Waypoint, State) and the one waypoint
conversion (anafi_sim.ros.waypoints): wire-identical, field for field, to the shared interface notes."""
import io

import genpy
import pytest

from anafi_sim.ros import waypoints, wire_types


def round_trip(msg):
    buf = io.BytesIO()
    msg.serialize(buf)
    return type(msg)().deserialize(buf.getvalue())


def test_md5sums_and_type_names_are_the_shared_notes():
    waypoint, state = wire_types.paper_waypoint_class(), wire_types.paper_state_class()
    assert (waypoint._type, waypoint._md5sum) == ('anafi_control/Waypoint', 'c72c4e4d66b8cdce8f9bcb0dbae36dca')
    assert (state._type, state._md5sum) == ('anafi_control/State', 'e65cd25dc6c41d22d5b47104c1dfbd7b')
    s = state()
    assert (type(s.twist)._type, type(s.twist)._md5sum) == ('anafi_control/TwistStampedModified',
                                                            '953cf8d869ec497d6eb74723a9307a2e')
    assert (type(s.twist.twist)._type, type(s.twist.twist)._md5sum) == ('anafi_control/TwistModified',
                                                                        '2d3ab5e2b924162f6809bed7c278f6b8')
    assert waypoint.__slots__ == ['x', 'y', 'z', 'v_x', 'v_y', 'v_z', 'yaw']        # no header
    assert state.__slots__ == ['header', 'pose', 'twist']


def test_no_module_named_like_their_package_is_created():
    import os
    import sys
    wire_types.paper_state_class()
    assert 'anafi_control.msg' not in sys.modules           # their package is absent here: nothing stands in
    from conftest import ROOT as root
    assert not os.path.exists(os.path.join(root, 'anafi_control', 'msg'))


def test_state_round_trip():
    msg = wire_types.paper_state_class()()
    msg.header.frame_id = '/world'
    msg.pose.pose.position.x, msg.pose.pose.orientation.w = 1.5, 1.0
    msg.twist.twist.linear.vector.z = -0.25
    back = round_trip(msg)
    assert back.header.frame_id == '/world' and back.pose.pose.position.x == 1.5
    assert back.twist.twist.linear.vector.z == -0.25


NUMBERS = (1.0, 2.0, 3.0, 0.5, -0.5, 0.25, 120.0)


@pytest.mark.parametrize('kind', waypoints.WAYPOINT_TYPES)
def test_waypoint_numbers_survive_both_types_and_the_wire(kind):
    msg = waypoints.waypoint_message(kind, NUMBERS, genpy.Time(12, 5), 'world')
    assert waypoints.kind_of(msg) == kind
    assert waypoints.waypoint_numbers(round_trip(msg)) == NUMBERS
    other = [k for k in waypoints.WAYPOINT_TYPES if k != kind][0]
    converted = waypoints.convert(msg, other)
    assert waypoints.kind_of(converted) == other and waypoints.waypoint_numbers(converted) == NUMBERS


def test_header_of_our_type_and_none_for_theirs():
    ours = waypoints.waypoint_message('anafi_sim', NUMBERS, 3.5, 'map')
    assert ours._type == 'anafi_sim/Waypoint'
    assert ours.header.stamp == genpy.Time.from_sec(3.5) and ours.header.frame_id == 'map'
    assert (ours.vx, ours.vy, ours.vz) == NUMBERS[3:6]
    theirs = waypoints.waypoint_message('anafi_control', NUMBERS)
    assert (theirs.v_x, theirs.v_y, theirs.v_z) == NUMBERS[3:6] and waypoints.stamp_of(theirs) is None
    assert waypoints.convert(theirs, 'anafi_sim', stamp=2.0).header.stamp == genpy.Time.from_sec(2.0)


def test_default_and_refusals():
    assert waypoints.DEFAULT_WAYPOINT_TYPE == 'anafi_sim'      # nothing changes for existing users
    with pytest.raises(ValueError):
        waypoints.waypoint_class('geometry_msgs')
    with pytest.raises(ValueError):
        waypoints.waypoint_numbers(object())
