"""anafi_control.pid_wiring: topic wiring of the distributed PID framework and command assembly (the input gate
and the odometry conversion are tested in test_contract.py and test_frames.py)."""
import math
import os
import xml.etree.ElementTree as ET

import pytest

HOVER = None     # CommandAssembler: no command (the firmware brakes)
from anafi_control.pid import PidController
from anafi_control.pid_framework import DEFAULT_CONFIG, LOOP_NAMES, PidFramework, relative_state
from anafi_control.pid_wiring import (CASCADES, COMMAND_LOOPS, DISABLED, CommandAssembler, input_topics,
                                      loop_inputs, loop_topics)
from conftest import ROOT

LAUNCH = os.path.join(ROOT, 'anafi_sim', 'launch', 'pid.launch')
NAN = float('nan')


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


@pytest.mark.parametrize('value', [0.0, -1.0, NAN, float('inf'), True, '1'])
def test_bad_effort_timeouts_are_refused(value):
    with pytest.raises(ValueError):
        CommandAssembler(effort_timeout=value)


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
    assert asm.command(-1.0)[0] is HOVER           # clock went back: not fresh


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
    assert asm.command(0.1)[0] is HOVER            # the old efforts were forgotten
    fill(asm, 0.2)
    assert asm.command(0.2)[1] is None
