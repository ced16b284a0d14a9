"""One straight-line run (straight_line.py, cpu_usage.py): sim.launch + a controller's launch file on a private
ROS master, the worker (straight_line_worker.py) flying the scenario against it, everything stopped after.

``args`` are straight_line.py's options (controller/launch, launch_arg, drone, state_topic, rtf, wall_clock,
settle, measure).
"""
import json
import os
import subprocess
import sys
import time

from anafi_sim import processes
from anafi_sim.mission.fleet import launch_document

BENCH = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(BENCH)
RESULTS = os.path.join(BENCH, 'results')
WORKER = os.path.join(BENCH, 'straight_line_worker.py')
MASTER_PORTS = (11400, 11900)   # private masters' ports, away from the OS's ephemeral range



def controller_launch_path(args):
    if args.launch:
        return os.path.abspath(args.launch)
    path = os.path.join(ROOT, 'anafi_sim', 'launch', '%s.launch' % args.controller)
    if not os.path.exists(path):
        raise SystemExit('no launch file for controller %r (%s); give --launch' % (args.controller, path))
    return path


def launch_nodes(args):
    """Node names (absolute) started by the controller launch file with the run's arguments."""
    cmd = ['roslaunch', '--nodes', controller_launch_path(args), 'drone_name:=' + args.drone,
           'state_topic:=' + args.state_topic] + list(args.launch_arg)
    out = subprocess.check_output(cmd, universal_newlines=True)
    return [line.strip() for line in out.splitlines() if line.strip().startswith('/')]


class RosRun(object):
    """roscore (ours, proven) + roslaunch (sim + controller) on a private master. Use as a context."""

    def __init__(self, args, workdir):
        self.args = args
        self.workdir = workdir
        self.procs = processes.Processes(workdir, grace=20.0)   # roslaunch stops its nodes one by one
        self.env = None
        self.launch_file = None

    def __enter__(self):
        try:
            uri, self.env = processes.private_master(self.procs, os.path.join(self.workdir, 'ros_home'),
                                                   os.path.join(self.workdir, 'ros_log'), MASTER_PORTS)
            self.port = int(uri.rsplit(':', 1)[1])
            self.launch_file = self._write_launch()
            self.procs.start('roslaunch', ['roslaunch', '--port', str(self.port), self.launch_file], self.env)
        except BaseException:
            self.stop()
            raise
        return self

    def __exit__(self, *exc):
        self.stop()

    def _write_launch(self):
        args = self.args
        sim = [('drone_name', args.drone), ('use_sim_time', 'true' if not args.wall_clock else 'false'),
               ('rtf', 1.0 if args.wall_clock else args.rtf), ('telemetry_port', processes.free_port())]
        controller = [('drone_name', args.drone), ('state_topic', args.state_topic), ('output', 'log')]
        controller += [tuple(a.split(':=', 1)) for a in args.launch_arg]
        path = os.path.join(self.workdir, 'run_%d.launch' % self.port)
        with open(path, 'w') as f:
            f.write(launch_document([('sim.launch', sim), (controller_launch_path(args), controller)]))
        return path

    def stop(self):
        left = self.procs.stop_all()
        if left:
            sys.stderr.write('processes %s did not stop\n' % left)

    def run_worker(self, worker_args, timeout):
        """Run straight_line_worker.py (a rospy client of the private master); returns its JSON result."""
        out = os.path.join(self.workdir, 'result_%d.json' % self.port)
        cmd = [sys.executable, WORKER, '--out', out] + worker_args
        rc = subprocess.call(cmd, env=self.env, timeout=timeout)
        if rc != 0 or not os.path.exists(out):
            raise RuntimeError('worker failed (exit %d); end of the roslaunch log:\n%s'
                               % (rc, self.procs.log_tail('roslaunch', 40)))
        with open(out) as f:
            return json.load(f)


def run_speed(args, speed, workdir, cpu_nodes=None, measure=None):
    """One run at ``speed`` [m/s]: the worker's result dict (see straight_line_worker.py)."""
    with RosRun(args, workdir) as run:
        worker_args = ['--speed', repr(speed), '--settle', repr(args.settle),
                       '--measure', repr(measure if measure is not None else args.measure),
                       '--drone', args.drone]
        if cpu_nodes:
            worker_args += ['--cpu-nodes'] + list(cpu_nodes)
        time.sleep(2.0)
        result = run.run_worker(worker_args, timeout=900)
    return result
