#!/usr/bin/env python3
"""Benchmark helper: emulation of the paper's reference "Interface" (one ``client | grep KEY`` per key).

Stage: telemetry -> interface, the reference way, kept only to measure it
side by side with ours (benchmarks/bench_interface.py); not part of the stack.
The reference implementation started one shell pipeline
``tlm-data-logger -r R inet:HOST:PORT | grep KEY`` per telemetry key (24
pipelines = 24 CLI processes + 24 grep processes, each under a ``sh``), kept
the last value printed by each, and a ROS node published all of them in one
message. This node does exactly that: one reader thread per pipe stores the
last value of its key, a ``rospy.Timer`` publishes ``sphinx/drone_data``
(anafi_sim/DroneData, header.stamp = rospy.Time.now(), units as the
telemetry: SI, world ENU / body FLU) at ``~rate`` Hz with whatever values are
current, so one message may mix fields of different samples, as the
reference's did. Unlike the reference it fills the angular-velocity fields
with the angular velocity (the reference's bug does not change the cost), and
it builds each pipeline from two processes joined by a pipe instead of handing
a command line to ``sh`` (no parameter is ever run by a shell; the idle ``sh``
of each reference pipeline is not counted).

Parameters: ~cli (command printing the telemetry, without its endpoint;
default ``tlm_data_logger.py -r 0``; one of the known tools, checked like the
interface's ~telemetry_command: anafi_sim.interface.telemetry_command), ~host (127.0.0.1), ~port (9060),
~prefix (omniscient_anafi.), ~rate (100 Hz). Every pipeline runs in its own
process group, stopped on shutdown (anafi_sim.processes.stop).
"""
import subprocess
import sys
import threading

import rospy

from anafi_sim import processes
from anafi_sim.interface.telemetry_command import allowed_argv
from anafi_sim.msg import DroneData
from anafi_sim.telemetry.protocol import DEFAULT_PREFIX, key_map

# sample field -> DroneData field
MSG_FIELDS = {
    'x': 'posX', 'y': 'posY', 'z': 'posZ',
    'vx': 'velXENU', 'vy': 'velYENU', 'vz': 'velZENU',
    'roll': 'attitudeX', 'pitch': 'attitudeY', 'yaw': 'attitudeZ',
    'body_vx': 'velXABC', 'body_vy': 'velYABC', 'body_vz': 'velZABC',
    'body_wx': 'angVelXABC', 'body_wy': 'angVelYABC', 'body_wz': 'angVelZABC',
    'body_ax': 'accXABC', 'body_ay': 'accYABC', 'body_az': 'accZABC',
    'body_alpha_x': 'angAccXABC', 'body_alpha_y': 'angAccYABC', 'body_alpha_z': 'angAccZABC',
    'timestamp': 'timeStamp',
    'gimbal_pitch': 'gimbalPitchMotorAngle', 'gimbal_roll': 'gimbalRollMotorAngle',
}


def pipeline_commands(cli, host, port, key):
    """(CLI argv, grep argv): the two processes of the pipeline that prints only ``key``'s lines.
    ValueError when ``cli`` is not one of the known telemetry tools."""
    cli_argv = allowed_argv('%s inet:%s:%d' % (cli, host, int(port)))
    return cli_argv, ['grep', '--line-buffered', '--fixed-strings', '--', key]


class PaperInterface(object):
    def __init__(self, cli, host, port, prefix, rate):
        self.values = dict((f, 0.0) for f in MSG_FIELDS.values())
        self.lines = 0
        self.bad_lines = 0
        self.procs = []
        self.threads = []
        self.pub = rospy.Publisher('sphinx/drone_data', DroneData, queue_size=50)
        self.commands = [(pipeline_commands(cli, host, port, key), MSG_FIELDS[field])
                         for key, field in key_map(prefix).items()]
        self.period = 1.0 / rate
        self.timer = None

    def start(self):
        for (cli_argv, grep_argv), msg_field in self.commands:
            source = subprocess.Popen(cli_argv, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                                      start_new_session=True)
            proc = subprocess.Popen(grep_argv, stdin=source.stdout, stdout=subprocess.PIPE, start_new_session=True)
            source.stdout.close()    # grep holds the pipe: the CLI gets SIGPIPE when grep ends
            self.procs += [source, proc]
            t = threading.Thread(target=self._read, args=(proc, msg_field), daemon=True)
            t.start()
            self.threads.append(t)
        rospy.loginfo('paper_interface: %d pipelines started, e.g. %s | %s', len(self.commands),
                      ' '.join(self.commands[0][0][0]), ' '.join(self.commands[0][0][1]))
        self.timer = rospy.Timer(rospy.Duration(self.period), self._publish)

    def _read(self, proc, msg_field):
        values = self.values
        for line in iter(proc.stdout.readline, b''):
            self.lines += 1
            try:
                values[msg_field] = float(line.rsplit(b':', 1)[1])
            except (IndexError, ValueError):
                self.bad_lines += 1

    def _publish(self, _event):
        d = DroneData()
        d.header.stamp = rospy.Time.now()
        d.header.frame_id = 'world'
        for name, value in self.values.items():
            setattr(d, name, value)
        self.pub.publish(d)

    def shutdown(self):
        if self.timer is not None:
            self.timer.shutdown()
        for proc in self.procs:
            processes.stop(proc, grace=1.0)


def main():
    rospy.init_node('paper_interface')
    cli = rospy.get_param('~cli', 'tlm_data_logger.py -r 0')
    host = rospy.get_param('~host', '127.0.0.1')
    port = rospy.get_param('~port', 9060)
    prefix = rospy.get_param('~prefix', DEFAULT_PREFIX)
    rate = rospy.get_param('~rate', 100.0)
    if not isinstance(port, int) or not 0 < port < 65536:
        rospy.logfatal('paper_interface: ~port must be an integer in 1..65535, got %r', port)
        return 2
    if isinstance(rate, bool) or not isinstance(rate, (int, float)) or not rate > 0:
        rospy.logfatal('paper_interface: ~rate must be > 0, got %r', rate)
        return 2
    try:
        node = PaperInterface(cli, host, port, prefix, float(rate))
    except ValueError as error:
        rospy.logfatal('paper_interface: ~cli / ~host: %s', error)
        return 2
    rospy.on_shutdown(node.shutdown)
    try:
        node.start()
        rospy.spin()
    finally:
        node.shutdown()
    return 0


if __name__ == '__main__':
    sys.exit(main())
