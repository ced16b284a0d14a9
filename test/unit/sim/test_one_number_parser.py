"""The launch check and the nodes' parameters accept the same numbers (one parser, one table of ranges)."""
import pytest
from hypothesis import given, strategies as st

from anafi_sim.launch_check import check as _check
from anafi_sim.mission.fleet import launch_problem
from anafi_sim.numeric import parse_integer, parse_number
from anafi_sim.ros.params import ParamError, ParamReader


def check(args):
    return _check(args, {'fleet': launch_problem})


def node_accepts(name, text, positive=False):
    p = ParamReader(lambda n, default: text)
    try:
        (p.positive if positive else p.number)(name, 0.0)
        return True
    except ParamError as error:
        assert '\n' not in str(error)
        return False


def check_accepts(name, text):
    errors = check([(name, text)])
    assert all('\n' not in e for e in errors)
    return not errors


@pytest.mark.parametrize('name, text, accepted', [
    ('rtf', '1e0', True), ('rtf', '2.0', True), ('rtf', '1e308', False), ('rtf', 'inf', False),
    ('rtf', 'nan', False), ('rtf', '0', False), ('initial_x', '1e300', False), ('initial_x', '-2.5', True),
    ('initial_x', '١', False), ('initial_y', '²', False), ('rtf', '\n', False), ('initial_x', '1\n2', False),
])
def test_the_repro_values_get_the_same_answer(name, text, accepted):
    assert check_accepts(name, text) == accepted
    assert node_accepts(name, text, positive=(name == 'rtf')) == accepted


def test_a_refusal_names_the_range():
    assert any('[0, 1000]' in e for e in check([('rtf', '1e308')]))
    with pytest.raises(ParamError, match=r'\[-10000, 10000\]'):
        ParamReader(lambda n, d: '1e300').number('initial_x', 0.0)


def test_unicode_digits_are_one_line_not_a_traceback():
    errors = check([('drones', '²')])
    assert len(errors) == 1 and 'drones' in errors[0]
    assert parse_integer('²') is None and parse_number('²') is None
    with pytest.raises(ParamError):
        ParamReader(lambda n, d: '²').integer('drones', 0)


@given(st.one_of(st.text(max_size=12), st.floats().map(repr), st.integers().map(str)))
def test_check_and_node_agree_on_any_text(text):
    for name, positive in (('rtf', True), ('initial_x', False)):
        if name == 'initial_x' and text.strip() == '':
            continue    # '' = the launch file leaves the parameter unset (sim.yaml's)
        assert check_accepts(name, text) == node_accepts(name, text, positive)


def test_fleet_launch_checks_the_fleet_file_before_anything_starts(tmp_path, monkeypatch):
    monkeypatch.setenv('ROS_HOME', str(tmp_path))      # the conservative cap, not this machine's measured one
    assert check([('fleet', 'circles'), ('drones', '0')]) == []
    hostile = tmp_path / 'hostile.yaml'
    hostile.write_text('drones:\n  - name: a\n    target: {model: "$(eval exec(\'import os\'))"}\n')
    errors = check([('fleet', str(hostile)), ('drones', '0')])
    assert len(errors) == 1 and 'target.model' in errors[0] and '\n' not in errors[0]
    big = tmp_path / 'big.yaml'
    big.write_text('layout: shared\ndrones:\n' + ''.join('  - {name: a%d, scenario: static_wp0, start: [%d, 0]}\n'
                                                       % (i, 2 * i) for i in range(200)))
    errors = check([('fleet', str(big)), ('drones', '0'), ('max_drones', '0'), ('layout', '')])
    assert len(errors) == 1 and 'fleet cap' in errors[0] and 'shared' in errors[0]
    assert check([('fleet', str(tmp_path / 'missing.yaml'))])[0].endswith('missing.yaml')
