"""Launch arguments checked before any node starts (anafi_sim.launch_check, scripts/check_launch_args.py)."""
import os
import subprocess
import sys

import pytest

from anafi_sim.launch_check import RULES, check, parse

SCRIPT = os.path.join(os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__)))),
                      'anafi_sim', 'scripts', 'check_launch_args.py')


def test_the_launch_files_defaults_pass():
    assert check(parse(['drone_name=anafi', 'rtf=1.0', 'use_sim_time=false', 'telemetry_port=9060',
                        'initial_x=', 'initial_y=-2.5', 'initial_yaw=', 'model_file=anafi_model.yaml',
                        'controller=mpc', 'scenario=circle_r2_v1', 'scenario_file=', 'pid_mode=distributed',
                        'progress_period=0', 'ready_timeout=90', 'sync=false', 'sync_period=0.1'])) == []


@pytest.mark.parametrize('arg, words', [
    ('rtf=-1', ['rtf:=-1', '> 0']), ('rtf=0', ['rtf:=0']), ('rtf=nan', ['rtf:=nan']), ('rtf=fast', ['rtf']),
    ('scenario=circl_r2_v1', ['scenario:=circl_r2_v1', 'circle_r2_v1']),
    ('scenario=../../../etc/passwd', ['scenario:=']), ('telemetry_port=70000', ['telemetry_port']),
    ('drone_name=1drone', ['drone_name']), ('initial_x=1e999', ['initial_x']), ('controller=lqr', ['controller']),
    ('model_file=nope.yaml', ['model_file', 'anafi_model.yaml']), ('model_file=../sim.yaml', ['model_file']),
    ('use_sim_time=yes', ['use_sim_time']), ('scenario_file=/no/such.yaml', ['scenario_file']),
])
def test_a_bad_argument_is_one_line_naming_it(arg, words):
    [line] = check(parse([arg]))
    assert line.startswith('launch argument ') and all(w in line for w in words), line


def test_a_scenario_file_wins_over_the_scenario_name(tmp_path):
    path = tmp_path / 'mine.yaml'
    path.write_text('x: 1\n')
    assert check(parse(['scenario=unknown', 'scenario_file=%s' % path])) == []


def test_an_argument_without_a_rule_is_a_launch_file_error():
    with pytest.raises(ValueError, match='no rule'):
        check(parse(['bogus=1']))
    with pytest.raises(ValueError, match='NAME=VALUE'):
        parse(['rtf'])
    assert 'rtf' in RULES


def test_the_script_exits_non_zero_with_the_line_and_prints_ok_otherwise():
    bad = subprocess.run([sys.executable, SCRIPT, 'rtf=-1', 'drone_name=anafi'], capture_output=True, text=True)
    assert bad.returncode == 2 and bad.stdout == ''
    assert bad.stderr.strip().splitlines() == ['launch argument rtf:=-1: must be a finite number > 0']
    good = subprocess.run([sys.executable, SCRIPT, 'rtf=2'], capture_output=True, text=True)
    assert good.returncode == 0 and good.stdout == 'ok'
