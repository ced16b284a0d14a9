#!/usr/bin/env python3
"""Checks launch arguments before any node starts: ``check_launch_args.py NAME=VALUE ...``.

Called by the launch files from ``<param name="launch_args_checked" command="...">`` (roslaunch runs it
while reading the file). Every argument good: prints ``ok`` (the parameter's value), exit 0. Otherwise one
line per bad argument on stderr (``launch argument rtf:=-1: must be a finite number > 0``), exit 2, and
roslaunch stops with a non-zero status before starting anything. Rules: anafi_sim.launch_check (and
the fleet file's: anafi_sim.mission.fleet.launch_problem).
"""
import sys

from anafi_sim.launch_check import check, parse


def main(argv):
    try:
        args = parse(argv)
        context = {}
        if any(name == 'fleet' for name, _ in args):     # fleet.launch: the fleet file too
            from anafi_sim.mission.fleet import launch_problem
            context['fleet'] = launch_problem
        errors = check(args, context)
    except ValueError as error:
        errors = [str(error)]
    if errors:
        sys.stderr.write(''.join('\033[31m%s\033[0m\n' % e if sys.stderr.isatty() else e + '\n' for e in errors))
        return 2
    sys.stdout.write('ok')
    return 0


if __name__ == '__main__':
    sys.exit(main(sys.argv[1:]))
