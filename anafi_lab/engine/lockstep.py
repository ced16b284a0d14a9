"""Lockstep ROS runs (experiment.launch sync:=true) and their in-process reference (pure Python, no rospy).

``run_sync`` starts one experiment.launch on a private ROS master and collects the evaluator's summary, the
monitor's run figures and the simulator's lockstep diagnostics (from the run's bag); ``run_inprocess`` runs the
same scenario on the in-process engine with the lockstep's schedule (``experiment.py run --sync-schedule``).
Used by benchmarks/bench_sync.py and the lockstep rostests.
"""
import os
import subprocess
import sys
import time

from anafi_sim import processes
from anafi_sim.run_files import read_yaml

SIM_STATUS = 'anafi_sim: simulated Anafi'
"""Name prefix of the simulator's /diagnostics status."""



def lockstep_figures(bag_path):
    """The simulator's last /diagnostics values in a run's bag (the lockstep keys among them), {} if none."""
    import rosbag
    values = {}
    with rosbag.Bag(bag_path) as bag:
        for _, msg, _ in bag.read_messages(topics=['/diagnostics']):
            for status in msg.status:
                if status.name.startswith(SIM_STATUS):
                    values = dict((kv.key, kv.value) for kv in status.values)
    return values


def run_sync(controller, out_dir, scenario_file, rtf=0.5, timeout=300.0, extra=(), sync=True):
    """One ROS run of experiment.launch sync:=true (``sync`` False: the free-running graph, for comparison; no
    mirror, bag recorded) on a private master: a dict with
    summary (the evaluator's), info (the monitor's run.yaml), lockstep (the simulator's diagnostics values),
    wall_s, log (the launch log path), files base. Every process it starts is stopped by id."""
    name = 'sync_%s' % controller
    os.makedirs(out_dir, exist_ok=True)
    port = processes.free_port()
    env = dict(os.environ, ROS_MASTER_URI='http://127.0.0.1:%d' % port, ROS_HOME=os.path.join(out_dir, 'ros_home'))
    processes.add_module_paths(env, 'osqp')
    scenario = os.path.splitext(os.path.basename(scenario_file))[0]
    cmd = ['roslaunch', '-p', str(port), 'anafi_sim', 'experiment.launch', 'controller:=' + controller,
           'scenario:=' + scenario, 'scenario_file:=' + scenario_file, 'rtf:=%g' % rtf,
           'sync:=%s' % ('true' if sync else 'false'),
           'mirror:=false', 'record:=true', 'out_dir:=' + out_dir, 'run_name:=' + name, 'unique:=false',
           'plot:=false',
           'progress_period:=0', 'telemetry_port:=%d' % processes.free_port()] + list(extra)
    log = os.path.join(out_dir, name + '.launch.log')
    base = os.path.join(out_dir, name)
    wall0 = time.monotonic()
    proc = processes.start(cmd, env=env, log=log)
    try:
        while time.monotonic() - wall0 < timeout and proc.poll() is None:
            if os.path.exists(base + '.run.yaml') and os.path.exists(base + '.bag'):
                break
            time.sleep(0.5)
        wall = time.monotonic() - wall0
        time.sleep(1.5)                 # the bag's last /diagnostics (1 Hz)
    finally:
        processes.stop(proc, grace=20.0)
    lockstep = lockstep_figures(base + '.bag') if os.path.exists(base + '.bag') else {}
    return {'summary': read_yaml(base + '.yaml'), 'info': read_yaml(base + '.run.yaml'), 'lockstep': lockstep,
            'wall_s': round(wall, 2), 'log': log, 'base': base}


def run_inprocess(controller, out_dir, scenario_file):
    """``experiment.py run --engine inprocess --sync-schedule``: the summary dict."""
    name = 'inprocess_%s' % controller
    subprocess.check_call([sys.executable, '-m', 'anafi_lab.cli.experiment', 'run', '--controller', controller, '--scenario', scenario_file,
                           '--engine', 'inprocess', '--sync-schedule', '--no-plot', '--name', name,
                           '--out', out_dir], stdout=subprocess.DEVNULL)
    return read_yaml(os.path.join(out_dir, name + '.yaml'))


def e_mu(summary, source='estimate'):
    try:
        return float(summary[source]['e_mu'])
    except (KeyError, TypeError, ValueError):
        return None
