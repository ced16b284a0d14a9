"""anafi_sim.run_files and the result checks: unique run folders, atomic writes (a full disk leaves no cut
file), FAILED names, a rerun removing the previous run's files; the monitor's "not a measurement" check;
the recorder's bag renamed when the run did not end final."""
import errno
import os
import sys

import pytest
import yaml

from anafi_sim import run_files
from anafi_sim.mission import monitor as em


def test_every_run_gets_a_new_folder_and_latest_follows(tmp_path):
    a = run_files.new_run_dir(str(tmp_path), 'circle_mpc', now=0.0, pid=7)
    b = run_files.new_run_dir(str(tmp_path), 'circle_mpc', now=0.0, pid=7)    # same second, same pid
    assert a != b and os.path.isdir(a) and os.path.isdir(b)
    assert os.path.realpath(os.path.join(str(tmp_path), 'latest')) == os.path.realpath(b)
    c = run_files.new_run_dir(str(tmp_path), 'circle_pid')
    assert os.path.realpath(os.path.join(str(tmp_path), 'latest')) == os.path.realpath(c)
    assert not os.path.islink(os.path.join(str(tmp_path), 'latest.tmp-%d' % os.getpid()))


def test_an_atomic_write_is_complete_or_absent(tmp_path):
    path = str(tmp_path / 'run.yaml')
    run_files.atomic_write_text(path, 'state: final\n')
    assert open(path).read() == 'state: final\n'

    def full_disk(stream):
        stream.write('state: fin')
        raise OSError(errno.ENOSPC, 'No space left on device')
    with pytest.raises(OSError):
        run_files.atomic_write(path, full_disk)
    assert open(path).read() == 'state: final\n'          # the previous complete file, never a cut one
    assert os.listdir(str(tmp_path)) == ['run.yaml']       # no temporary left
    with pytest.raises(OSError):
        run_files.atomic_write(str(tmp_path / 'new.csv'), full_disk)
    assert not os.path.exists(str(tmp_path / 'new.csv'))


def test_atomic_path_for_writers_taking_a_path(tmp_path):
    path = str(tmp_path / 'plot.png')
    with run_files.atomic_path(path, '.png') as tmp:
        assert tmp.endswith('.png') and tmp != path
        open(tmp, 'w').write('png')
    assert open(path).read() == 'png'
    with pytest.raises(OSError):
        with run_files.atomic_path(str(tmp_path / 'b.csv')) as tmp:
            open(tmp, 'w').write('half')
            raise OSError(errno.ENOSPC, 'No space left on device')
    assert sorted(os.listdir(str(tmp_path))) == ['plot.png']


def test_failed_names_and_marking(tmp_path):
    assert run_files.failed_name('/d/RUN.csv') == '/d/RUN.FAILED.csv'
    assert run_files.failed_name('/d/RUN.run.yaml') == '/d/RUN.FAILED.run.yaml'
    assert run_files.failed_name('/d/RUN.FAILED.csv') == '/d/RUN.FAILED.csv'
    for name in ('RUN.csv', 'RUN.yaml'):
        (tmp_path / name).write_text('x')
    marked = run_files.mark_failed([str(tmp_path / n) for n in ('RUN.csv', 'RUN.yaml', 'RUN.png')])
    assert sorted(os.path.basename(m) for m in marked) == ['RUN.FAILED.csv', 'RUN.FAILED.yaml']
    assert sorted(os.listdir(str(tmp_path))) == ['RUN.FAILED.csv', 'RUN.FAILED.yaml']


def test_a_rerun_removes_the_previous_runs_files_first(tmp_path):
    """A rerun into the same names (unique:=false) that is SIGKILLed later can never leave the previous run's
    final files next to its own half-written bag: they are gone when it starts."""
    for name in ('RUN.yaml', 'RUN.csv', 'RUN.bag', 'RUN.run.yaml', 'RUN.FAILED.png'):
        (tmp_path / name).write_text('previous')
    (tmp_path / 'RUN.bag.active').write_text('the new recording')
    base = str(tmp_path / 'RUN')
    removed = run_files.remove_previous([base + e for e in ('.yaml', '.csv', '.png', '.run.yaml', '.bag')])
    assert len(removed) == 5
    assert os.listdir(str(tmp_path)) == ['RUN.bag.active']


def flown_monitor(drone_moves=True, truth=True):
    m = em.ExperimentMonitor(20.0, min_commands=0)
    m.on_drone_state('flying')
    m.tick(0.0, 100.0)
    assert m.state == em.STARTED
    for i in range(50):
        m.on_waypoint((0.1 * i, 0.0, 2.0))
        m.on_estimate((0.1 * i if drone_moves else 0.0, 0.0, 2.0))
    m.on_summary({'state': 'final', 'samples': 50, 'estimate': {'e_mu': 0.1},
                  'truth': {'e_mu': 0.1} if truth else None}, 101.0)
    return m


def test_a_final_summary_is_a_measurement_only_with_ground_truth_and_a_drone_that_flew():
    assert flown_monitor().result_problem() == ''
    assert 'no ground truth' in flown_monitor(truth=False).result_problem()
    assert flown_monitor(truth=False).result_problem(require_truth=False) == ''
    problem = flown_monitor(drone_moves=False).result_problem()
    assert 'did not fly' in problem and '0.00 m' in problem and '4.90 m' in problem
    info = flown_monitor().run_info()
    assert info['drone_travel_m'] == pytest.approx(4.9) and info['target_travel_m'] == pytest.approx(4.9)
    m = em.ExperimentMonitor(20.0)
    m.on_summary({'state': 'final', 'samples': 0}, 1.0)
    assert m.result_problem() == 'no evaluated samples'


def _record_bag():
    from anafi_sim.nodes import record_bag
    return record_bag


@pytest.mark.parametrize('state,kept', [('final', True), ('failed', False), (None, False)])
def test_the_recorder_keeps_the_bag_name_only_for_a_final_run(tmp_path, state, kept):
    rb = _record_bag()
    bag, info = str(tmp_path / 'RUN.bag'), str(tmp_path / 'RUN.run.yaml')
    if state:
        with open(info, 'w') as f:
            yaml.safe_dump({'state': state}, f)
    code = rb.supervise([sys.executable, '-c', 'open(%r, "w").write("bag")' % bag], bag, info)
    assert code == 0
    assert os.path.exists(bag) == kept
    assert os.path.exists(str(tmp_path / 'RUN.FAILED.bag')) != kept


def test_the_recorder_takes_its_run_info_option_out_of_rosbags_arguments():
    rb = _record_bag()
    assert rb.split_run_info(['--run-info', '/r.run.yaml', '-O', '/r.bag', '/t', '__name:=rec']) == \
        ('/r.run.yaml', ['-O', '/r.bag', '/t', '__name:=rec'])
    assert rb.split_run_info(['-O', '/r.bag']) == (None, ['-O', '/r.bag'])
