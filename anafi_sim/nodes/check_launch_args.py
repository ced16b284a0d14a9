"""The launch arguments' check (``scripts/check_launch_args.py [--launch FILE] NAME=VALUE ...``): its main().

Called by the launch files from ``<param name="..._args_checked" command="...">`` (roslaunch runs it while
reading the file). Every argument good: prints ``ok`` (the parameter's value), exit 0. Otherwise one line per
bad argument on stderr (``launch argument rtf:=-1: must be a finite number > 0``), exit 2. ``--launch FILE``
(the launch file running the check): when FILE is the one roslaunch was started with, the arguments of
roslaunch's command line (its parent's /proc/PID/cmdline, read only) that FILE does not declare are refused
too (``launch argument contoller:=pid: not an argument of experiment.launch (did you mean controller?)``).
After a refusal the check ends its parent roslaunch (SIGTERM; roslaunch has no handler while it reads the
files: nothing started yet) so the line is the last one printed; under a parent that is not the roslaunch
command (rostest, a program using roslaunch's API) it only exits 2 and the parent reports the failure.
Rules: anafi_sim.launch_check (and the fleet file's: anafi_sim.mission.fleet.launch_problem).
"""
import os
import signal
import sys

from anafi_sim.launch_check import check, command_line_arguments, declared_arguments, parse, roslaunch_argv, \
    unknown_arguments


def parent_roslaunch():
    """(pid, roslaunch's arguments) of this process's parent; arguments None when it is not roslaunch."""
    pid = os.getppid()
    try:
        with open('/proc/%d/cmdline' % pid, 'rb') as f:
            raw = f.read(1 << 20)
    except (IOError, OSError):
        return pid, None
    words = [w.decode('utf-8', 'surrogateescape') for w in raw.split(b'\0')]
    if words and words[-1] == '':
        words.pop()
    return pid, roslaunch_argv(words)


def top_level_files(argv):
    """The launch files roslaunch's ``argv`` starts, resolved as roslaunch does (real paths)."""
    import roslaunch
    import roslaunch.rlutil
    parser = roslaunch._get_optparse()

    def refuse(message):
        raise ValueError(message)
    parser.error = refuse
    _, args = parser.parse_args(list(argv))
    return [os.path.realpath(f) for f in roslaunch.rlutil.resolve_launch_arguments(args) if f != '-']


def unknown_problems(launch_file, argv):
    """The lines refusing the arguments of roslaunch's ``argv`` that ``launch_file`` does not declare, when it
    is a file roslaunch was started with (else [])."""
    given = command_line_arguments(argv)
    name = os.path.basename(launch_file)
    if not given or not any(os.path.basename(word) == name for word in argv):
        return []                      # not started with a file of this name: an included file
    try:
        files = top_level_files(argv)
    except Exception:                  # roslaunch reports its own command line's errors
        return []
    if os.path.realpath(launch_file) not in files:
        return []
    declared = []
    for path in files:
        with open(path) as f:
            declared += declared_arguments(f.read())
    return unknown_arguments(given, declared, name)


def stop_parent(pid):
    """SIGTERM to the parent roslaunch ``pid`` (through a pidfd where Python has it: never another process)."""
    try:
        if hasattr(os, 'pidfd_open') and hasattr(signal, 'pidfd_send_signal'):
            fd = os.pidfd_open(pid)
            try:
                if os.getppid() == pid:
                    signal.pidfd_send_signal(fd, signal.SIGTERM)
            finally:
                os.close(fd)
        elif os.getppid() == pid:
            os.kill(pid, signal.SIGTERM)
    except (IOError, OSError):
        pass


def main(argv):
    launch_file = None
    if argv[:1] == ['--launch'] and len(argv) >= 2:
        launch_file, argv = argv[1], argv[2:]
    pid, roslaunch_args = parent_roslaunch()
    try:
        errors = []
        if launch_file and roslaunch_args is not None:
            errors += unknown_problems(launch_file, roslaunch_args)
        args = parse(argv)
        context = {}
        if any(name == 'fleet' for name, _ in args):     # fleet.launch: the fleet file too
            from anafi_sim.mission.fleet import launch_problem
            context['fleet'] = launch_problem
        errors += check(args, context)
    except ValueError as error:
        errors = [str(error)]
    if errors:
        sys.stderr.write(''.join('\033[31m%s\033[0m\n' % e if sys.stderr.isatty() else e + '\n' for e in errors))
        sys.stderr.flush()
        if roslaunch_args is not None:
            stop_parent(pid)
        return 2
    sys.stdout.write('ok')
    return 0

