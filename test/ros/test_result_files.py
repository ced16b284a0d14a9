#!/usr/bin/env python3
"""rostest (result_files.test): a full disk and a SIGKILLed rerun leave honest files.

Each case runs ``roslaunch anafi_sim experiment.launch`` (test scenario experiment_short.yaml, MPC, rtf 2,
no mirror) on a private ROS master of its own, like test_experiment.py.

- full disk: out_dir on a 64 kB tmpfs (mounted by this test when it runs as root and may mount; otherwise
  every process of the launch gets RLIMIT_FSIZE 64 kB, so each larger file fails with EFBIG): the run ends
  FAILED with the reason (RESULT ... FAILED), roslaunch's required node exits 1, no file named RUN.yaml /
  RUN.csv / RUN.png / RUN.run.yaml is left (a cut file would carry a final name), every file left is
  RUN.FAILED.* or a temporary-free partial bag.
- no ground truth: once the interface runs, the simulator's port parameter is pointed at a closed port and the
  telemetry CLI killed: the interface never reads a sample, the drone flies on its estimate, the run ends
  FAILED "no ground truth", exit 1, files RUN.FAILED.*.
- SIGKILLed rerun (unique:=false, the same out_dir and run name): the first run ends ok; the rerun is
  SIGKILLed (every process of it) once its bag is being recorded: none of the first run's final files is
  left next to the rerun's partial bag, and RUN.FAILED.run.yaml says state running.
"""
import json
import os
import re
import resource
import shutil
import signal
import subprocess
import sys
import tempfile
import time
import unittest

import psutil
import rostest
import yaml

from anafi_sim import paths, processes

SCENARIO = os.path.join(paths.package_dir(), 'test', 'ros', 'experiment_short.yaml')
NAME = 'short_mpc'
RUN_TIMEOUT = 150.0
FINAL_NAMES = ('.yaml', '.csv', '.png', '.run.yaml', '.bag')
RESULTS = os.path.join(paths.package_dir(), 'test_results', 'result_files.json')

#: (name, fault injected, expected): rows of the fault table of docs/reliability.md (tools/fault_table.py)
FAULTS = (
    ('full_disk', 'experiment.launch with its output folder on a full disk (a 64 kB tmpfs; RLIMIT_FSIZE 64 kB '
     'where the test may not mount)', 'the run ends FAILED naming what was not written, exit code 1; no file with '
     'a final name (RUN.yaml, .csv, .png, .run.yaml, .bag), no temporary left: only RUN.FAILED.*'),
    ('no_ground_truth', 'the interface gets no telemetry for the whole run (the simulator\'s port parameter pointed '
     'at a closed port, the telemetry CLI killed) while the drone flies the scenario on its estimate',
     'the evaluator\'s summary has no ground truth: the run ends FAILED "no ground truth", exit code 1, files '
     'RUN.FAILED.*'),
    ('sigkilled_rerun', 'a run into out_dir, then a rerun into the same names (unique:=false) SIGKILLed (every '
     'process) while it records', 'none of the first run\'s final files left next to the rerun\'s partial bag '
     '(RUN.bag.active); RUN.FAILED.run.yaml says state running'),
)


def launch(out, extra=(), log=None, port=None, **popen):
    port = port or processes.free_port()
    env = dict(os.environ, ROS_MASTER_URI='http://127.0.0.1:%d' % port,
               ROS_HOME=os.path.join(tempfile.gettempdir(), 'result_files_ros_home_%d' % port))
    processes.add_module_paths(env, 'osqp')
    cmd = ['roslaunch', '-p', str(port), 'anafi_sim', 'experiment.launch', 'controller:=mpc',
           'scenario:=experiment_short', 'scenario_file:=' + SCENARIO, 'rtf:=2.0', 'mirror:=false',
           'record:=true', 'out_dir:=' + out, 'run_name:=' + NAME, 'unique:=false', 'plot:=true',
           'progress_period:=0'] + list(extra)
    return processes.start(cmd, env=env, log=log, **popen)


def wait(proc, predicate, timeout):
    end = time.monotonic() + timeout
    while time.monotonic() < end and proc.poll() is None:
        if predicate():
            return True
        time.sleep(0.2)
    return predicate()


def read(path):
    try:
        with open(path) as f:
            return yaml.safe_load(f)
    except (IOError, OSError, yaml.YAMLError):
        return None


def mount_tmpfs(path, size):
    """Mount a tmpfs of ``size`` bytes on ``path``; False when not allowed."""
    if os.geteuid() != 0 or shutil.which('mount') is None:
        return False
    return subprocess.call(['mount', '-t', 'tmpfs', '-o', 'size=%d' % size, 'tmpfs', path],
                           stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL) == 0


class TestResultFiles(unittest.TestCase):
    rows = []

    @classmethod
    def tearDownClass(cls):
        os.makedirs(os.path.dirname(RESULTS), exist_ok=True)
        with open(RESULTS, 'w') as f:
            json.dump({'faults': [name for name, _, _ in FAULTS], 'rows': cls.rows,
                       'date': time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}, f, indent=1)

    def record(self, name, observed, stop='-', recovery=None):
        TestResultFiles.rows.append({'name': name, 'observed': observed, 'stop': stop, 'recovery': recovery,
                                     'ok': True})
    def test_full_disk_ends_failed_with_marked_files(self):
        root = tempfile.mkdtemp(prefix='result_files_disk_')
        out = os.path.join(root, 'out')
        os.makedirs(out)
        mounted = mount_tmpfs(out, 64 * 1024)
        popen = {}
        if not mounted:     # no permission to mount: cap every file of the launch instead
            popen['preexec_fn'] = lambda: resource.setrlimit(resource.RLIMIT_FSIZE, (64 * 1024, 64 * 1024))
        log = os.path.join(root, 'launch.log')
        proc = launch(out, log=log, **popen)
        try:
            wait(proc, lambda: False, RUN_TIMEOUT)      # the required monitor ends the launch
            time.sleep(1.0)
            text = open(log, errors='replace').read()
            files = sorted(os.listdir(out))
        finally:
            processes.stop(proc, grace=20.0)
            if mounted:
                subprocess.call(['umount', out])
        try:
            result = re.search(r'RESULT %s\s+\((.*)\)' % NAME, text)
            self.assertIsNotNone(result, text[-3000:])
            self.assertTrue(result.group(1).startswith('FAILED'), result.group(0))
            self.assertRegex(result.group(1), r'not written|cannot write|No space|too large|not being recorded',
                             result.group(0))
            self.assertRegex(text, r'process has died \[pid \d+, exit code 1, cmd \S+experiment_monitor', text[-3000:])
            for ext in FINAL_NAMES:
                self.assertNotIn(NAME + ext, files, 'a file with a final name on a full disk: %s' % files)
            self.assertFalse([f for f in files if '.tmp-' in f], files)
            self.assertTrue(all('.FAILED' in f for f in files), files)
            observed = '%s: "%s", monitor exit code 1; files left %s' % (
                'tmpfs 64 kB' if mounted else 'RLIMIT_FSIZE 64 kB', result.group(0), ', '.join(files))
            sys.stdout.write(observed + '\n')
            self.record('full_disk', observed, 'not needed (the run ends)')
        finally:
            shutil.rmtree(root, ignore_errors=True)

    def test_no_ground_truth_ends_failed(self):
        out = tempfile.mkdtemp(prefix='result_files_truth_')
        port = processes.free_port()
        uri = 'http://127.0.0.1:%d' % port
        log = os.path.join(out, 'launch.log')
        proc = launch(out, log=log, port=port)
        env = dict(os.environ, ROS_MASTER_URI=uri)
        try:
            cli = [None]

            def telemetry_cli():
                pid = processes.node_pid('/anafi/interface', uri)
                kids = processes.descendants(pid) if pid else []
                cli[0] = kids[0] if kids else None
                return cli[0] is not None
            self.assertTrue(wait(proc, telemetry_cli, 60.0), open(log, errors='replace').read()[-3000:])
            closed = processes.free_port()      # nobody serves there
            subprocess.check_call(['rosparam', 'set', '/anafi/anafi_sim/telemetry_bound_port', str(closed)], env=env)
            cli[0].kill()
            wait(proc, lambda: False, RUN_TIMEOUT)
            time.sleep(1.0)
            text = open(log, errors='replace').read()
            files = sorted(f for f in os.listdir(out) if f.startswith(NAME))
        finally:
            processes.stop(proc, grace=20.0)
        try:
            result = re.search(r'RESULT %s\s+\((.*)\)' % NAME, text)
            self.assertIsNotNone(result, text[-3000:])
            self.assertTrue(result.group(1).startswith('FAILED: no ground truth'), result.group(0))
            self.assertRegex(text, r'process has died \[pid \d+, exit code 1, cmd \S+experiment_monitor', text[-3000:])
            for ext in FINAL_NAMES:
                self.assertNotIn(NAME + ext, files, files)
            self.assertIn(NAME + '.FAILED.yaml', files)
            truth = read(os.path.join(out, NAME + '.FAILED.yaml')).get('truth')
            self.assertTrue(truth is None or truth.get('e_mu') is None, truth)
            observed = '"%s", monitor exit code 1; files left %s' % (result.group(0), ', '.join(files))
            sys.stdout.write(observed + '\n')
            self.record('no_ground_truth', observed, 'not needed (the drone flew on its estimate)')
        finally:
            shutil.rmtree(out, ignore_errors=True)

    def test_a_sigkilled_rerun_never_leaves_the_previous_final_files(self):
        out = tempfile.mkdtemp(prefix='result_files_rerun_')
        base = os.path.join(out, NAME)
        try:
            first = launch(out, log=os.path.join(out, 'first.log'))
            try:
                self.assertTrue(wait(first, lambda: (read(base + '.run.yaml') or {}).get('state') == 'final'
                                     and os.path.exists(base + '.bag'), RUN_TIMEOUT),
                                open(os.path.join(out, 'first.log'), errors='replace').read()[-3000:])
            finally:
                processes.stop(first, grace=20.0)
            self.assertEqual(read(base + '.yaml')['state'], 'final')
            rerun = launch(out, log=os.path.join(out, 'rerun.log'))
            try:
                self.assertTrue(wait(rerun, lambda: os.path.exists(base + '.bag.active') and
                                     os.path.exists(base + '.FAILED.run.yaml'), RUN_TIMEOUT))
                time.sleep(3.0)        # mid-run
                tree = [psutil.Process(rerun.pid)] + processes.descendants(rerun.pid)
                for p in tree:         # the whole run at once, as a power cut would
                    try:
                        p.send_signal(signal.SIGKILL)
                    except psutil.Error:
                        pass
                psutil.wait_procs(tree, timeout=5.0)
            finally:
                processes.stop(rerun, grace=1.0)
            files = sorted(os.listdir(out))
            for ext in FINAL_NAMES:
                self.assertNotIn(NAME + ext, files, 'the previous run\'s final file next to the rerun: %s' % files)
            self.assertIn(NAME + '.bag.active', files)
            self.assertEqual(read(base + '.FAILED.run.yaml')['state'], 'running')
            observed = 'the rerun leaves %s (state running); the first run\'s %s gone' % (
                ', '.join(f for f in files if f.startswith(NAME)), ', '.join(NAME + e for e in FINAL_NAMES))
            sys.stdout.write(observed + '\n')
            self.record('sigkilled_rerun', observed, 'not needed')
        finally:
            shutil.rmtree(out, ignore_errors=True)


if __name__ == '__main__':
    rostest.rosrun('anafi_sim', 'result_files', TestResultFiles, sys.argv)
