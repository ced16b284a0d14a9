"""Sweeps and batches of in-process runs (anafi_lab.engine.sweep, .runs): spec expansion, a small sweep
on 2 worker processes and on a Dask LocalCluster, the batch's records and report, the command line."""
import csv
import glob
import os
import subprocess
import sys

import pytest
import yaml

from anafi_lab.engine import runs
from anafi_lab.engine import sweep
from anafi_lab.reports import batch_report, sweep_report
from anafi_sim.numeric import median
from conftest import ROOT

SCRIPT = os.path.join(ROOT, 'anafi_lab', 'cli', 'experiment.py')

SHORT = """
name: %s
start: trajectory
trajectory: {type: circle, centre: [0.0, 0.0, 1.5], radius: 0.5, speed: 0.5, yaw: 0.0}
phases:
  - {name: approach, duration: 0.5, hold: start}
  - {name: measure, duration: 1.5, measure: true}
"""


@pytest.fixture
def short(tmp_path):
    out = []
    for name in ('short_a', 'short_b'):
        path = tmp_path / (name + '.yaml')
        path.write_text(SHORT % name)
        out.append(str(path))
    return out


def test_example_specs_expand():
    specs = sorted(glob.glob(os.path.join(sweep.specs_dir(), '*.yaml')))
    assert len(specs) >= 3
    counts = dict((os.path.basename(p), len(sweep.expand(sweep.load_spec(p)))) for p in specs)
    assert counts['wind_circles.yaml'] == 200
    assert counts['schedule_phases.yaml'] == 16 * (32 + 16)
    assert counts['mpc_weights.yaml'] == 24


def test_grid_expansion_per_controller_and_seeds(short):
    spec = {'scenarios': short, 'seeds': {'range': [3, 5]},
            'wind': [{'wind_x': 1.0}, {'wind_x': 2.0, 'gust_std_horizontal': 0.5}],
            'controllers': {'mpc': {'params': {'r': [0.1, 0.2]}},
                            'pid': {'params': {'x_outer': {'Kp': [0.5, 1.0]}},
                                    'schedule': {'pid_command_phase': 0.05}}},
            'schedule': {'generator_phase': [0.0, 0.05]}}
    tasks = sweep.expand(spec)
    assert len(tasks) == 2 * (2 + 2) * 2 * 2 * 2
    pid = [t for t in tasks if t['controller'] == 'pid']
    assert {t['params']['x_outer']['Kp'] for t in pid} == {0.5, 1.0}
    assert all(t['schedule']['pid_command_phase'] == 0.05 for t in pid)
    assert {t['seed'] for t in tasks} == {3, 4}
    assert len({t['name'] for t in tasks}) == len(tasks)
    listed = sweep.expand({'runs': [{'scenario': short[0], 'controller': 'pid', 'seed': 1}]})
    assert len(listed) == 1 and listed[0]['seed'] == 1
    for bad in ({'scenarios': ['no_such_scenario']}, {'scenarios': short, 'controllers': ['lqr']},
                {'scenarios': short, 'seeds': [-1]}, {'scenarios': short, 'schedule': {'bogus': [1]}},
                {'scenarios': short, 'wind': [{'speed': 3}]}, {'scenarios': short, 'typo': 1},
                {'runs': [{'scenario': short[0]}], 'scenarios': short}):
        with pytest.raises(ValueError):
            sweep.expand(bad)


def _check_sweep_outputs(out, n):
    with open(os.path.join(out, 'runs.csv')) as f:
        table = list(csv.DictReader(f))
    assert len(table) == n and all(r['ok'] == 'True' for r in table)
    assert all(0.0 < float(r['e_mu']) < 1.0 and float(r['e_mu_truth']) > 0.0 for r in table)
    summary = open(os.path.join(out, 'summary.md')).read()
    assert '| short_a | mpc |' in summary and 'e_mu.png' in summary
    return table


def test_small_sweep_on_two_worker_processes(short, tmp_path):
    spec = {'name': 'small', 'scenarios': short, 'controllers': ['mpc', 'pid'], 'seeds': [0, 1],
            'wind': [{'wind_x': 0.5, 'gust_std_horizontal': 0.5}]}
    out = str(tmp_path / 'sweep')
    table, files, meta = sweep_report.run_sweep(spec, out, workers=2, progress=runs.Progress(8, bar=False))
    assert os.path.isfile(files['plot']) and os.path.getsize(files['plot']) > 1000
    table = _check_sweep_outputs(out, 8)
    by_seed = dict(((r['scenario'], r['controller'], r['seed']), r['e_mu']) for r in table)
    assert by_seed[('short_a', 'mpc', '0')] != by_seed[('short_a', 'mpc', '1')]     # gusts differ per seed
    serial = sweep_report.run_sweep(spec, str(tmp_path / 'serial'), workers=1, plot=False,
                             progress=runs.Progress(8, bar=False))[0]
    assert [r['e_mu'] for r in serial] == [float(r['e_mu']) for r in table], 'parallel = serial, run for run'


def test_small_sweep_on_a_dask_local_cluster(short, tmp_path):
    distributed = pytest.importorskip('distributed', reason='Dask distributed not installed (python3-distributed)')
    cluster = distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=False, dashboard_address=None)
    try:
        spec = {'name': 'dask', 'scenarios': short[:1], 'controllers': ['mpc', 'pid']}
        out = str(tmp_path / 'dask')
        sweep_report.run_sweep(spec, out, scheduler=cluster.scheduler_address, progress=runs.Progress(2, bar=False))
        table = _check_sweep_outputs(out, 2)
        local = sweep_report.run_sweep(spec, str(tmp_path / 'local'), plot=False, progress=runs.Progress(2, bar=False))[0]
        assert [float(r['e_mu']) for r in table] == [r['e_mu'] for r in local]
    finally:
        cluster.close()


def test_batch_writes_the_records_and_the_report(short, tmp_path):
    out = str(tmp_path / 'batch')
    records, meta, report_path = batch_report.batch(out, scenarios=short, controllers=('mpc', 'pid'), workers=1,
                                            plots=False, progress=runs.Progress(4, bar=False))
    with open(os.path.join(out, 'experiments.yaml')) as f:
        data = yaml.safe_load(f)
    assert set(data) == {'meta', 'records'} and len(data['records']) == 4
    rec = data['records'][0]
    for key in ('scenario', 'controller', 'ok', 'error', 'summary', 'info', 'step', 'wall_s', 'files', 'plot'):
        assert key in rec
    assert rec['summary']['state'] == 'final' and rec['info']['engine'] == 'inprocess'
    assert [(r['scenario'], r['controller']) for r in data['records']] == [
        ('short_a', 'mpc'), ('short_a', 'pid'), ('short_b', 'mpc'), ('short_b', 'pid')]
    text = open(report_path).read()
    assert text.startswith('# Experiments') and '## Runs: wall time and the simulator' in text
    assert os.path.isfile(os.path.join(out, 'runs', 'short_a_pid.csv'))


def test_command_line_run(short, tmp_path):
    out = str(tmp_path / 'cli')
    env = dict(os.environ)
    env['PYTHONPATH'] = ROOT + os.pathsep + env.get('PYTHONPATH', '')
    proc = subprocess.run([sys.executable, SCRIPT, 'run', '--controller', 'pid', '--scenario', short[0],
                           '--seed', '2', '--wind', '0.5,0', '--gust', '0.3', '--param', 'x_outer.Kp=1.0',
                           '--out', out], stdout=subprocess.PIPE, stderr=subprocess.PIPE, universal_newlines=True,
                          timeout=120, env=env)
    assert proc.returncode == 0, proc.stderr
    lines = proc.stdout.strip().splitlines()
    assert lines[0].startswith('RESULT short_a_pid  ok  e_mu '), proc.stdout
    # then the paths it wrote, absolute, one per line (before: none printed)
    printed = dict(line.split(None, 1) for line in lines[1:])
    assert printed == {'csv:': os.path.join(out, 'short_a_pid.csv'), 'plot:': os.path.join(out, 'short_a_pid.png'),
                       'summary:': os.path.join(out, 'short_a_pid.yaml')}, proc.stdout
    assert sorted(os.listdir(out)) == ['short_a_pid.csv', 'short_a_pid.png', 'short_a_pid.yaml']
    bad = subprocess.run([sys.executable, SCRIPT, 'run', '--scenario', short[0], '--schedule', 'bogus=1',
                          '--out', out], stdout=subprocess.PIPE, stderr=subprocess.PIPE, universal_newlines=True,
                         timeout=60, env=env)
    assert bad.returncode == 2 and 'bogus' in bad.stderr


def test_command_line_run_names_its_conditions_and_draws_the_asked_format(short, tmp_path):
    """--conditions in the run's name (files, title); --format svg --dpi: the figure as SVG."""
    import xml.etree.ElementTree as ElementTree
    out = str(tmp_path / 'cli')
    env = dict(os.environ)
    env['PYTHONPATH'] = ROOT + os.pathsep + env.get('PYTHONPATH', '')
    proc = subprocess.run([sys.executable, SCRIPT, 'run', '--controller', 'pid', '--scenario', short[0],
                           '--conditions', 'real_flights', '--format', 'svg', '--dpi', '150', '--out', out],
                          stdout=subprocess.PIPE, stderr=subprocess.PIPE, universal_newlines=True, timeout=600, env=env)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.startswith('RESULT short_a_pid_real_flights  ok'), proc.stdout
    assert sorted(os.listdir(out)) == ['short_a_pid_real_flights.csv', 'short_a_pid_real_flights.svg',
                                       'short_a_pid_real_flights.yaml']
    assert ElementTree.parse(os.path.join(out, 'short_a_pid_real_flights.svg')).getroot().tag.endswith('svg')
    bad = subprocess.run([sys.executable, SCRIPT, 'run', '--scenario', short[0], '--format', 'jpg', '--out', out],
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, universal_newlines=True, timeout=60, env=env)
    assert bad.returncode == 2 and 'jpg' in bad.stderr


def test_median_is_the_middle_of_an_even_count():
    """The sweep plot's '/ median' row divides by the median of anafi_sim.numeric (the mean of the two middle
    values of an even count; None for no values)."""
    assert median([4.0, 1.0, 3.0, 2.0]) == 2.5
    assert median([3.0, 1.0, 2.0]) == 2.0
    assert median([5.0]) == 5.0
    assert median([]) is None


def test_sweep_spec_found_by_name_or_by_package_path_from_any_folder(tmp_path, monkeypatch):
    """`experiment.py sweep wind_circles` and the README's `anafi_lab/sweeps/wind_circles.yaml` from a
    folder other than the repository root (before: 'No such file' from anywhere but the root; no names)."""
    monkeypatch.chdir(str(tmp_path))
    shipped = os.path.join(sweep.specs_dir(), 'wind_circles.yaml')
    assert sweep.sweep_path('wind_circles') == shipped
    assert os.path.samefile(sweep.sweep_path('anafi_lab/sweeps/wind_circles.yaml'), shipped)
    assert sweep.load_spec('wind_circles')['name'] == 'wind_circles'
    own = tmp_path / 'anafi_lab' / 'sweeps'       # a file here wins over the package's
    own.mkdir(parents=True)
    (own / 'wind_circles.yaml').write_text('name: mine\nscenarios: [circle_r1_v1]\ncontrollers: [mpc]\n')
    assert sweep.load_spec('anafi_lab/sweeps/wind_circles.yaml')['name'] == 'mine'
    with pytest.raises(ValueError) as error:
        sweep.sweep_path('no_such_sweep')
    assert 'wind_circles' in str(error.value)        # the known names are listed
    assert 'wind_circles' in sweep.list_specs()


def test_progress_lines_have_an_eta():
    import io
    assert runs.eta(10.0, 1, 4) == '0:30' and runs.eta(10.0, 4, 4) == '0:00' and runs.eta(0.0, 0, 4) == '?'
    assert runs.eta(3600.0, 1, 3) == '2:00:00'
    stream = io.StringIO()
    progress = runs.Progress(3, 'x', stream=stream, bar=False)
    progress.update({'ok': True, 'scenario': 's', 'controller': 'mpc', 'summary': {'estimate': {'e_mu': 0.1}}})
    assert 'ETA ' in stream.getvalue() and ' 1/3 ' in stream.getvalue()
