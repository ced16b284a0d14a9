"""anafi_sim.mission.run_end: the end of a run: files checked, plotted, written, FAILED names, RESULT block."""
import os

import pytest
import yaml

from anafi_sim import run_files
from anafi_sim.mission import run_end
from anafi_sim.mission.monitor import FAILED, FINAL

SUMMARY = {'state': 'final', 'samples': 200, 'estimate': {'e_max': 0.5, 'e_mu': 0.2, 'e_sigma': 0.1},
           'truth': {'e_max': 0.6, 'e_mu': 0.25, 'e_sigma': 0.12}}


def run_folder(tmp_path, summary_state='final', csv=True, bag='closed'):
    """A run's files as the evaluator and the recorder leave them, the monitor's "running" marker too."""
    files = dict((k, str(tmp_path / ('RUN.run.yaml' if k == 'info' else 'RUN.' + ext)))
                 for k, ext in (('summary', 'yaml'), ('csv', 'csv'), ('plot', 'png'), ('info', ''), ('bag', 'bag')))
    if summary_state:
        run_files.write_yaml(files['summary'], dict(SUMMARY, state=summary_state))
    if csv:
        (tmp_path / 'RUN.csv').write_text('t,x\n0,0\n')
    if bag == 'closed':
        (tmp_path / 'RUN.bag').write_text('bag')
    elif bag == 'active':
        (tmp_path / 'RUN.bag.active').write_text('bag')
    run_files.write_yaml(run_files.failed_name(files['info']), {'state': 'running'})
    return files


def draw(csv, out, failed=None):
    with open(out, 'w') as f:
        f.write('plot of %s' % os.path.basename(csv) + ('' if failed is None else ', FAILED: %s' % failed))


def broken(csv, out, failed=None):
    raise RuntimeError('no display')


def info_of(state=FINAL, reason=None):
    return {'state': state, 'reason': reason, 'label': 'circle', 'scenario_sim_s': 20.0, 'scenario_wall_s': 10.0,
            'achieved_rtf': 2.0, 'sim_overruns': 0, 'sim_reanchors': 0, 'mpc_solve_time_mean_ms': 1.5,
            'mpc_solve_time_max_ms': 4.0}


def listing(tmp_path):
    return sorted(os.listdir(str(tmp_path)))


def test_a_measured_run_keeps_its_names_writes_its_run_file_and_removes_the_marker(tmp_path):
    files = run_folder(tmp_path)
    done = run_end.finish_run(True, info_of(), files, draw)
    assert done.ok and done.problems == [] and done.errors == [] and done.files == files
    assert listing(tmp_path) == ['RUN.bag', 'RUN.csv', 'RUN.png', 'RUN.run.yaml', 'RUN.yaml']
    written = run_files.read_yaml(files['info'])
    assert written['state'] == FINAL and written['plot'] == files['plot']
    assert open(files['plot']).read() == 'plot of RUN.csv'


def test_the_inputs_are_not_changed(tmp_path):
    files, info = run_folder(tmp_path, summary_state='measuring'), info_of()
    before = (dict(files), dict(info))
    run_end.finish_run(True, info, files, draw)
    assert (files, info) == before


def test_a_bag_still_being_recorded_counts_as_written(tmp_path):
    assert run_end.finish_run(True, info_of(), run_folder(tmp_path, bag='active'), draw).ok


@pytest.mark.parametrize('kwargs,words', [
    (dict(summary_state='measuring'), ['summary', 'not final']),
    (dict(summary_state=None), ['summary', 'not written']),
    (dict(bag=None), ['bag', 'not being recorded']),
])
def test_an_ended_run_whose_files_are_incomplete_fails_and_says_why(tmp_path, kwargs, words):
    files = run_folder(tmp_path, **kwargs)
    done = run_end.finish_run(True, info_of(), files, draw)
    assert not done.ok and len(done.problems) == 1
    assert all(w in done.problems[0] for w in words) and done.problems[0].endswith('see the nodes\' logs)')
    assert done.info['state'] == FAILED and done.info['reason'] == done.problems[0]
    for key in ('csv', 'plot', 'info', 'bag'):    # every file's name says FAILED (the bag's: renamed by its recorder)
        assert done.files[key] == run_files.failed_name(files[key])
    assert done.files['summary'] == (run_files.failed_name(files['summary']) if kwargs.get('summary_state', 1)
                                     else files['summary'])      # a file not written keeps its name
    assert not [n for n in listing(tmp_path) if 'FAILED' not in n and n.split('.')[-1] not in ('bag', 'active')]
    written = run_files.read_yaml(done.files['info'])
    assert written['state'] == FAILED and words[0] in written['reason']


def test_a_run_without_a_csv_has_no_plot_and_fails(tmp_path):
    files = run_folder(tmp_path, csv=False)
    done = run_end.finish_run(True, info_of(), files, draw)
    assert not done.ok
    assert done.problems == ['CSV %s not written (a full disk? see the nodes\' logs)' % files['csv'],
                             'no CSV %s: no plot' % files['csv']]
    assert 'plot' not in done.info and not os.path.exists(done.files['plot'])


def test_the_monitors_problem_fails_the_run_first(tmp_path):
    done = run_end.finish_run(True, info_of(), run_folder(tmp_path), draw, problem='no ground truth')
    assert not done.ok and done.problems == ['no ground truth'] and done.info['reason'] == 'no ground truth'


def test_a_plot_that_cannot_be_drawn_fails_the_run_and_leaves_no_partial_file(tmp_path):
    files = run_folder(tmp_path)
    done = run_end.finish_run(True, info_of(), files, broken)
    assert not done.ok and done.problems == ['plot %s not written: no display' % files['plot']]
    assert not [n for n in listing(tmp_path) if 'png' in n]


def test_a_run_that_failed_before_its_end_keeps_its_reason_and_is_still_plotted(tmp_path):
    files = run_folder(tmp_path, summary_state='measuring')
    done = run_end.finish_run(False, info_of(FAILED, 'not ready within 90 s'), files, draw)
    assert not done.ok and done.problems == []       # the evaluator's files are not judged: the run failed already
    assert done.info['reason'] == 'not ready within 90 s' and done.info['plot'] == files['plot']
    assert os.path.isfile(done.files['plot']) and done.files['plot'].endswith('RUN.FAILED.png')
    assert open(done.files['plot']).read() == 'plot of RUN.csv, FAILED: not ready within 90 s'
    assert run_files.read_yaml(done.files['info'])['reason'] == 'not ready within 90 s'


def test_a_run_that_fails_at_its_end_is_plotted_as_failed_with_its_problems(tmp_path):
    files = run_folder(tmp_path)
    done = run_end.finish_run(True, info_of(), files, draw, problem='no ground truth')
    assert open(done.files['plot']).read() == 'plot of RUN.csv, FAILED: no ground truth'


def test_the_plot_is_drawn_through_a_temporary_name_with_the_files_extension(tmp_path):
    files = run_folder(tmp_path)
    files['plot'] = str(tmp_path / 'RUN.svg')
    seen = []
    done = run_end.finish_run(True, info_of(), files, lambda csv, out, failed: seen.append(out) or draw(csv, out))
    assert done.ok and seen[0].endswith('.svg') and os.path.isfile(str(tmp_path / 'RUN.svg'))


def test_a_run_file_that_cannot_be_written_fails_the_run(tmp_path):
    files = run_folder(tmp_path)
    files['info'] = str(tmp_path / 'a_folder')        # a folder where the run file should be: cannot be replaced
    os.mkdir(files['info'])
    done = run_end.finish_run(True, info_of(), files, draw)
    assert not done.ok and done.info['state'] == FAILED and 'cannot write %s' % files['info'] in done.info['reason']
    assert done.files['csv'] == run_files.failed_name(files['csv']) and os.path.isfile(done.files['csv'])


def test_files_not_given_stay_unnamed(tmp_path):
    done = run_end.finish_run(False, info_of(FAILED, 'x'), {'csv': '', 'plot': ''}, broken)
    assert done.files == dict((k, '') for k in run_end.RUN_FILES) and done.problems == []


def test_the_result_block_names_the_outcome_the_figures_and_the_files(tmp_path):
    files = run_folder(tmp_path)
    done = run_end.finish_run(True, info_of(), files, draw)
    lines = run_end.result_lines(done, SUMMARY, 'circle', run_dir=str(tmp_path))
    assert lines[0] == '' and lines[1] == lines[-1] == '=' * 78
    assert lines[2] == 'RESULT circle  (ok)'
    text = '\n'.join(lines)
    assert 'e_max 0.500' in text and 'real-time factor 2.00' in text and 'mean 1.50 ms, max 4.00 ms' in text
    assert '  folder:  %s' % tmp_path in lines
    named = [line.split()[0] for line in lines if line.startswith('  ') and line.split()[0].endswith(':')]
    assert named[-5:] == ['bag:', 'csv:', 'summary:', 'plot:', 'info:']


def test_the_result_block_of_a_failed_run(tmp_path):
    done = run_end.finish_run(True, info_of(), run_folder(tmp_path, summary_state=None), draw)
    lines = run_end.result_lines(done, None, 'circle')
    assert lines[2].startswith('RESULT circle  (FAILED: summary ') and '  no evaluator summary' in lines
    assert not [line for line in lines if line.startswith('  summary:')]     # not written: not named
    assert [line for line in lines if line.startswith('  info:') and 'RUN.FAILED.run.yaml' in line]
    assert yaml.safe_load(open(done.files['info']))['state'] == FAILED


def test_files_that_cannot_be_renamed_are_reported_not_raised(tmp_path, monkeypatch):
    def refuse(paths, *state_and_reason):
        raise OSError('read-only file system')
    monkeypatch.setattr(run_files, 'mark_failed', refuse)
    files = run_folder(tmp_path)
    done = run_end.finish_run(False, info_of(FAILED, 'x'), files, draw)
    assert done.errors == ['cannot mark the files of the failed run: read-only file system']
    assert done.files['csv'] == files['csv'] and done.files['bag'] == run_files.failed_name(files['bag'])


def test_a_failed_run_file_says_failed_inside(tmp_path):
    from anafi_sim import run_files
    summary = tmp_path / 'run.yaml'
    run_files.write_yaml(str(summary), {'state': 'final', 'rmse': 0.1})
    csv = tmp_path / 'run.csv'
    csv.write_text('t,x\n')
    marked = run_files.mark_failed([str(summary), str(csv)], 'failed', 'the drone never flew')
    assert marked == [str(tmp_path / 'run.FAILED.yaml'), str(tmp_path / 'run.FAILED.csv')]
    data = run_files.read_yaml(marked[0])
    assert data['state'] == 'failed' and data['reason'] == 'the drone never flew' and data['rmse'] == 0.1
    assert not summary.exists() and not csv.exists()


def test_the_run_file_names_the_conditions_a_run_flew_in():
    assert run_end.conditions_info('') == {'name': 'none', 'settings': {}}
    assert run_end.conditions_info('real_flights', {'wind_x': 2.5, 'gust_std_horizontal': 0.4}) == {
        'name': 'real_flights', 'settings': {'wind_x': 2.5, 'gust_std_horizontal': 0.4}}
    assert run_end.conditions_info('/some/where/gusty.yaml')['name'] == 'gusty'


def test_a_windy_runs_title_names_its_conditions():
    assert run_end.run_title('circle_r2_v1_mpc') == 'circle_r2_v1_mpc'
    assert run_end.run_title('circle_r2_v1_mpc_real_flights', 'real_flights') == 'circle_r2_v1_mpc_real_flights'
    assert run_end.run_title('my_run', 'real_flights') == 'my_run (real_flights)'


def test_the_result_line_says_a_tuning_change_inside_the_measured_window(tmp_path):
    info = dict(info_of(), disturbed='', measured_window=[10.0, 30.0], tuning=[
        {'stamp': 22.3, 'wall': 1.0, 'node': '/anafi/mpc_controller', 'parameter': 'a_max', 'old': 5.0, 'new': 5.5,
         'requested': 5.5, 'outcome': 'applied'}])
    done = run_end.finish_run(True, info, run_folder(tmp_path), draw)
    lines = run_end.result_lines(done, SUMMARY, 'circle')
    assert lines[2] == 'RESULT circle  (ok, tuning changed at t=12.3 s: /anafi/mpc_controller a_max 5.0 -> 5.5)'
