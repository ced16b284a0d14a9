#!/usr/bin/env python3
"""rosbag record with its output directory created first (rosbag refuses a missing directory).

Stage: experiment logging. Usage (as a launch-file node; roslaunch's __name / __log remappings are
passed through):

    record_bag.py -O /path/to/run.bag /topic_a /topic_b ...

Creates the directory of the -O/--output-name file, then replaces itself (exec) with rosbag's
``record`` executable (the node roslaunch runs for pkg="rosbag" type="record"; ``rosbag record``
when it cannot be found) and the same arguments, so roslaunch's SIGINT reaches it and the bag is
closed properly (run.bag.active -> run.bag). Exit code 2 when no -O is given.
"""
import os
import sys


def output_path(argv):
    """The file given with -O / --output-name=... in ``argv``, or None."""
    for i, arg in enumerate(argv):
        if arg == '-O' and i + 1 < len(argv):
            return argv[i + 1]
        if arg.startswith('--output-name='):
            return arg.split('=', 1)[1]
    return None


def main(argv):
    path = output_path(argv)
    if not path:
        sys.stderr.write('record_bag.py: give the bag file with -O PATH\n')
        return 2
    directory = os.path.dirname(os.path.abspath(path))
    if not os.path.isdir(directory):
        os.makedirs(directory)
    try:
        import roslib.packages
        found = roslib.packages.find_node('rosbag', 'record')
    except Exception:       # roslib missing or no rosbag package: the command-line tool below
        found = []
    if found:
        os.execv(found[0], [found[0]] + list(argv))
    os.execvp('rosbag', ['rosbag', 'record'] + list(argv))
    return 1    # not reached


if __name__ == '__main__':
    sys.exit(main(sys.argv[1:]))
