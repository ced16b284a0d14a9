"""Figures of the docs that drift (docs/experiments.md): run counts and wall times of the batches, checked against the code (the batch's
scenarios and default controllers) and the committed results (benchmarks/results/experiments.yaml for the ROS
batch, benchmarks/results/inprocess/experiments.yaml for the in-process one)."""
import os
import re

import yaml

from anafi_lab import paper
from conftest import ROOT

README = open(os.path.join(ROOT, 'docs', 'experiments.md')).read()   # where the batch figures are


def _experiment_script():
    from anafi_lab.cli import experiment
    return experiment


def _results(*parts):
    with open(os.path.join(ROOT, 'benchmarks', 'results', *parts)) as f:
        return yaml.safe_load(f)


def _runs(engine):
    return len(paper.ALL_SCENARIOS) * len(_experiment_script().BATCH_CONTROLLERS[engine].split(','))


def test_batch_run_counts_follow_the_code():
    inprocess, ros = _runs('inprocess'), _runs('ros')
    assert '16 scenarios x 3: %d runs' % inprocess in README
    assert len(paper.ALL_SCENARIOS) == 16 and inprocess == 48 and ros == 32
    m = re.search(r'the 16 scenarios with the MPC, the PID and the preview MPC, (\d+) runs in ([\d.]+) s', README)
    assert m and int(m.group(1)) == inprocess, m and m.group(0)
    m = re.search(r"the ROS batch of the paper's (\d+) runs took ([\d.]+) min", README)
    assert m and int(m.group(1)) == ros, m and m.group(0)
    assert not re.search(r'about 20 s for the 32 runs|the paper\'s 32 runs\s*$', README, re.M)


def test_batch_times_are_those_of_the_committed_results():
    inproc = _results('inprocess', 'experiments.yaml')
    assert len(inproc['records']) == _runs('inprocess')
    m = re.search(r'(\d+) runs in ([\d.]+) s on a (\d+)-core ', README)      # a time names its machine
    assert float(m.group(2)) == round(inproc['meta']['wall_s'], 1), (m.group(0), inproc['meta']['wall_s'])
    cores = re.search(r'(\d+) (?:CPUs|cores)', inproc['meta']['machine'])
    assert cores and int(cores.group(1)) == int(m.group(3)), (m.group(0), inproc['meta']['machine'])
    m = re.search(r'make bench\s+# the same in-process \(~(\d+) s, see below\)', README)
    assert m and int(m.group(1)) == int(round(inproc['meta']['wall_s'])), m and m.group(0)
    ros = _results('experiments.yaml')
    minutes = '%.1f' % (ros['meta']['wall_s'] / 60.0)
    assert len(ros['records']) == _runs('ros')
    assert "paper's %d runs took %s min" % (len(ros['records']), minutes) in README


def test_no_unmeasured_setup_time():
    assert 'about a second' not in README


def test_live_tuning_is_documented_with_the_packaged_client():
    """rqt_reconfigure is not packaged on Debian 12: docs/launch.md shows dynparam, for a node that exists."""
    launch_doc = open(os.path.join(ROOT, 'docs', 'launch.md')).read() + '\n## end'
    section = launch_doc[launch_doc.index('## Live tuning'):]
    section = section[:section.index('\n## ', 1)]
    assert 'rosrun dynamic_reconfigure dynparam set /anafi/mpc_controller' in section
    assert 'tuning/changes' in section and 'run.yaml' in section
    launch = open(os.path.join(ROOT, 'anafi_sim', 'launch', 'mpc.launch')).read()
    assert 'controller.launch' in launch and '<arg name="controller" value="mpc"/>' in launch
    generic = open(os.path.join(ROOT, 'anafi_sim', 'launch', 'controller.launch')).read()
    assert 'name="$(arg controller)_controller"' in generic        # /anafi/mpc_controller
