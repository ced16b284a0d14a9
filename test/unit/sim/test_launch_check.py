"""Launch arguments checked before any node starts (anafi_sim.launch_check, scripts/check_launch_args.py)."""
import os
import subprocess
import sys

import pytest

from anafi_sim import launch_check
from anafi_sim.launch_check import RULES, check, parse
from conftest import ROOT

SCRIPT = os.path.join(ROOT, 'anafi_sim', 'scripts', 'check_launch_args.py')


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
    ('fence_radius=0', ['fence_radius']), ('fence_min_altitude=low', ['fence_min_altitude']),
    ('max_reach=-2', ['max_reach']), ('source=odom', ['source', 'state_enu']), ('world_yaw=inf', ['world_yaw']),
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


def test_the_fleet_cap_comes_from_the_measured_cost_per_drone(monkeypatch):
    from anafi_sim import launch_check
    from anafi_sim.launch_check import fleet_cap, fleet_size_problem
    monkeypatch.setattr(launch_check, 'CPU_PER_DRONE', {'per_drone': 0.165, 'shared': 0.1})
    monkeypatch.setattr(launch_check, 'FAILING_PER_CORE', {'per_drone': None, 'shared': None})
    assert fleet_cap(2) == 12 and fleet_cap(1) == 6 and fleet_cap(0.1) == 1
    assert fleet_cap(2, 'shared') == 20 and fleet_cap(2, layout='per_drone') == 12
    assert fleet_size_problem(12, cores=2) is None and fleet_size_problem(20, cores=2, layout='shared') is None
    problem = fleet_size_problem(50, cores=2)
    assert problem == ('50 drones is more than the fleet cap of 12 (2 cores / 0.165 core per drone '
                       '(benchmarks/results/fleet.md): slower than real time beyond it; max_drones:=N to raise it)')
    problem = fleet_size_problem(50, 0, 2, 'shared')
    assert problem.startswith('50 drones is more than the fleet cap of 20 (2 cores / 0.100 core per drone '
                              '(shared layout, benchmarks/results/fleet.md)')
    assert fleet_size_problem(50, max_drones=60) is None and 'max_drones:=20' in fleet_size_problem(30, 20)
    with pytest.raises(KeyError):
        fleet_cap(2, 'no_such_layout')


def test_the_fleet_cap_stays_below_the_smallest_fleet_measured_not_to_hold(monkeypatch):
    from anafi_sim import launch_check
    from anafi_sim.launch_check import fleet_cap, fleet_size_problem
    monkeypatch.setattr(launch_check, 'CPU_PER_DRONE', {'per_drone': 0.271, 'shared': 0.06})
    monkeypatch.setattr(launch_check, 'FAILING_PER_CORE', {'per_drone': 4.0, 'shared': 12.5})
    assert fleet_cap(2) == 7                     # 2 / 0.271 = 7.4 and 8 did not hold: 7 either way
    assert fleet_cap(2, 'shared') == 24          # 2 / 0.06 = 33, but 25 did not hold on 2 cores
    assert fleet_cap(4, 'shared') == 49 and fleet_cap(1, 'shared') == 12 and fleet_cap(0.01, 'shared') == 1
    assert fleet_size_problem(24, cores=2, layout='shared') is None
    problem = fleet_size_problem(25, cores=2, layout='shared')
    assert problem.startswith('25 drones is more than the fleet cap of 24 (2 cores / 0.060 core per drone, below '
                              '25 drones (12.5 per core) measured not to hold (shared layout')
    assert 'measured not to hold' not in fleet_size_problem(8, cores=2)


def test_drones_above_the_cap_fail_the_launch_check():
    from anafi_sim.launch_check import fleet_cap
    [line] = check(parse(['drones=%d' % (fleet_cap() + 1), 'max_drones=0']))
    assert line.startswith('launch argument drones:=') and 'fleet cap' in line
    assert check(parse(['drones=%d' % (fleet_cap() + 1), 'max_drones=%d' % (fleet_cap() + 1)])) == []
    assert check(parse(['drones=0'])) == []


def test_the_fleet_size_is_checked_against_the_layout_given(monkeypatch):
    monkeypatch.setattr(launch_check, 'CPU_PER_DRONE', {'per_drone': 0.2, 'shared': 0.1})
    monkeypatch.setattr(launch_check, 'FAILING_PER_CORE', {'per_drone': None, 'shared': None})
    monkeypatch.setattr(launch_check, 'available_cores', lambda: 2)
    assert launch_check.check([('drones', '15'), ('layout', 'shared')]) == []
    [line] = launch_check.check([('drones', '15'), ('layout', '')])      # '' = per_drone here (its launcher rechecks)
    assert 'fleet cap of 10' in line
    [line] = launch_check.check([('layout', 'pooled')])
    assert 'must be per_drone or shared' in line


def test_the_fence_altitudes_must_be_in_order():
    assert check(parse(['fence_radius=5', 'fence_min_altitude=1', 'fence_max_altitude=4', 'max_reach='])) == []
    [line] = check(parse(['fence_min_altitude=4', 'fence_max_altitude=1']))
    assert 'fence_max_altitude:=1' in line and 'above' in line
