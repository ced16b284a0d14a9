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
    assert check(parse(['scenario=circle_r2_v1', 'scenario_file=none'])) == []     # none: no file
    [line] = check(parse(['scenario=unknown', 'scenario_file=none']))
    assert line.startswith('launch argument scenario:=unknown')


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


def figures(cpu, failing=None, model='Test CPU', cores=2, date='2026-01-01 00:00', source='cache'):
    failing = failing or dict((k, None) for k in cpu)
    return launch_check.CapFigures(cpu, failing, model, cores, date, source)


def test_the_fleet_cap_comes_from_the_measured_cost_per_drone():
    from anafi_sim.launch_check import fleet_cap, fleet_size_problem
    f = figures({'per_drone': 0.165, 'shared': 0.1})
    assert fleet_cap(2, figures=f) == 12 and fleet_cap(1, figures=f) == 6 and fleet_cap(0.1, figures=f) == 1
    assert fleet_cap(2, 'shared', f) == 20 and fleet_cap(2, layout='per_drone', figures=f) == 12
    cap = launch_check.Cap(12, 2, 'per_drone', f, True, 'measured here on Test CPU')
    assert fleet_size_problem(12, cap=cap) is None
    assert fleet_size_problem(50, cap=cap) == (
        '50 drones is more than the fleet cap of 12 (measured here on Test CPU: slower than real time beyond it; '
        'max_drones:=N to raise it)')
    assert fleet_size_problem(50, max_drones=60, cap=cap) is None
    assert 'max_drones:=20' in fleet_size_problem(30, 20, cap=cap)
    with pytest.raises(KeyError):
        fleet_cap(2, 'no_such_layout')


def test_the_fleet_cap_stays_below_the_smallest_fleet_measured_not_to_hold():
    from anafi_sim.launch_check import fleet_cap
    f = figures({'per_drone': 0.271, 'shared': 0.06}, {'per_drone': 4.0, 'shared': 12.5})
    assert fleet_cap(2, figures=f) == 7                     # 2 / 0.271 = 7.4 and 8 did not hold: 7 either way
    assert fleet_cap(2, 'shared', f) == 24                  # 2 / 0.06 = 33, but 25 did not hold on 2 cores
    assert fleet_cap(4, 'shared', f) == 49 and fleet_cap(1, 'shared', f) == 12 and fleet_cap(0.01, 'shared', f) == 1


def _write_cache(path, model='Test CPU', cores=2, layouts=None, date='2026-01-02 03:04'):
    from anafi_sim import run_files
    layouts = layouts or {'shared': {'cpu_per_drone': 0.09, 'failing_per_core': 10.0, 'largest_holding': 16}}
    data = launch_check.cap_cache_with(run_files.read_yaml(str(path)), model, cores, date, layouts, load=0.5)
    run_files.write_yaml(str(path), data)
    return data


def test_the_machine_cap_is_its_own_measurement_from_the_cache(tmp_path):
    path = tmp_path / 'fleet_cap.yaml'
    _write_cache(path)
    cap = launch_check.machine_cap('shared', cores=2, model='Test CPU', cache_path=str(path))
    assert cap.measured and cap.drones == 19 and cap.figures.cpu_per_drone == {'shared': 0.09}
    problem = launch_check.fleet_size_problem(20, cap=cap)
    assert problem == ('20 drones is more than the fleet cap of 19 (measured here on Test CPU, 2 cores at '
                       '2026-01-02 03:04: 2 cores / 0.090 core per drone, below 20 drones (10 per core) measured '
                       'not to hold (%s): slower than real time beyond it; max_drones:=N to raise it)' % path)
    # another CPU model, other cores, a layout not measured: the conservative default
    for model, cores, layout in (('Other CPU', 2, 'shared'), ('Test CPU', 4, 'shared'), ('Test CPU', 2, 'per_drone')):
        cap = launch_check.machine_cap(layout, cores=cores, model=model, cache_path=str(path))
        assert not cap.measured and cap.drones == launch_check.default_cap(cores, layout), (model, cores, layout)
    # a second machine and a second layout: merged, the first kept
    _write_cache(path, model='Other CPU', cores=8)
    _write_cache(path, layouts={'per_drone': {'cpu_per_drone': 0.3, 'failing_per_core': None}})
    assert launch_check.machine_cap('per_drone', 2, 'Test CPU', str(path)).drones == 6
    assert launch_check.machine_cap('shared', 2, 'Test CPU', str(path)).drones == 19
    assert launch_check.machine_cap('shared', 8, 'Other CPU', str(path)).measured


def test_without_a_measurement_the_cap_is_the_conservative_default_and_says_how_to_measure(tmp_path):
    path = str(tmp_path / 'none' / 'fleet_cap.yaml')
    cap = launch_check.machine_cap('shared', cores=2, model='Intel(R) Xeon(R) CPU', cache_path=path)
    reference = launch_check.fleet_cap(2, 'shared')
    assert not cap.measured and cap.drones == max(1, int(launch_check.DEFAULT_CAP_SCALE * reference))
    assert cap.drones < reference
    line = launch_check.fleet_size_problem(cap.drones + 1, cap=cap)
    for words in ('fleet cap of %d (conservative default, not measured on this machine (Intel(R) Xeon(R) CPU, '
                  '2 cores)' % cap.drones, 'the %d of the reference machine (AMD EPYC, 2 cores at' % reference,
                  'benchmarks/results/fleet.md', launch_check.CALIBRATE_COMMAND, 'max_drones:=N'):
        assert words in line, line
    assert launch_check.default_cap(0.1, 'per_drone') == 1


@pytest.mark.parametrize('text', ['', ':::', 'machines: 3', 'machines: {"Test CPU, 2 cores": {layouts: {shared: '
                                  '{cpu_per_drone: -1}}}}', 'machines: {"Test CPU, 2 cores": {layouts: {pooled: '
                                  '{cpu_per_drone: 0.1}}}}', 'machines: {"Test CPU, 2 cores": {layouts: {shared: '
                                  '{cpu_per_drone: .nan}}}}', 'machines: {"Test CPU, 2 cores": {layouts: {shared: '
                                  '{failing_per_core: 3}}}}'])
def test_a_bad_cache_gives_the_default_never_an_error(tmp_path, text):
    path = tmp_path / 'fleet_cap.yaml'
    path.write_text(text)
    assert launch_check.read_cap_cache(str(path), 'Test CPU', 2) is None
    assert not launch_check.machine_cap('shared', 2, 'Test CPU', str(path)).measured


def test_the_cache_key_names_the_cpu_model_the_benchmark_pages_name(tmp_path):
    from anafi_sim import processes
    assert launch_check.cpu_model() == processes.cpu_model()
    info = tmp_path / 'cpuinfo'
    info.write_text('processor\t: 0\nmodel name\t: Intel(R) Xeon(R) CPU @ 2.20GHz\nprocessor\t: 1\n')
    assert launch_check.cpu_model(str(info)) == 'Intel(R) Xeon(R) CPU @ 2.20GHz'
    assert launch_check.cpu_model(str(tmp_path / 'none'))                    # what platform knows, or 'unknown'
    assert launch_check.machine_key('Intel(R) Xeon(R) CPU @ 2.20GHz', 2) == 'Intel(R) Xeon(R) CPU @ 2.20GHz, 2 cores'


def test_the_cache_is_under_the_ros_home_and_refuses_bad_figures(tmp_path):
    assert launch_check.cap_cache_path({'ROS_HOME': '/r'}) == '/r/anafi_sim/fleet_cap.yaml'
    assert launch_check.cap_cache_path({}).endswith('/.ros/anafi_sim/fleet_cap.yaml')
    with pytest.raises(ValueError):
        launch_check.cap_cache_with(None, 'Test CPU', 2, 'now', {'shared': {'cpu_per_drone': 0.0}})
    data = launch_check.cap_cache_with({'machines': 'garbage'}, 'Test CPU', 2, 'now',
                                       {'shared': {'cpu_per_drone': 0.1}})
    assert list(data['machines']) == ['Test CPU, 2 cores']


def test_drones_above_the_cap_fail_the_launch_check(tmp_path):
    cache = str(tmp_path / 'fleet_cap.yaml')
    cap = launch_check.machine_cap(cache_path=cache).drones
    [line] = check(parse(['drones=%d' % (cap + 1), 'max_drones=0']), cap_cache=cache)
    assert line.startswith('launch argument drones:=') and 'fleet cap of %d' % cap in line
    assert check(parse(['drones=%d' % (cap + 1), 'max_drones=%d' % (cap + 1)]), cap_cache=cache) == []
    assert check(parse(['drones=0'])) == []


def test_the_fleet_size_is_checked_against_the_layout_given(tmp_path, monkeypatch):
    monkeypatch.setattr(launch_check, 'available_cores', lambda: 2)
    path = tmp_path / 'fleet_cap.yaml'
    _write_cache(path, model=launch_check.cpu_model(), layouts={'per_drone': {'cpu_per_drone': 0.2},
                                                                 'shared': {'cpu_per_drone': 0.1}})
    assert launch_check.check([('drones', '15'), ('layout', 'shared')], cap_cache=str(path)) == []
    [line] = launch_check.check([('drones', '15'), ('layout', '')], cap_cache=str(path))   # '' = per_drone here
    assert 'fleet cap of 10' in line
    [line] = launch_check.check([('layout', 'pooled')])
    assert 'must be per_drone or shared' in line


def test_the_fence_altitudes_must_be_in_order():
    assert check(parse(['fence_radius=5', 'fence_min_altitude=1', 'fence_max_altitude=4', 'max_reach='])) == []
    [line] = check(parse(['fence_min_altitude=4', 'fence_max_altitude=1']))
    assert 'fence_max_altitude:=1' in line and 'above' in line


def test_roslaunch_command_lines_are_recognised_strictly():
    from anafi_sim.launch_check import roslaunch_argv
    assert roslaunch_argv(['/usr/bin/python3', '/usr/bin/roslaunch', 'anafi_sim', 'x.launch', 'a:=1']) == \
        ['anafi_sim', 'x.launch', 'a:=1']
    assert roslaunch_argv(['/opt/ros/bin/roslaunch', '-p', '0', 'f.launch']) == ['-p', '0', 'f.launch']
    assert roslaunch_argv(['python3.8', 'roslaunch']) == []
    for other in (['/usr/bin/rostest', 'anafi_sim', 'x.test'], ['/usr/bin/python3', '-m', 'pytest'],
                  ['/usr/bin/python3', '/usr/bin/roslaunch-deps'], ['bash', 'roslaunch'], [], ['roslaunchx']):
        assert roslaunch_argv(other) is None, other


def test_command_line_arguments_are_read_as_roslaunch_reads_them():
    from anafi_sim.launch_check import command_line_arguments
    argv = ['-p', '11311', 'anafi_sim', 'experiment.launch', 'rtf:=2', ' controller := pid ', 'empty:=',
            '_private:=1', '__ns:=/x', 'a:=b:=c', 'plain', ':=x']
    assert command_line_arguments(argv) == [('rtf', '2'), ('controller', 'pid')]


def test_declared_arguments_are_the_files_own_not_those_it_passes_on():
    from anafi_sim.launch_check import declared_arguments
    xml = ('<launch><arg name="a" default="1"/><group if="true"><arg name="b" value="2"/></group>'
           '<include file="x.launch"><arg name="c" value="3"/></include><arg name="d"/></launch>')
    assert declared_arguments(xml) == ['a', 'b', 'd']
    with pytest.raises(ValueError, match='not a launch file'):
        declared_arguments('<launch>')


def test_an_unknown_argument_is_one_line_naming_it_and_the_nearest_known_one():
    from anafi_sim.launch_check import unknown_arguments
    declared = ['controller', 'scenario', 'rtf']
    assert unknown_arguments([('controller', 'pid'), ('rtf', '2')], declared, 'experiment.launch') == []
    assert unknown_arguments([('contoller', 'pid')], declared, 'experiment.launch') == [
        'launch argument contoller:=pid: not an argument of experiment.launch (did you mean controller?)']
    [line] = unknown_arguments([('zzz', '1')], declared, 'experiment.launch')
    assert line == ('launch argument zzz:=1: not an argument of experiment.launch '
                    '(its arguments: roslaunch anafi_sim experiment.launch --ros-args)')


def test_the_script_checks_only_under_a_roslaunch_parent():
    """Under pytest (not roslaunch) the parent is neither read as roslaunch's arguments nor signalled."""
    good = subprocess.run([sys.executable, SCRIPT, '--launch', os.path.join(ROOT, 'anafi_sim', 'launch',
                                                                             'sim.launch'), 'rtf=2'],
                          capture_output=True, text=True)
    assert good.returncode == 0 and good.stdout == 'ok'


def _roslaunch(tmp_path, *args):
    from anafi_sim import processes
    env = dict(os.environ, ROS_HOME=str(tmp_path), ROS_LOG_DIR=str(tmp_path / 'log'),
               ROS_MASTER_URI='http://127.0.0.1:%d' % processes.free_port())   # no master there: none is needed
    return subprocess.run(['roslaunch', '--skip-log-check'] + list(args), env=env, cwd=str(tmp_path),
                          stdin=subprocess.DEVNULL, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                          universal_newlines=True, timeout=120)


def _roslaunch_finds_the_package():
    import shutil
    if not shutil.which('roslaunch'):
        return False
    try:
        import rospkg
        return os.path.samefile(os.path.join(rospkg.RosPack().get_path('anafi_sim'), 'anafi_sim'),
                               os.path.join(ROOT, 'anafi_sim'))
    except Exception:
        return False


@pytest.mark.skipif(not _roslaunch_finds_the_package(), reason='roslaunch or this anafi_sim not on the ROS path')
@pytest.mark.parametrize('args, line', [
    (['experiment.launch', 'contoller:=pid'],
     'launch argument contoller:=pid: not an argument of experiment.launch (did you mean controller?)'),
    (['demo.launch', 'sceanrio:=straight_3'],
     'launch argument sceanrio:=straight_3: not an argument of demo.launch (did you mean scenario?)'),
    (['experiment.launch', 'rtf:=-1'], 'launch argument rtf:=-1: must be a finite number > 0'),
])
def test_roslaunch_ends_with_the_one_line_and_no_exception_dump(tmp_path, args, line):
    out = _roslaunch(tmp_path, 'anafi_sim', *args)
    plain = [text.split('\x07')[-1] for text in out.stdout.strip().splitlines()]   # after the window title
    assert out.returncode != 0 and plain[-1] == line, out.stdout[-3000:]
    assert 'RLException' not in out.stdout and 'Traceback' not in out.stdout, out.stdout[-3000:]
    assert 'started with pid' not in out.stdout and 'auto-starting new master' not in out.stdout


@pytest.mark.skipif(not _roslaunch_finds_the_package(), reason='roslaunch or this anafi_sim not on the ROS path')
def test_an_included_file_does_not_refuse_the_arguments_of_the_file_that_includes_it(tmp_path):
    """experiment.launch includes sim.launch, whose check sees roslaunch's controller:=pid and must not refuse
    it: --nodes loads every file (running the checks) and starts nothing."""
    out = _roslaunch(tmp_path, '--nodes', 'anafi_sim', 'experiment.launch', 'controller:=pid', 'mirror:=false')
    assert out.returncode == 0 and 'not an argument' not in out.stdout, out.stdout[-3000:]
    assert '/anafi/experiment_monitor' in out.stdout.split(), out.stdout[-3000:]


def test_each_split_host_stays_within_the_budget_of_a_core():
    assert launch_check.HOST_CORE_BUDGET == 0.5
    assert launch_check.drones_per_host({'fleet_drones': 0.05, 'fleet_ground_truth': 0.062}) == \
        {'fleet_drones': 10, 'fleet_ground_truth': 8}
    assert launch_check.drones_per_host({'fleet_ground_truth': 0.9}) == {'fleet_ground_truth': 1}   # at least one
    for cost in (0.01, 0.031, 0.027, 0.062, 0.07, 0.125, 0.3):
        n = launch_check.drones_per_host({'h': cost})['h']
        assert n * cost <= launch_check.HOST_CORE_BUDGET + 1e-12 < (n + 1) * cost


def test_the_split_comes_from_the_hosts_cost_measured_here_else_the_drones_cost_else_the_default(tmp_path):
    path = str(tmp_path / 'fleet_cap.yaml')
    ref = launch_check.REFERENCE_HOST_CPU_PER_DRONE
    # unmeasured: the reference's host costs / DEFAULT_CAP_SCALE (a machine twice as slow)
    limits, why = launch_check.machine_drones_per_host(2, 'Test CPU', path)
    assert limits == launch_check.drones_per_host(dict((h, c / launch_check.DEFAULT_CAP_SCALE) for h, c in
                                                       ref.items()))
    assert 'conservative default' in why
    # the shared layout's cost of a drone measured here: the reference's host costs scaled by it
    _write_cache(path, layouts={'shared': {'cpu_per_drone': 2 * launch_check.CPU_PER_DRONE['shared'],
                                           'failing_per_core': None}})
    scaled, why = launch_check.host_costs(2, 'Test CPU', path)
    assert all(abs(scaled[h] - 2 * ref[h]) < 1e-12 for h in ref) and 'x 2.00' in why and path in why
    # the hosts' own costs measured here win
    _write_cache(path, layouts={'shared': {'cpu_per_drone': 0.1, 'failing_per_core': None,
                                           'host_cpu_per_drone': {'fleet_drones': 0.05, 'fleet_ground_truth': 0.062}}})
    limits, why = launch_check.machine_drones_per_host(2, 'Test CPU', path)
    assert limits == {'fleet_drones': 10, 'fleet_ground_truth': 8} and 'measured here' in why
    # another machine, or a host cost that is not one: not these figures
    assert launch_check.host_costs(4, 'Test CPU', path)[1].startswith('conservative default')
    _write_cache(path, layouts={'shared': {'cpu_per_drone': 0.1, 'failing_per_core': None,
                                           'host_cpu_per_drone': {'fleet_drones': -1, 'fleet_ground_truth': 0.06}}})
    assert 'x ' in launch_check.host_costs(2, 'Test CPU', path)[1]
