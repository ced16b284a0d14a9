#!/usr/bin/env python3
"""``rostopic echo`` for topics whose message package is not installed here (e.g. ``drone/rpyt``).

Stage: tools. ``rostopic echo /anafi/drone/rpyt`` needs the ``olympe_bridge`` package on this machine to
decode ``olympe_bridge/PilotingCommand``; where only the stand-in exists (or a real bridge runs on another
host) it cannot. Every ROS publisher sends its type and full definition when a subscriber connects, so this
tool subscribes with ``rospy.AnyMsg``, builds the class from that connection header
(``anafi_sim.ros.wire_types.decode``) and prints each message as ``rostopic echo`` does (YAML, ``---``).
Works for any type, also ``gazebo_msgs`` ones without gazebo_msgs installed.

Usage::

    rosrun anafi_sim echo.py /anafi/drone/rpyt [-n COUNT]

Exit code 0 after COUNT messages or Ctrl-C, 1 if a message cannot be decoded (the reason on stderr).
"""
import argparse
import sys
import threading

import genpy.message
import rospy

from anafi_sim.ros import wire_types


def main(argv):
    parser = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    parser.add_argument('topic', help='topic name (resolved in the caller namespace)')
    parser.add_argument('-n', type=int, default=0, help='exit after this many messages (0: run until Ctrl-C)')
    args = parser.parse_args(rospy.myargv(argv)[1:])
    rospy.init_node('echo', anonymous=True, disable_signals=False)
    done = threading.Event()
    state = {'count': 0, 'failed': False}
    lock = threading.Lock()

    def on_message(raw):
        with lock:
            if done.is_set():
                return
            try:
                msg = wire_types.decode(raw._connection_header, raw._buff)
                text = genpy.message.strify_message(msg)
            except Exception as error:   # anything a foreign publisher sends: report once, exit 1
                sys.stderr.write('echo.py: cannot decode %s: %s\n' % (args.topic, error))
                state['failed'] = True
                done.set()
                return
            sys.stdout.write(text + '\n---\n')
            sys.stdout.flush()
            state['count'] += 1
            if args.n and state['count'] >= args.n:
                done.set()

    rospy.Subscriber(args.topic, rospy.AnyMsg, on_message, queue_size=100)
    while not rospy.is_shutdown() and not done.wait(0.1):
        pass
    rospy.signal_shutdown('done')
    return 1 if state['failed'] else 0
