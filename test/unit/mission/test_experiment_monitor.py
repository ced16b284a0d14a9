"""anafi_sim.mission.monitor: start gate, failures, end and run figures of one experiment (pure core)."""
import pytest

from anafi_sim.mission import monitor as em

SIM = {em.SIM_RTF_KEY: '2.50', em.SIM_OVERRUNS_KEY: '10', 'schedule re-anchors (> 0.25 s behind)': '1',
       em.SIM_RATE_KEY: '500.0', em.SIM_WANTED_KEY: '600.0', 'flight state': 'flying'}


def ready_monitor(**kw):
    m = em.ExperimentMonitor(20.0, min_commands=3, **kw)
    m.on_drone_state('flying')
    for _ in range(3):
        m.on_command((0.0, 1.5, 0.0, 0.2))
    return m


def test_start_waits_for_flying_engaged_commands_and_subscribers():
    m = em.ExperimentMonitor(20.0, min_commands=3)
    assert m.tick(0.0, 100.0) == []
    m.on_drone_state('taking_off')
    for _ in range(5):
        m.on_command((0.0, 0.0, 0.0, 0.0))          # hover commands: not engaged
    m.on_command((float('nan'), 1.0, 0.0, 0.0))      # garbage: not counted
    assert m.commands == 0
    for _ in range(3):
        m.on_command((0.0, 0.0, 0.0, 0.4))
    assert m.tick(1.0, 101.0) == []                  # still not flying
    assert 'drone flying' in m.waiting_for()
    m.on_drone_state('flying')
    assert m.tick(2.0, 102.0, subscribers_ok=False) == []
    assert 'subscriptions' in m.waiting_for(False)
    assert m.holding
    actions = m.tick(3.0, 103.0, subscribers_ok=True)
    assert [a for a, _ in actions] == ['start']
    assert m.state == em.STARTED and not m.holding
    assert m.tick(3.1, 103.1) == []                  # started only once


def test_not_ready_in_time_fails_with_the_reason():
    m = em.ExperimentMonitor(20.0, min_commands=3, ready_timeout=10.0)
    m.tick(0.0, 50.0)
    m.on_drone_state('flying')
    assert m.tick(1.0, 59.0) == []
    actions = m.tick(2.0, 60.5)
    assert actions[0][0] == 'fail' and 'controller commands (0 of 3)' in actions[0][1]
    assert m.state == em.FAILED


def test_scenario_not_ending_in_ros_time_fails():
    m = ready_monitor(end_margin=5.0)
    m.tick(100.0, 0.0)                               # start at ROS 100 s
    m.on_begin(105.0)
    assert m.state == em.MEASURING
    assert m.tick(124.9, 10.0) == []                 # 20 s scenario + 5 s margin not yet over
    actions = m.tick(125.1, 11.0)
    assert actions[0][0] == 'fail' and 'did not end' in actions[0][1]


def test_end_then_final_summary_is_done_else_timeout():
    m = ready_monitor(final_timeout=4.0)
    m.tick(0.0, 0.0)
    m.on_begin(5.0)
    m.on_end(20.0, 8.0)
    assert m.state == em.MEASURED
    m.on_summary({'state': 'measuring'}, 9.0)
    assert m.tick(20.5, 9.0) == []
    m.on_summary({'state': 'final', 'estimate': {'e_mu': 0.2}}, 9.5)
    assert [a for a, _ in m.tick(21.0, 9.5)] == ['done']

    m2 = ready_monitor(final_timeout=4.0)
    m2.tick(0.0, 0.0)
    m2.on_end(20.0, 8.0)
    assert m2.tick(21.0, 11.9) == []
    assert m2.tick(21.0, 12.1)[0][0] == 'fail'


def test_progress_line_shows_phase_error_and_statistics():
    m = ready_monitor()
    assert 'waiting' in m.progress_line('run')
    m.tick(10.0, 0.0)
    m.on_status('settle', 'running')
    m.on_waypoint((3.0, 4.0, 5.0, 0.0))
    m.on_estimate((0.0, 0.0, 5.0))
    assert m.current_error() == pytest.approx(5.0)
    m.on_summary({'state': 'measuring', 'estimate': {'e_mu': 0.25, 'e_max': 0.5}}, 1.0)
    m.on_sim_diagnostics(SIM)
    m.tick(22.5, 1.0)
    line = m.progress_line('circle_mpc')
    assert 'circle_mpc' in line and 'settle' in line and 'e 5.00 m' in line
    assert 't   12.5 s' in line and 'e_mu 0.25' in line and 'rtf 2.50' in line


def test_run_info_durations_rtf_overruns_since_start_and_cpu():
    m = ready_monitor()
    m.on_sim_diagnostics({em.SIM_RTF_KEY: '3.0', em.SIM_OVERRUNS_KEY: '4',
                          'schedule re-anchors (> 0.25 s behind)': '0'})
    m.on_controller_cpu(10.0)
    m.tick(10.0, 100.0, epoch=1000.0)                # start: counters taken as the baseline
    m.on_sim_diagnostics(SIM)
    m.on_sim_diagnostics(dict(SIM, **{em.SIM_RTF_KEY: '1.5'}))
    m.on_mpc_stats(0.002, 0.005, 10, 1)
    m.on_mpc_stats(0.004, 0.007, 20, 1)
    m.on_begin(15.0)
    m.on_end(40.0, 110.0)                            # 30 s of ROS time in 10 s of wall time
    m.on_controller_cpu(13.0)
    info = m.run_info()
    assert info['scenario_sim_s'] == pytest.approx(30.0)
    assert info['scenario_wall_s'] == pytest.approx(10.0)
    assert info['achieved_rtf'] == pytest.approx(3.0)
    assert info['sim_reported_rtf_mean'] == pytest.approx(2.0)
    assert info['sim_reported_rtf_min'] == pytest.approx(1.5)
    assert info['sim_overruns'] == 6 and info['sim_reanchors'] == 1
    assert info['mpc_solve_time_mean_ms'] == pytest.approx(3.0)
    assert info['mpc_solve_time_max_ms'] == pytest.approx(4.0)
    assert info['mpc_cycles'] == 20
    assert info['controller_cpu_s'] == pytest.approx(3.0)
    assert info['controller_cpu_per_sim_s'] == pytest.approx(0.1)
    assert info['wall_clock']['created'] == pytest.approx(1000.0)
    assert info['wall_clock']['started'] == pytest.approx(1000.0)


def test_bad_parameters_are_refused():
    with pytest.raises(ValueError):
        em.ExperimentMonitor(0.0)
    with pytest.raises(ValueError):
        em.ExperimentMonitor(float('nan'))
    with pytest.raises(ValueError):
        em.ExperimentMonitor(10.0, min_commands=-1)
    with pytest.raises(ValueError):
        em.ExperimentMonitor(10.0, ready_timeout=True)


def test_summary_lines():
    lines = em.summary_lines({'name': 'x', 'samples': 10, 'state': 'final',
                              'estimate': {'e_max': 1.0, 'e_mu': 0.5, 'e_sigma': 0.25},
                              'truth': None, 'garbage': ['z_anafi: 1 x 65280'], 'warnings': []})
    text = '\n'.join(lines)
    assert 'e_max 1.000' in text and 'e_mu 0.500' in text and 'e_sigma 0.250' in text
    assert 'ground truth' in text and 'absent' in text and 'GARBAGE' in text
    assert 'no evaluator summary' in em.summary_lines(None, 'run')[0]


def test_hover_commands_and_gaps_while_the_scenario_runs_make_it_disturbed():
    m = ready_monitor()
    for k in range(5):
        m.on_command((0.0, 0.0, 0.0, 0.0), 0.1 * k)        # hover before the start: not counted
    m.tick(1.0, 0.0)
    t = 1.0
    for k in range(30):
        t += 0.1
        m.on_command((0.1, 0.0, 0.0, 0.0), t)
    assert m.disturbed() == '' and m.scenario_commands == 30 and m.hover_commands == 0
    assert m.max_command_gap == pytest.approx(0.1)
    for k in range(3):
        t += 0.1
        m.on_command((0.0, 0.0, 0.0, 0.0), t)
    t += 0.8
    m.on_command((0.2, 0.0, 0.0, 0.0), t)
    reason = m.disturbed()
    assert '3 hover commands' in reason and 'stopped for 0.80 s' in reason
    m.on_end(t, 5.0)
    m.on_command((0.0, 0.0, 0.0, 0.0), t + 5.0)            # after the end: not counted
    info = m.run_info()
    assert info['hover_commands'] == 3 and info['max_command_gap_s'] == pytest.approx(0.8)
    assert info['disturbed'] == reason


def test_the_controller_says_what_a_hover_command_is_when_it_can():
    """In-process the contract's ``ok`` decides: an exact-zero command on target (preview_mpc's quantised
    output) is not a hover command, a non-zero failsafe command (HOLD) is; without it, all-zero = hover."""
    m = ready_monitor()
    m.tick(1.0, 0.0)
    t = 1.0
    for hover, values in ((False, (0.0, 0.0, 0.0, 0.0)), (True, (0.3, 0.0, 0.0, 0.1)), (None, (0.0,) * 4),
                          (False, (float('nan'), 0.0, 0.0, 0.0))):
        t += 0.1
        m.on_command(values, t, hover=hover)
    assert m.scenario_commands == 4 and m.hover_commands == 3


def test_a_late_ground_truth_reader_while_the_scenario_runs_makes_it_disturbed_with_the_figure():
    m = ready_monitor()
    m.on_interface_diagnostics({em.READER_LAG_KEY: '0.900'})    # before the start: not counted
    m.tick(1.0, 0.0)
    m.on_interface_diagnostics({em.READER_LAG_KEY: '0.040'})
    m.on_interface_diagnostics({'other': 'x'})
    m.on_interface_diagnostics({em.READER_LAG_KEY: 'nan'})
    assert m.disturbed() == '' and m.reader_lag == pytest.approx(0.04)
    m.on_interface_diagnostics({em.READER_LAG_KEY: '0.350', 'process hangs': '0', 'process starved': '2'})
    assert m.disturbed() == ''                                   # within the limit: printed, not disturbed
    m.on_interface_diagnostics({em.READER_LAG_KEY: '0.750'})
    m.on_interface_diagnostics({em.READER_LAG_KEY: '0.010'})
    assert m.disturbed() == 'ground-truth reader 0.75 s late (limit 0.50 s)'
    info = m.run_info()
    assert info['reader_lag_max_s'] == pytest.approx(0.75) and info['disturbed'] == m.disturbed()
    assert (info['interface_hangs'], info['interface_starved']) == (0, 2)
    assert em.result_status(True, info) == 'disturbed: ground-truth reader 0.75 s late (limit 0.50 s)'
    assert em.reader_line(info) == '  ground-truth reader: wake-up lag max 0.750 s (disturbed beyond 0.50 s), ' \
        'telemetry process hung 0, starved 2'
    assert em.reader_line({}) is None


def test_ground_truth_missing_in_the_summary_makes_a_run_disturbed():
    m = ready_monitor()
    m.tick(1.0, 0.0)
    m.on_summary({'state': 'final', 'samples': 100, 'truth_missing': 3}, 2.0)
    assert m.disturbed() == 'ground truth missing at 3 samples' and m.run_info()['truth_missing'] == 3


def test_the_result_status_is_ok_disturbed_or_failed():
    assert em.result_status(True, {'disturbed': ''}) == 'ok'
    assert em.result_status(True, {'disturbed': '3 hover commands'}) == 'disturbed: 3 hover commands'
    assert em.result_status(False, {'disturbed': 'x', 'reason': 'no ground truth'}) == 'FAILED: no ground truth'


def test_garbage_and_warnings_are_counted_in_the_summary_lines_not_repeated():
    lines = em.summary_lines({'name': 'x', 'samples': 10, 'state': 'final', 'estimate': None, 'truth': None,
                              'garbage': ['x_sphinx, y_sphinx: 1 of 10 samples (non-finite: 1)'],
                              'garbage_samples': 1, 'warnings': ['w1', 'w2']})
    text = '\n'.join(lines)
    assert 'GARBAGE excluded: 1 samples, 2 warning(s)' in text and 'x_sphinx' not in text and 'w1' not in text


def tuning_record(stamp, parameter='a_max', old=5.0, new=5.5, node='/anafi/mpc_controller', outcome='applied'):
    return {'stamp': stamp, 'wall': 1.0e9 + stamp, 'node': node, 'parameter': parameter, 'old': old, 'new': new,
            'requested': new, 'outcome': outcome}


def test_the_run_info_keeps_the_measured_window():
    m = ready_monitor()
    assert m.run_info()['measured_window'] is None
    m.on_begin(12.5)
    m.on_end(32.5, 100.0)
    assert m.run_info()['measured_window'] == [12.5, 32.5]


def test_only_the_measured_windows_tuning_changes_that_changed_a_value_count():
    info = {'measured_window': [10.0, 30.0], 'tuning': [
        tuning_record(5.0),                                   # before the window: the run's tuning, not a change
        tuning_record(22.3, 'q_cum_vel', 0.0, 0.0, outcome='clamped'),   # asked, nothing changed
        tuning_record(14.25),
        tuning_record(31.0)]}                                 # after the window
    changes = em.tuning_in_window(info)
    assert [(c['parameter'], c['t']) for c in changes] == [('a_max', pytest.approx(4.25))]
    assert em.tuning_clause(info) == 'tuning changed at t=4.2 s: /anafi/mpc_controller a_max 5.0 -> 5.5'
    assert em.tuning_in_window({'tuning': info['tuning']}) == []          # no window: nothing to say
    assert em.tuning_in_window({'measured_window': [10.0, None], 'tuning': info['tuning']}) == []
    assert em.tuning_in_window({'measured_window': [10.0, 30.0], 'tuning': [None, {'stamp': 'x'}]}) == []


def test_a_tuning_change_in_the_measured_window_is_said_in_the_result_line():
    info = {'disturbed': '', 'measured_window': [10.0, 30.0], 'tuning': [tuning_record(22.3, 'r', 0.1, 0.5)]}
    said = 'tuning changed at t=12.3 s: /anafi/mpc_controller r 0.1 -> 0.5'
    assert em.result_status(True, info) == 'ok, ' + said
    assert em.result_status(True, dict(info, disturbed='3 hover commands')) == 'disturbed: 3 hover commands; ' + said
    assert em.result_status(False, dict(info, reason='no ground truth')) == 'FAILED: no ground truth; ' + said
    many = dict(info, tuning=[tuning_record(11.0 + i, new=6.0 + i) for i in range(5)])
    assert em.result_status(True, many).endswith('a_max 5.0 -> 8.0 (+2 more)')
