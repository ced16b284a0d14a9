#!/usr/bin/env python3
"""rosbag record with its output directory created first (rosbag refuses a missing directory).

Stage: experiment logging. Usage (as a launch-file node; roslaunch's __name / __log remappings are
passed through):

    record_bag.py [--run-info RUN.run.yaml] -O /path/to/run.bag /topic_a /topic_b ...

Creates the directory of the -O/--output-name file, then replaces itself (exec) with rosbag's
``record`` executable (the node roslaunch runs for pkg="rosbag" type="record"; ``rosbag record``
when it cannot be found) and the same arguments, so roslaunch's SIGINT reaches it and the bag is
closed properly (run.bag.active -> run.bag). Exit code 2 when no -O is given.

With ``--run-info PATH`` (the experiment monitor's run file) it runs rosbag as a child instead,
forwards SIGINT / SIGTERM to it, and once the bag is closed keeps its name only when PATH says
``state: final``; otherwise (the run failed or never ended) the bag is renamed RUN.FAILED.bag
(anafi_sim.run_files.failed_name), like the run's other files.
"""
import os
import signal
import subprocess
import sys


def output_path(argv):
    """The file given with -O / --output-name=... in ``argv``, or None."""
    for i, arg in enumerate(argv):
        if arg == '-O' and i + 1 < len(argv):
            return argv[i + 1]
        if arg.startswith('--output-name='):
            return arg.split('=', 1)[1]
    return None


def split_run_info(argv):
    """(run info path or None, the other arguments)."""
    rest, info = [], None
    args = list(argv)
    while args:
        arg = args.pop(0)
        if arg == '--run-info' and args:
            info = args.pop(0)
        elif arg.startswith('--run-info='):
            info = arg.split('=', 1)[1]
        else:
            rest.append(arg)
    return info, rest


def run_final(path):
    """True when the run file at ``path`` says state final."""
    try:
        import yaml
        with open(path) as f:
            data = yaml.safe_load(f)
    except Exception:     # missing, unreadable: not a final run
        return False
    return isinstance(data, dict) and data.get('state') == 'final'


def _record_command(argv):
    try:
        import roslib.packages
        found = roslib.packages.find_node('rosbag', 'record')
    except Exception:       # roslib missing or no rosbag package: the command-line tool below
        found = []
    if found:
        return [found[0]] + list(argv)
    return ['rosbag', 'record'] + list(argv)


def supervise(command, bag, info):
    """Run ``command``, forward SIGINT / SIGTERM, then mark the bag FAILED unless ``info`` is final."""
    from anafi_sim.run_files import failed_name
    child = subprocess.Popen(command)

    def forward(signum, frame):
        try:
            child.send_signal(signum)
        except OSError:
            pass
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, forward)
    code = child.wait()
    if not run_final(info):
        for path in (bag, bag + '.active'):
            if os.path.exists(path):
                target = failed_name(path[:-len('.active')] if path.endswith('.active') else path)
                os.replace(path, target + ('.active' if path.endswith('.active') else ''))
                sys.stderr.write('record_bag.py: the run did not end final (%s): bag renamed %s\n' % (info, target))
    return code


def main(argv):
    info, argv = split_run_info(argv)
    path = output_path(argv)
    if not path:
        sys.stderr.write('record_bag.py: give the bag file with -O PATH\n')
        return 2
    directory = os.path.dirname(os.path.abspath(path))
    if not os.path.isdir(directory):
        os.makedirs(directory)
    command = _record_command(argv)
    if info:
        return supervise(command, path, info)
    os.execv(command[0], command) if os.path.isabs(command[0]) else os.execvp(command[0], command)
    return 1    # not reached
