"""calibrate_model.py's outputs: a new run folder by default, the committed files only with --update, the shipped
reference logs as input (no fits run here: argument handling and the comparison with the committed files)."""
import os

from anafi_sim import paths
from anafi_lab.cli import calibrate_model as cli


def test_by_default_every_output_goes_into_a_new_run_folder(tmp_path):
    args = cli.parse_args(['--dir', str(tmp_path)])
    assert os.path.dirname(args.run_dir) == str(tmp_path) and os.path.basename(args.run_dir).startswith('calibrate-')
    for option, _, name in cli.OUTPUTS:
        assert getattr(args, option) == os.path.join(args.run_dir, name)
    assert os.path.realpath(os.path.join(str(tmp_path), 'latest')) == os.path.realpath(args.run_dir)
    assert args.logs == paths.reference_logs_dir() and len(args.log_files) == 14
    assert args.logs_label == 'anafi_sim/data/reference_logs'
    second = cli.parse_args(['--dir', str(tmp_path)])
    assert second.run_dir != args.run_dir          # a rerun never writes into an earlier run's folder


def test_update_writes_the_committed_files_and_makes_no_run_folder(tmp_path):
    args = cli.parse_args(['--update', '--plot', ''])
    assert args.run_dir is None and args.plot == ''
    assert args.out == os.path.join(paths.checkout(), 'anafi_sim', 'config', 'anafi_model.yaml')
    assert args.report == os.path.join(paths.checkout(), 'docs', 'calibration.md')
    assert args.context == os.path.join(paths.checkout(), 'benchmarks', 'results', 'calibration.yaml')


def test_other_logs_are_named_by_their_folder(tmp_path):
    logs = tmp_path / 'logs'
    logs.mkdir()
    (logs / 'a.csv').write_text('time\n')
    args = cli.parse_args(['--logs', str(logs), '--dir', str(tmp_path / 'run')])
    assert args.logs_label == str(logs) and args.log_files == [str(logs / 'a.csv')]


def test_the_run_folder_is_compared_with_the_committed_files(tmp_path):
    args = cli.parse_args(['--dir', str(tmp_path)])
    with open(cli.committed('out'), 'rb') as f:
        same = f.read()
    with open(args.out, 'wb') as f:
        f.write(same)
    with open(args.fitted, 'w') as f:
        f.write('# not the committed file\n')
    lines = cli.compare_with_committed(args)
    assert lines == ['same as    anafi_sim/config/anafi_model.yaml',
                     'DIFFERS from anafi_sim/config/anafi_model_fitted.yaml']
