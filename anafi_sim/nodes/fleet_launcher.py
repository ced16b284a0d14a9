#!/usr/bin/env python3
"""Fleet launcher node: a fleet file -> one launch file with every drone's includes -> roslaunch it (thin node).

Stage: experiments (anafi_sim.mission.fleet does the parsing, the checks and the XML). roslaunch cannot
loop, so fleet.launch starts this node (required): it reads the fleet file ~fleet (or builds ~drones N drones
in a row from its defaults), picks a free telemetry port for each simulated drone that has none, writes each
drone's scenario shifted by its offset and the generated launch file into ~out_dir, and runs ``roslaunch``
on that file (a child process in a session of its own, on the same master) until it ends or this node is
stopped (SIGINT / SIGTERM: SIGINT to the child and to each of its nodes at once; then SIGTERM, SIGKILL; the
child also gets SIGINT from the kernel if this node is killed, so no drone is left running).
When the child has ended it prints the fleet's summary, one table with a row per drone (its controller, the
state of its evaluation, e_mu / e_max against estimate and ground truth: anafi_sim.mission.fleet_summary, from the
evaluators' out_dir/NAME.yaml of this run) and exits with the child's code; a bad fleet file or parameter:
logfatal, exit code 2.

Parameters: ~fleet (name in anafi_sim/config/fleets or a path; circles), ~drones (0: the file's list;
N > 0: N in a row), ~out_dir (~/.ros/anafi_fleet), ~evaluate (true), ~mirror (true), ~mirror_rate (100 Hz),
~output (log | screen), ~aggregator (false: diagnostic_aggregator, ROS Noetic only), ~rviz (false; true: rviz.launch
per drone and rviz on the fleet's generated view ~out_dir/fleet.rviz, anafi_sim/mission/rviz_config.py),
~stop_timeout (STOP_TIMEOUT, 8 s), ~max_drones (0: this machine's fleet cap, anafi_sim.launch_check.machine_cap:
its own measurement cached under the ROS home, else the conservative default; a larger fleet is refused with a
message naming the cap, its figure and where it came from).

Also a command-line tool, to see or check what a fleet file starts without starting it:

    fleet_launcher.py FLEET [--drones N] [--out-dir DIR] [--evaluate true|false] [--mirror true|false]
                      [--mirror-rate HZ] [--output log|screen] [--aggregator true|false] [--rviz true|false]
                      [--max-drones N] [--world kinematic|gazebo|none] [--layout per_drone|shared]
                      (--print | --write-only)

--print: the generated XML on stdout; --write-only: write the files and print the launch file's path (then
e.g. ``roslaunch --nodes PATH``). A bad fleet file: one error line and exit code 2.
"""
import argparse
import ctypes
import os
import signal
import subprocess
import sys
import threading
import time

import yaml

from anafi_sim.mission.fleet import aggregator_analyzers, drone_scenario, fleet_path, launch_xml, load_fleet
from anafi_sim.mission.fleet_layout import LAYOUTS, NodeSpec, check_layout, shared_layout, split_limits
from anafi_sim.mission.fleet_summary import fleet_summary
from anafi_sim.mission.rviz_config import fleet_rviz
from anafi_sim.mission.trajectory import scenario_from_dict
from anafi_sim.processes import free_port, stop
from anafi_sim.launch_check import fleet_size_problem, machine_drones_per_host

DEFAULT_OUT_DIR = os.path.join(os.path.expanduser('~'), '.ros', 'anafi_fleet')
DEFAULT_FLEET = 'circles'
OUTPUTS = ('log', 'screen')


def generate(fleet_name, drones, out_dir, evaluate, mirror, mirror_rate, output, aggregator, log=sys.stderr.write,
             rviz=False, conditions='', max_drones=0, layout='', world=False):
    """Write the scenarios (and the aggregator groups) and the launch file into out_dir; its path. ValueError
    for a bad fleet, or one larger than the fleet cap (anafi_sim.launch_check.fleet_size_problem). ``layout``:
    per_drone | shared ('' = the fleet file's, per_drone by default; anafi_sim.mission.fleet_layout); ``world``:
    the kinematic world in the generated launch (fleet.launch world:=kinematic)."""
    fleet = load_fleet(fleet_name, drones)
    layout = check_layout(layout or fleet.layout)
    too_many = fleet_size_problem(len(fleet.drones), max_drones, layout=layout)
    if too_many:
        raise ValueError(too_many)
    out_dir = os.path.abspath(os.path.expanduser(out_dir))
    os.makedirs(out_dir, exist_ok=True)
    ports, files = {}, {}
    for drone in fleet.drones:
        if drone.source == 'sim':
            port = drone.telemetry_port
            while port is None or port in ports.values():
                port = free_port()
            ports[drone.name] = port
        scenario = drone_scenario(drone)
        if scenario is not None:
            files[drone.name] = os.path.join(out_dir, '%s.scenario.yaml' % drone.name)
            with open(files[drone.name], 'w') as f:
                yaml.safe_dump(scenario, f, default_flow_style=None, sort_keys=False)
    aggregator_file = ''
    if aggregator:
        aggregator_file = os.path.join(out_dir, 'diagnostics_aggregator.yaml')
        with open(aggregator_file, 'w') as f:
            yaml.safe_dump(aggregator_analyzers(fleet), f, default_flow_style=False, sort_keys=False)
    rviz_file = ''
    if rviz:
        rviz_file = os.path.join(out_dir, 'fleet.rviz')
        text, _ = fleet_rviz(fleet, dict((name, scenario_from_dict(yaml.safe_load(open(path))))
                                         for name, path in files.items()))
        with open(rviz_file, 'w') as f:
            f.write(text)
    xml = launch_xml(fleet, ports, files, out_dir, evaluate=evaluate, mirror=mirror, mirror_rate=mirror_rate,
                     output=output, source=fleet_path(fleet_name), aggregator_file=aggregator_file,
                     rviz=rviz, rviz_file=rviz_file, conditions=conditions, world=world)
    path = os.path.join(out_dir, 'fleet.launch')
    if layout == 'shared':
        machine, why = machine_drones_per_host()
        limits = split_limits(machine, fleet.drones_per_host)
        log('fleet %s: hosts split by %s (this machine: %s%s)\n' % (
            fleet.name, ', '.join('%d drones (%s)' % (limits[h], h) for h in sorted(limits)), why,
            '; the fleet file sets %s' % fleet.drones_per_host if fleet.drones_per_host else ''))
        xml = shared_launch(xml, out_dir, output, fleet.name, limits)
    with open(path, 'w') as f:
        f.write(xml)
    for drone in fleet.drones:
        log('fleet %s: %s (%s, %s%s)\n' % (fleet.name, drone.name, drone.source, drone.controller,
                                           ', telemetry port %d' % ports[drone.name] if drone.name in ports else ''))
    log('fleet %s: %s layout\n' % (fleet.name, layout))
    return path


def shared_launch(per_drone_xml, out_dir, output, title, drones_per_host=None):
    """The shared layout's launch XML (its parameters written to out_dir/fleet.params.yaml): roslaunch expands
    the per-drone launch (out_dir/fleet.per_drone.launch, kept for reading) into nodes and parameters, and
    anafi_sim.mission.fleet_layout puts the hostable nodes into hosts."""
    import roslaunch.config
    per_drone = os.path.join(out_dir, 'fleet.per_drone.launch')
    with open(per_drone, 'w') as f:
        f.write(per_drone_xml)
    config = roslaunch.config.load_config_default([per_drone], None, verbose=False)
    nodes = [NodeSpec(n.package, n.type, n.name, n.namespace, n.args, n.output, n.respawn, n.respawn_delay,
                      n.required, n.launch_prefix, n.cwd, list(n.env_args), list(n.remap_args))
             for n in config.nodes]
    params = dict((key, p.value) for key, p in config.params.items()
                  if key not in ('/rosdistro', '/rosversion'))
    params_file = os.path.join(out_dir, 'fleet.params.yaml')
    xml, document = shared_layout(nodes, params, params_file, output=output, title='fleet ' + title,
                                  drones_per_host=drones_per_host)
    with open(params_file, 'w') as f:
        yaml.safe_dump(document, f, default_flow_style=False, sort_keys=True)
    return xml


# ------------------------------------------------------------------------------------ the node
PR_SET_PDEATHSIG = 1


def _child_setup():
    """In the fleet's roslaunch before exec: a session of its own (signals to our group do not hit it twice),
    and SIGINT from the kernel when this node dies (Linux prctl PR_SET_PDEATHSIG), so the drones stop even if
    this node is killed."""
    os.setsid()
    try:
        ctypes.CDLL(None, use_errno=True).prctl(PR_SET_PDEATHSIG, signal.SIGINT)
    except (OSError, AttributeError):   # not Linux: stopping relies on cleanup()
        pass


#: [s] wall time the fleet's roslaunch has to stop its nodes (then SIGTERM, SIGKILL of what is left): with the
#: summary and this node's own end, below the 15 s roslaunch gives this node before it escalates (a node on a quiet
#: machine ends in about a second)
STOP_TIMEOUT = 8.0
#: [s] more for the SIGTERM / SIGKILL of what was left, before the summary is printed anyway
KILL_TIME = 2.0
#: [s] for this node's own rospy shutdown after the summary
END_TIME = 1.5
#: [s] after SIGINT to the fleet's roslaunch, before SIGINT to each of its nodes: its process monitor is shut down
#: by then, so it does not respawn a node that ends
NODES_AFTER = 0.3


def interrupt_nodes(child, after=NODES_AFTER):
    """SIGINT to the fleet's roslaunch ``child``, then (``after`` s later) to every node it started, all at once:
    roslaunch alone stops them ten at a time, each wave waiting for its slowest node; the nodes ignore its SIGINT
    when it comes (anafi_sim.ros.node.install_shutdown_signals)."""
    import psutil
    try:
        child.send_signal(signal.SIGINT)
        time.sleep(after)
        nodes = psutil.Process(child.pid).children()
    except (OSError, psutil.Error):
        return
    for node in nodes:
        try:
            node.send_signal(signal.SIGINT)
        except psutil.Error:
            pass


class FleetLauncherNode(object):
    def __init__(self):
        import rospy
        from anafi_sim.ros.node import private_params
        self.rospy = rospy
        p = private_params()
        self.stop_timeout = p.positive('stop_timeout', STOP_TIMEOUT)
        self.started = time.time()
        name, drones = p.string('fleet', DEFAULT_FLEET, allow_empty=False), p.integer('drones', 0, minimum=0)
        self.out_dir = os.path.abspath(os.path.expanduser(p.string('out_dir', DEFAULT_OUT_DIR, allow_empty=False)))
        self.evaluate = p.flag('evaluate', True)
        self.path = generate(name, drones, self.out_dir, self.evaluate, p.flag('mirror', True),
                             p.positive('mirror_rate', 100.0),
                             p.choice('output', 'log', OUTPUTS), p.flag('aggregator', False),
                             log=lambda text: rospy.loginfo(text.rstrip()), rviz=p.flag('rviz', False),
                             conditions=p.string('conditions', '', allow_empty=True),
                             max_drones=p.integer('max_drones', 0, minimum=0),
                             layout=p.string('layout', ''),
                             world=p.flag('kinematic_world', False))   # ValueError: fatal, exit 2
        self.fleet = load_fleet(name, drones)
        self.child = None
        self.code = 0
        self.ended = 'stopped'
        self.printed = False

    def spin(self):
        rospy = self.rospy
        rospy.loginfo('fleet_launcher: roslaunch %s', self.path)
        self.child = subprocess.Popen(['roslaunch', self.path], stdin=subprocess.DEVNULL, preexec_fn=_child_setup)
        while not rospy.is_shutdown() and self.child.poll() is None:
            time.sleep(0.2)
        if self.child.poll() is not None:
            self.code = self.child.returncode
            self.ended = 'ended (its roslaunch exited with code %d)' % self.code
            rospy.logerr('fleet_launcher: the fleet\'s roslaunch ended (exit code %d)', self.code)

    def cleanup(self):
        # the parent roslaunch escalates SIGINT -> SIGTERM -> SIGKILL; keep stopping the fleet meanwhile (if
        # we are killed, the child gets SIGINT from the kernel: _child_setup) instead of dying half-way
        for sig in (signal.SIGINT, signal.SIGTERM):
            signal.signal(sig, signal.SIG_IGN)
        if self.child is not None and self.child.poll() is None:
            started = time.monotonic()
            interrupt_nodes(self.child)
            left = []
            stopping = threading.Thread(target=lambda: left.extend(stop(self.child, grace=self.stop_timeout,
                                                                        kill_wait=0.3)), daemon=True)
            stopping.start()
            stopping.join(self.stop_timeout + KILL_TIME)
            took = time.monotonic() - started
            if took > self.stop_timeout:
                self.rospy.logwarn('fleet_launcher: the fleet had not stopped %.0f s after the signal: the rest '
                                   'ended with SIGTERM / SIGKILL', self.stop_timeout)
            if left or stopping.is_alive():
                self.rospy.logwarn('fleet_launcher: processes still alive after stopping: %s', left or '(still '
                                   'stopping)')
        self.print_summary()
        # this node's own end bounded too (rospy's shutdown unregisters from a master that may be busy with the
        # whole fleet's): at most END_TIME s, then the process ends with the fleet's exit code
        ending = threading.Thread(target=self.rospy.signal_shutdown, args=('fleet stopped',), daemon=True)
        ending.start()
        ending.join(END_TIME)
        sys.stderr.flush()
        os._exit(self.code)

    def print_summary(self):
        if not self.printed:
            self.printed = True
            sys.stdout.write('\n' + self.summary())
            sys.stdout.flush()

    def summary(self):
        """The fleet's one table (anafi_sim.mission.fleet_summary): per drone, its evaluation of this run."""
        return fleet_summary(self.fleet.name, [(d.name, d.controller) for d in self.fleet.drones], self.out_dir,
                             self.evaluate, since=self.started, reason=self.ended)

    def run(self):
        from anafi_sim.ros.node import run_until_interrupted
        try:
            # the stop and the summary take stop_timeout + KILL_TIME at most; this node's own end some more
            run_until_interrupted(self.spin, self.cleanup, 'fleet stopped', grace=self.stop_timeout + KILL_TIME + 3.0)
        finally:
            self.print_summary()
        return self.code


# ------------------------------------------------------------------------------------ the tool
def flag(text):
    """A roslaunch boolean: true / false (any case), 1 / 0."""
    value = {'true': True, '1': True, 'false': False, '0': False}.get(text.strip().lower())
    if value is None:
        raise argparse.ArgumentTypeError('expected true or false, got %r' % text)
    return value


def tool(argv):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument('fleet', help='fleet file (path, or a name in anafi_sim/config/fleets)')
    ap.add_argument('--drones', type=int, default=0, help='N > 0: N drones in a row from the file\'s defaults')
    ap.add_argument('--out-dir', default=DEFAULT_OUT_DIR)
    ap.add_argument('--evaluate', type=flag, default=True, metavar='true|false')
    ap.add_argument('--mirror', type=flag, default=True, metavar='true|false')
    ap.add_argument('--mirror-rate', type=float, default=100.0, help='Hz')
    ap.add_argument('--output', default='log', choices=OUTPUTS)
    ap.add_argument('--aggregator', type=flag, default=False, metavar='true|false')
    ap.add_argument('--rviz', type=flag, default=False, metavar='true|false')
    ap.add_argument('--conditions', default='', help='flight-conditions profile NAME for every simulated drone')
    ap.add_argument('--max-drones', type=int, default=0,
                    help='the fleet cap (0: this machine\'s, launch_check.machine_cap)')
    ap.add_argument('--world', default='kinematic', choices=('kinematic', 'gazebo', 'none'),
                    help='as fleet.launch world:= (kinematic: the world is in the generated launch)')
    ap.add_argument('--layout', default='', choices=('',) + LAYOUTS,
                    help='per_drone | shared (default: the fleet file\'s, else per_drone)')
    what = ap.add_mutually_exclusive_group(required=True)
    what.add_argument('--print', dest='print_only', action='store_true')
    what.add_argument('--write-only', action='store_true')
    args = ap.parse_args(argv)
    try:
        path = generate(args.fleet, args.drones, args.out_dir, args.evaluate, args.mirror, args.mirror_rate,
                        args.output, args.aggregator, rviz=args.rviz, conditions=args.conditions,
                        max_drones=args.max_drones, layout=args.layout, world=args.world == 'kinematic')
    except ValueError as error:
        sys.stderr.write('fleet_launcher: %s\n' % error)
        return 2
    if args.print_only:
        with open(path) as f:
            sys.stdout.write(f.read())
    else:
        sys.stdout.write(path + '\n')
    return 0


def main():
    argv = [a for a in sys.argv[1:] if not a.startswith('__')]   # roslaunch's __name:= / __log:=
    if argv:
        sys.exit(tool(argv))
    from anafi_sim.ros.node import run_node
    run_node('fleet_launcher', FleetLauncherNode, fatal_exit_code=2, disable_signals=True)
