"""anafi_control.pid_wiring: topic wiring of the distributed PID framework, odometry, input gate, command assembly."""
import math
import os
import xml.etree.ElementTree as ET

import pytest

from anafi_control.frames import euler_to_quaternion
from anafi_control.pid import PidController
from anafi_control.pid_framework import DEFAULT_CONFIG, HOVER, LOOP_NAMES, PidFramework, relative_state
from anafi_control.pid_wiring import (BAD_STATE, BAD_WAYPOINT, CASCADES, COMMAND_LOOPS, DISABLED,
                                      NO_STATE, NO_WAYPOINT, STALE_STATE, STALE_WAYPOINT,
                                      CommandAssembler, InputGate, check_timeout, input_topics,
                                      loop_inputs, loop_topics, odometry_state)

REPO = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
LAUNCH = os.path.join(REPO, 'anafi_sim', 'launch', 'pid.launch')
NAN = float('nan')
LEVEL = (0.0, 0.0, 0.0, 1.0)
WP = (3.0, 2.0, 5.0, 0.0, 0.0, 0.0, 0.0)


# -- topic wiring -------------------------------------------------------------------------
def test_cascades_take_the_outer_effort_as_setpoint():
    assert loop_topics('x_inner')['setpoint_topic'] == 'x_outer/control_effort'
    assert loop_topics('y_inner')['setpoint_topic'] == 'y_outer/control_effort'
    assert loop_topics('x_outer') == {'setpoint_topic': 'x_outer/setpoint', 'topic_from_plant': 'x_outer/state',
                                      'topic_from_controller': 'x_outer/control_effort',
                                      'pid_enable_topic': 'pid_enable'}
    with pytest.raises(ValueError):
        loop_topics('z_outer')


def test_relative_state_feeds_every_loop_input_that_is_not_a_cascade():
    published = set(input_topics())
    for loop in LOOP_NAMES:
        topics = loop_topics(loop)
        assert topics['topic_from_plant'] in published, loop
        assert (topics['setpoint_topic'] in published) == (loop not in CASCADES), loop
    # nothing published that no loop reads
    read = set(t for loop in LOOP_NAMES for t in (loop_topics(loop)['setpoint_topic'],
                                                   loop_topics(loop)['topic_from_plant']))
    assert published <= read


def test_loop_inputs_values_at_heading_90():
    rel = relative_state((1.0, 1.0, 2.0), (0.0, 3.0, 0.5), math.radians(90.0), (1.0, 4.0, 5.0, 0, 0, 0, -170.0))
    values = dict(loop_inputs(rel))
    assert values['x_outer/setpoint'] == pytest.approx(3.0)      # 3 m north = ahead when facing north
    assert values['y_outer/setpoint'] == pytest.approx(0.0, abs=1e-12)
    assert values['x_inner/state'] == pytest.approx(3.0)         # flying forward at 3 m/s
    assert values['y_inner/state'] == pytest.approx(0.0, abs=1e-12)
    assert values['vertical/setpoint'] == pytest.approx(3.0)
    assert values['yaw/setpoint'] == -170.0 and values['yaw/state'] == pytest.approx(90.0)
    for loop in ('x_outer', 'y_outer', 'vertical'):
        assert values[loop + '/state'] == 0.0                    # the drone is the origin


def test_command_fields_come_from_the_right_loops():
    assert list(COMMAND_LOOPS.items()) == [('roll', 'y_inner'), ('pitch', 'x_inner'), ('yaw', 'yaw'),
                                           ('gaz', 'vertical')]


def _launch_nodes():
    root = ET.parse(LAUNCH).getroot()
    out = {}
    for node in root.iter('node'):
        if node.get('type') == 'pid_controller.py':
            out[node.get('name')] = dict((p.get('name'), p.get('value')) for p in node.findall('param'))
    return root, out


def test_launch_file_wires_the_loops_like_the_table():
    root, nodes = _launch_nodes()
    assert sorted(nodes) == sorted(LOOP_NAMES)
    for loop, params in nodes.items():
        assert params == dict(loop_topics(loop)), loop
    # the controllers live in <drone>/pid, where pid.yaml is loaded (their private parameters)
    loads = [r for r in root.iter('rosparam') if r.get('file', '').endswith('/pid.yaml')]
    assert any(r.get('ns') == 'pid' for r in loads)


def _distributed_command(loops, efforts, rel, t):
    """One cycle of the distributed wiring using only the tables: each loop computes once, outer first."""
    inputs = dict(loop_inputs(rel))
    for loop in sorted(LOOP_NAMES, key=lambda name: name in CASCADES):     # outer loops before inner ones
        topics = loop_topics(loop)
        setpoint_topic = topics['setpoint_topic']
        if setpoint_topic.endswith('/control_effort'):
            setpoint = efforts[setpoint_topic.split('/')[0]]
        else:
            setpoint = inputs[setpoint_topic]
        effort = loops[loop].update(setpoint, inputs[topics['topic_from_plant']], t)
        if effort is not None:
            efforts[loop] = effort
    return tuple(efforts[loop] for loop in COMMAND_LOOPS.values())


def test_tables_reproduce_the_single_process_framework():
    """The wiring tables driving six PidControllers give the PidFramework's commands, cycle by cycle."""
    fw = PidFramework()
    loops = dict((name, PidController(**DEFAULT_CONFIG[name])) for name in LOOP_NAMES)
    efforts = dict((name, 0.0) for name in LOOP_NAMES)
    pos, vel, yaw = [0.0, 0.0, 1.0], [0.0, 0.0, 0.0], 0.3
    compared = 0
    for k in range(90):
        t = k / 30.0
        wp = (3.0 + 0.5 * t, 2.0, 5.0, 0.5, 0.0, 0.0, 170.0 if k < 45 else -175.0)
        assert fw.update(t, tuple(pos), tuple(vel), yaw, wp)
        cmd = _distributed_command(loops, efforts, relative_state(tuple(pos), tuple(vel), yaw, wp), t)
        if k >= 1:
            assert cmd == pytest.approx(fw.command(), rel=1e-12, abs=1e-12)
            compared += 1
        # crude motion so that every input changes
        vel = [vel[0] + 0.02 * cmd[1], vel[1] - 0.02 * cmd[0], 0.5 * cmd[3]]
        pos = [p + v / 30.0 for p, v in zip(pos, vel)]
        yaw = math.atan2(math.sin(yaw + math.radians(cmd[2]) / 30.0), math.cos(yaw + math.radians(cmd[2]) / 30.0))
    assert compared == 89 and any(v != 0.0 for v in fw.command())


# -- odometry ------------------------------------------------------------------------------
@pytest.mark.parametrize('roll,pitch,yaw,body,world', [
    (0.0, 0.0, 0.0, (1.0, 2.0, 3.0), (1.0, 2.0, 3.0)),
    (0.0, 0.0, 90.0, (1.0, 0.0, 0.0), (0.0, 1.0, 0.0)),        # nose north: forward = +y
    (0.0, 0.0, 180.0, (1.0, 1.0, 0.0), (-1.0, -1.0, 0.0)),
    (0.0, 30.0, 0.0, (1.0, 0.0, 0.0), (math.cos(math.radians(30)), 0.0, -math.sin(math.radians(30)))),
    (20.0, 0.0, -90.0, (0.0, 1.0, 0.0), (math.cos(math.radians(20)), 0.0, math.sin(math.radians(20)))),
])
def test_odometry_twist_is_rotated_from_body_to_world(roll, pitch, yaw, body, world):
    q = euler_to_quaternion(math.radians(roll), math.radians(pitch), math.radians(yaw))
    pos, vel, heading = odometry_state((1.0, 2.0, 3.0), q, body)
    assert pos == (1.0, 2.0, 3.0)
    assert vel == pytest.approx(world, abs=1e-12)
    assert heading == pytest.approx(math.radians(yaw))


def test_odometry_refuses_garbage_and_normalises():
    assert odometry_state((0, NAN, 0), LEVEL, (0, 0, 0)) is None
    assert odometry_state((0, 0, 0), (0, 0, 0, float('inf')), (0, 0, 0)) is None
    assert odometry_state((0, 0, 0), LEVEL, (0, 0, NAN)) is None
    assert odometry_state((0, 0, 0), (0, 0, 0, 0), (0, 0, 0)) is None          # not a rotation
    assert odometry_state((0, 0), LEVEL, (0, 0, 0)) is None
    _, vel, heading = odometry_state((0, 0, 0), (0, 0, 2.0 * math.sin(0.25), 2.0 * math.cos(0.25)), (1, 0, 0))
    assert heading == pytest.approx(0.5) and vel == pytest.approx((math.cos(0.5), math.sin(0.5), 0.0))


# -- input gate ----------------------------------------------------------------------------
def test_gate_reasons_in_order_then_runs():
    gate = InputGate(state_timeout=0.5, waypoint_timeout=1.0)
    assert gate.step(0.0) == (None, NO_STATE)
    gate.on_state(0.1, (1, 2, 3), LEVEL, (0, 0, 0))
    assert gate.step(0.2) == (None, NO_WAYPOINT)
    gate.on_waypoint(0.2, WP)
    inputs, reason = gate.step(0.3)
    assert reason is None
    assert inputs.pos == (1, 2, 3) and inputs.vel == (0, 0, 0) and inputs.yaw == 0.0 and inputs.waypoint == WP
    assert gate.cycles == 3 and gate.hover_cycles == 2


def test_gate_stale_state_and_waypoint():
    gate = InputGate(state_timeout=0.5, waypoint_timeout=1.0)
    gate.on_state(0.0, (0, 0, 0), LEVEL, (0, 0, 0))
    gate.on_waypoint(0.0, WP)
    assert gate.step(0.5)[1] is None                 # exactly the timeout is still fresh
    assert gate.step(0.51) == (None, STALE_STATE)
    gate.on_state(0.9, (0, 0, 0), LEVEL, (0, 0, 0))
    assert gate.step(1.0)[1] is None
    assert gate.step(1.01) == (None, STALE_WAYPOINT)
    gate.on_waypoint(1.1, WP)
    assert gate.step(1.2)[1] is None


def test_gate_waypoint_timeout_zero_holds_a_single_waypoint():
    gate = InputGate(state_timeout=0.5, waypoint_timeout=0.0)
    gate.on_waypoint(0.0, WP)
    gate.on_state(100.0, (0, 0, 0), LEVEL, (0, 0, 0))
    assert gate.step(100.1)[1] is None


@pytest.mark.parametrize('bad', ['state', 'waypoint', 'waypoint_short'])
def test_gate_non_finite_input_hovers_until_a_good_sample(bad):
    gate = InputGate()
    gate.on_state(0.0, (0, 0, 0), LEVEL, (0, 0, 0))
    gate.on_waypoint(0.0, WP)
    if bad == 'state':
        assert not gate.on_state(0.1, (0, 0, 0), LEVEL, (NAN, 0, 0))
        assert gate.step(0.1) == (None, BAD_STATE) and gate.bad_states == 1
        gate.on_state(0.2, (0, 0, 0), LEVEL, (0, 0, 0))
    else:
        assert not gate.on_waypoint(0.1, WP[:6] + (NAN,) if bad == 'waypoint' else WP[:3])
        assert gate.step(0.1) == (None, BAD_WAYPOINT) and gate.bad_waypoints == 1
        gate.on_waypoint(0.2, WP)
    assert gate.step(0.2)[1] is None


def test_gate_clock_going_back_drops_inputs():
    gate = InputGate()
    gate.on_state(10.0, (0, 0, 0), LEVEL, (0, 0, 0))
    gate.on_waypoint(10.0, WP)
    assert gate.step(10.1)[1] is None
    assert gate.step(1.0) == (None, NO_STATE)        # simulation restarted
    assert gate.clock_jumps == 1


@pytest.mark.parametrize('value', [0.0, -1.0, NAN, float('inf'), True, '1'])
def test_bad_timeouts_are_refused(value):
    with pytest.raises(ValueError):
        InputGate(state_timeout=value)
    with pytest.raises(ValueError):
        CommandAssembler(effort_timeout=value)


def test_timeout_zero_allowed_only_where_it_means_never():
    assert check_timeout('w', 0, allow_zero=True) == 0.0
    with pytest.raises(ValueError):
        InputGate(waypoint_timeout=-0.1)


# -- command assembly ----------------------------------------------------------------------
def fill(asm, t, roll=1.0, pitch=2.0, yaw=3.0, gaz=0.5):
    for field, value in (('roll', roll), ('pitch', pitch), ('yaw', yaw), ('gaz', gaz)):
        asm.on_effort(field, t, value)


def test_assembler_orders_the_fields_and_needs_all_four():
    asm = CommandAssembler(effort_timeout=0.5)
    assert asm.command(0.0) == (HOVER, 'no effort yet from y_inner')
    asm.on_effort('roll', 0.0, -4.0)
    asm.on_effort('pitch', 0.0, 5.0)
    asm.on_effort('yaw', 0.0, 6.0)
    assert asm.command(0.1) == (HOVER, 'no effort yet from vertical')
    asm.on_effort('gaz', 0.1, 1.5)
    assert asm.command(0.2) == ((-4.0, 5.0, 6.0, 1.5), None)
    assert asm.commands == 3 and asm.hovers == 2
    with pytest.raises(ValueError):
        asm.on_effort('thrust', 0.0, 1.0)


def test_assembler_stale_effort_hovers():
    asm = CommandAssembler(effort_timeout=0.5)
    fill(asm, 0.0)
    asm.on_effort('roll', 0.4, 1.0)
    asm.on_effort('pitch', 0.4, 1.0)
    asm.on_effort('gaz', 0.4, 1.0)
    assert asm.command(0.5)[1] is None
    assert asm.command(0.51) == (HOVER, 'stale effort from yaw')
    assert asm.command(-1.0)[0] == HOVER           # clock went back: not fresh


def test_assembler_non_finite_effort_hovers_and_counts():
    asm = CommandAssembler()
    fill(asm, 0.0)
    assert not asm.on_effort('pitch', 0.1, NAN)
    assert asm.command(0.1) == (HOVER, 'non-finite effort from x_inner')
    assert asm.bad_efforts == 1
    asm.on_effort('pitch', 0.2, 2.0)
    assert asm.command(0.2) == ((1.0, 2.0, 3.0, 0.5), None)


def test_assembler_disable_hovers_and_needs_fresh_efforts_after_enable():
    asm = CommandAssembler()
    fill(asm, 0.0)
    asm.on_enable(False)
    assert asm.command(0.1) == (HOVER, DISABLED)
    asm.on_enable(True)
    assert asm.command(0.1)[0] == HOVER            # the old efforts were forgotten
    fill(asm, 0.2)
    assert asm.command(0.2)[1] is None


def test_gate_health_waiting_for_the_first_waypoint_is_not_a_warning():
    from anafi_control.pid_wiring import NO_WAYPOINT, STALE_STATE, gate_health
    assert gate_health(None) == (False, 'tracking')
    assert gate_health(NO_WAYPOINT) == (False, 'hovering: ' + NO_WAYPOINT)
    assert gate_health(STALE_STATE) == (True, 'hovering: ' + STALE_STATE)
