"""anafi_lab.reports.paper_tables (the batch's Markdown tables) and anafi_lab/cli/ros_batch.py options."""
import pytest

from anafi_lab.reports import paper_tables as rep
from anafi_sim.numeric import fmt


def rec(scenario, controller, e_mu, e_max=None, e_sigma=0.05, truth=None, ok=True, **info):
    est = {'e_mu': e_mu, 'e_max': e_max if e_max is not None else 2 * e_mu, 'e_sigma': e_sigma}
    tr = {'e_mu': truth, 'e_max': None, 'e_sigma': None} if truth is not None else None
    return {'scenario': scenario, 'controller': controller, 'ok': ok, 'error': '' if ok else 'boom',
            'summary': {'state': 'final', 'estimate': est, 'truth': tr}, 'info': info, 'step': None,
            'wall_s': 30.0, 'plot': ''}


def test_table3_has_ours_paper_and_ratio_in_the_speed_columns():
    records = [rec('straight_%d' % v, 'mpc', 0.1 * v, truth=0.1 * v + 0.01) for v in (1, 2, 3, 4, 5)]
    records += [rec('straight_2', 'pid', 2.5)]
    lines = rep.markdown_table(['Controller / speed', '1', '2', '3', '4', '5'], rep.table3(records))
    mpc_ours = [l for l in lines if l.startswith('| MPC ours, vs estimate')][0]
    assert mpc_ours.split('|')[2].strip() == '**0.10**' and mpc_ours.split('|')[6].strip() == '**0.50**'
    assert [l for l in lines if l.startswith('| MPC paper')][0].split('|')[2].strip() == '0.16'
    assert [l for l in lines if l.startswith('| PID paper')][0].split('|')[6].strip() == '7.00'
    ratio = [l for l in lines if l.startswith('| MPC ours / paper')][0]
    assert ratio.split('|')[2].strip() == '%.2f' % (0.1 / 0.16)
    pid = [l for l in lines if l.startswith('| PID ours, vs estimate')][0].split('|')
    assert pid[2].strip() == '**-**' and pid[3].strip() == '**2.50**'      # missing run shows '-'
    truth = [l for l in lines if l.startswith('| MPC ours, vs ground truth')][0]
    assert truth.split('|')[2].strip() == '0.11'


def test_stats_table_and_mpc_beats_pid():
    records = [rec('circle_r1_v1', 'mpc', 0.2, e_max=0.3, e_sigma=0.04), rec('circle_r1_v1', 'pid', 0.9),
               rec('circle_r2_v1', 'mpc', 1.0), rec('circle_r2_v1', 'pid', 0.8),
               rec('circle_r2_v2', 'mpc', 0.5), rec('circle_r2_v2', 'pid', 0.4, ok=False)]
    lines = rep.markdown_table(*rep.stats_table(records, rep.CIRCLE_SCENARIOS, rep.CIRCLES, 'estimate'))
    row = [l for l in lines if l.startswith('| 1 | 1 |')][0].split('|')
    assert [c.strip() for c in row[3:6]] == ['0.30', '0.20', '0.04']
    assert row[-2].strip() == 'yes'
    assert [l for l in lines if l.startswith('| 2 | 1 |')][0].split('|')[-2].strip() == '**no**'
    assert [l for l in lines if l.startswith('| 2 | 2 |')][0].split('|')[-2].strip() == '-'   # PID failed
    assert rep.mpc_beats_pid(records, 'circle_r1_v1') is True
    assert rep.mpc_beats_pid(records, 'circle_r2_v1') is False
    assert rep.mpc_beats_pid(records, 'circle_r2_v2') is None
    _, wins, compared = rep.beats_summary(records)
    assert (wins, compared) == (1, 2)


def test_cpu_ratio_and_keeping_up():
    records = [rec('a', 'mpc', 0.1, controller_cpu_s=1.0, scenario_sim_s=20.0, achieved_rtf=2.8,
                   sim_overruns=3, sim_reanchors=0),
               rec('b', 'pid', 0.1, controller_cpu_s=5.0, scenario_sim_s=20.0, achieved_rtf=2.1,
                   sim_overruns=5, sim_reanchors=2)]
    per, ratio = rep.cpu_ratio(records)
    assert per['mpc'] == pytest.approx(0.05) and per['pid'] == pytest.approx(0.25)
    assert ratio == pytest.approx(5.0)
    assert rep.keeping_up(records) == (2.1, 8, 2, 2, [2.1, 2.8])


def test_render_has_every_section_and_the_wall_time():
    records = [rec(s, c, 0.3 if c == 'mpc' else 1.0) for s in rep.ALL_SCENARIOS for c in rep.CONTROLLERS]
    records[0]['step'] = {'overshoot_x': 0.1, 'overshoot_y': 0.0, 'overshoot_z': 0.0, 'overshoot': 0.1,
                          'settling_time': 3.2, 'yaw_settling_time': 0.0}
    text = rep.render(records, {'rtf': '3', 'wall_s': 900.0, 'mirror': 'true', 'pid_mode': 'distributed',
                                'date': 'today', 'machine': 'x'},
                      plots=[('static_wp0_mpc', 'plots/static_wp0_mpc.png')],
                      comparison_plots=[('Fig 6', 'plots/static_waypoints.png')])
    for heading in ('## Table 3', '## Table 4', '## Table 5', '## Static waypoints', '## MPC vs PID',
                    '## Runs: wall time', '## Did the simulator keep up?', '## Plots'):
        assert heading in text
    assert 'Wall time of the whole batch: 900 s (15.0 min)' in text
    assert 'MPC better than PID in 16 of 16 scenarios' in text
    assert '| static_wp0 | MPC | 0.10 / 0.00 / 0.00 | 0.10 | 3.2 |' in text
    assert '![Fig 6](plots/static_waypoints.png)' in text


def test_fmt():
    assert fmt(None) == '-' and fmt(float('nan')) == '-' and fmt(True) == '-'
    assert fmt(1.234) == '1.23' and fmt(2, 0) == '2'


def _runner():
    from anafi_lab.cli import ros_batch
    return ros_batch


def test_runner_options_expand_groups_and_refuse_unknown_names():
    run = _runner()
    args = run.parse_args(['--scenarios', 'static,circle_r2_v1', '--controllers', 'pid'])
    assert args.scenario_list == ['static_wp0', 'static_wp1', 'circle_r2_v1']
    assert args.controller_list == ['pid']
    args = run.parse_args([])
    assert args.scenario_list == list(rep.ALL_SCENARIOS) and len(args.scenario_list) == 16
    assert args.jobs == 1 and args.rtf == 2.0 and args.retries == 1
    for bad in (['--scenarios', 'nope'], ['--controllers', 'lqr'], ['--jobs', '0'], ['--rtf', '0'],
                ['--retries', '-1']):
        with pytest.raises(SystemExit):
            run.parse_args(bad)


def test_disturbed_runs_are_marked_and_counted():
    clean = rec('circle_r1_v1', 'mpc', 0.2)
    bad = rec('circle_r1_v1', 'pid', 0.9, disturbed='4 hover commands', hover_commands=4)
    bad['attempts'] = 2
    assert rep.cell(clean, 'estimate', 'e_mu') == '0.20'
    assert rep.cell(bad, 'estimate', 'e_mu') == '0.90 †'
    assert rep.cell(rec('x', 'pid', 0.9, ok=False, disturbed='x'), 'estimate', 'e_mu') == '-'
    text = rep.render([clean, bad], {'rtf': '3', 'wall_s': 60.0})
    assert '0.90 †' in text and '† the controller was interrupted during this run' in text
    assert '1 run(s) needed a repeat, 1 remain disturbed' in text
    assert '| circle_r1_v1_pid | ok, disturbed: 4 hover commands | 2 |' in text


def test_paper_comparison_ratios():
    records = [rec('straight_%d' % v, 'mpc', p) for v, p in zip((1, 2, 3, 4, 5), (0.16, 0.36, 0.59, 0.82, 1.41))]
    records += [rec('straight_%d' % v, 'pid', 2 * p) for v, p in zip((1, 2, 3, 4, 5), (1.32, 2.67, 4.07, 5.32, 7.0))]
    text = rep.render(records, {'rtf': '3', 'wall_s': 60.0})
    lines = [line for line in text.splitlines() if line.startswith('- Table 3')]
    assert lines[0].startswith('- Table 3, MPC: ours / paper = 1.00 on average')
    assert lines[1].startswith('- Table 3, PID: ours / paper = 2.00 on average (2.00 at')
    # PID/MPC ratio of ours (2 x the paper's PID over the paper's MPC), and the paper's own range
    assert '(the paper: 5.0 .. 8.2)' in lines[2]
    assert lines[2].startswith('- Table 3 (straight line): PID e_mu / MPC e_mu = 9.9 .. 16.5')


def test_in_process_batch_says_what_the_engine_is():
    records = [rec('static_wp0', 'mpc', 0.2, achieved_rtf=80.0), rec('static_wp0', 'pid', 0.4, achieved_rtf=95.0)]
    text = rep.render(records, {'engine': 'inprocess', 'workers': '2 worker process(es)', 'wall_s': 12.0,
                                'sim_s': 800.0, 'pid_mode': 'distributed'})
    assert 'in-process (anafi_lab/engine/engine.py) on 2 worker process(es): virtual time' in text
    assert 'Achieved real-time factor (simulated seconds per wall second of a run): min 80, max 95.' in text
    assert '- 2 runs on 2 worker process(es): 12.0 s wall for 800 s of simulated time.' in text
    assert 'one at a time, each on its own ROS master' not in text
