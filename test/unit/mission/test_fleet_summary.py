"""anafi_sim.mission.fleet_summary: the one table a fleet prints when it stops."""
import os

import yaml

from anafi_sim.mission import fleet_summary as fs


def _write(path, data):
    with open(path, 'w') as f:
        yaml.safe_dump(data, f)


def test_one_row_per_drone_with_its_state_and_errors(tmp_path):
    out = str(tmp_path)
    _write(fs.summary_path(out, 'anafi1'), {'name': 'circle_r2_v1', 'state': 'final', 'samples': 3000,
                                            'estimate': {'e_mu': 0.0412, 'e_max': 0.1},
                                            'truth': {'e_mu': 0.05, 'e_max': 0.12345}})
    _write(fs.summary_path(out, 'anafi2'), {'name': 'circle_r2_v1', 'state': 'incomplete', 'samples': 120,
                                            'estimate': {'e_mu': None, 'e_max': 0.2}, 'truth': None})
    with open(fs.summary_path(out, 'anafi3'), 'w') as f:
        f.write('state: [unclosed\n')
    text = fs.fleet_summary('circles', [('anafi1', 'mpc'), ('anafi2', 'pid_single'), ('anafi3', 'mpc'),
                                        ('anafi4', 'mpc')], out)
    lines = text.splitlines()
    assert lines[0] == 'fleet circles stopped: 4 drones (evaluations in %s)' % out
    assert lines[1].split() == ['drone', 'controller', 'state', 'samples', 'e_mu', 'est', '[m]', 'e_max', 'est',
                                '[m]', 'e_mu', 'truth', '[m]', 'e_max', 'truth', '[m]']
    assert set(lines[2]) == {'-', ' '}
    rows = lines[3:]
    assert len(rows) == 4
    assert rows[0].split() == ['anafi1', 'mpc', 'final', '3000', '0.041', '0.100', '0.050', '0.123']
    assert rows[1].split() == ['anafi2', 'pid_single', 'incomplete', '120', '-', '0.200', '-', '-']
    assert rows[2].startswith('anafi3') and 'unreadable summary' in rows[2]
    assert rows[3].split()[:5] == ['anafi4', 'mpc', 'no', 'summary', 'written']
    assert lines[1].index('controller') == rows[0].index('mpc') == rows[1].index('pid_single')   # aligned


def test_a_file_of_an_earlier_run_and_no_evaluators(tmp_path):
    out = str(tmp_path)
    path = fs.summary_path(out, 'anafi1')
    _write(path, {'state': 'final', 'samples': 10})
    os.utime(path, (1000.0, 1000.0))
    summary, why = fs.read_summary(path, since=2000.0)
    assert summary is None and 'older' in why
    assert fs.read_summary(path)[0]['samples'] == 10
    _write(path, [1, 2])
    assert fs.read_summary(path) == (None, 'not an evaluation summary')
    text = fs.fleet_summary('f', [('anafi1', 'mpc')], out, evaluate=False, reason='ended (exit code 1)')
    assert text.splitlines()[0] == 'fleet f ended (exit code 1): 1 drone (evaluations in %s)' % out
    assert 'not evaluated (evaluate:=false)' in text.splitlines()[3]
