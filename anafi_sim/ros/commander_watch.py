"""ROS glue of ``anafi_control.commanders.CommanderGuard``: a commanding node watches its own command topic.

``CommandTopicWatch(topic, msg_class)`` subscribes to the node's command topic and feeds the guard with
the commands of OTHER nodes. A command's sender is the publisher its connection was made to: the XML-RPC URI
the master listed for the topic (rospy's ``endpoint_id`` of the connection), not the ``callerid`` its header
claims (``commander_label``): a node that claims this node's name in its header but is another process is a
second commander like any other (the node's own commands come back too and are ignored). ``check()`` (every control cycle) says DOWN / RESUMED / CLEAR and logs an
ERROR once per episode naming the other nodes; ``check_presence()`` (from the 1 Hz wall-clock diagnostics
thread) asks the master whether each other node still publishes the topic and still answers (getPid, 1 s
timeout): a node killed without unregistering, or one that stopped publishing, no longer keeps this one
down. ``values()`` are the diagnostics values (with the other publishers of the topic, also idle ones: a
controller started on a drone that is already commanded hears the commands at once and never commands);
``message()`` the ERROR text while down.

``ctx`` (a NodeContext, default the process's node): the node instance that commands. A hosted instance
(the shared layout) hears the commands of the other instances of its host through the host's bus, without a
caller id: its own are the messages it handed to ``sent`` before publishing them, any other is a commander
named ``<host> (an instance of this host)``; those of other processes carry their caller id as usual.
"""
import collections
import threading
import time

import rosgraph

from anafi_control.commanders import DOWN, LISTEN, RESUMED, CommanderGuard
from anafi_sim.processes import xmlrpc_proxy
from anafi_sim.ros.context import NodeContext

#: [s] XML-RPC timeout of the presence checks (master and the other node)
PRESENCE_TIMEOUT = 1.0


def commander_label(claimed, endpoint, my_uri, my_name):
    """Who sent a command (pure): None when it is this node's own, else the name to report.

    ``claimed``: the connection header's callerid (anyone may write anything there); ``endpoint``: the XML-RPC
    URI of the publisher the connection was made to (from the master's publisher list; None or 'unknown'
    when the connection is not known); ``my_uri``: this node's; ``my_name``: its name, or the names it goes
    by (a hosted instance: its own and its host's, the name its commands carry on the wire). A known endpoint
    decides: this node's URI is its own command whatever the header says, any other URI is another node, named
    by its header unless that claims one of this node's names (then by its URI)."""
    names = (my_name,) if isinstance(my_name, str) else tuple(n for n in my_name if n)
    known = bool(endpoint) and endpoint != 'unknown' and bool(my_uri)
    if known:
        if endpoint == my_uri:
            return None
        if not claimed or claimed in names:
            return '%s (claims to be %s)' % (endpoint, claimed or names[0])
        return claimed
    return claimed if claimed and claimed not in names else None


def _answers(uri, caller, timeout=PRESENCE_TIMEOUT):
    try:
        code = xmlrpc_proxy(uri, timeout).getPid(caller)[0]
    except Exception:       # refused, timed out, not XML-RPC: gone
        return False
    return code == 1


class CommandTopicWatch(object):
    def __init__(self, topic, msg_class, quiet_time=2.0, ctx=None):
        self.ctx = ctx = ctx or NodeContext.process()     # also what logs
        self.topic = ctx.resolve(topic)
        self.me = ctx.name
        self.host = ctx.bus.caller_id if ctx.hosted else None     # the process's node name, hosted
        self._sent = collections.deque(maxlen=32)                # hosted: own commands handed to the bus
        self.guard = CommanderGuard(quiet_time)
        self.lock = threading.Lock()
        self._others = []
        self._endpoints = {}     # reported name -> the publisher URI its commands came from
        self.silent = True       # the last check said DOWN or LISTEN: publish nothing
        self.sub = ctx.subscriber(self.topic, msg_class, self._on_command, queue_size=20)

    def sent(self, msg):
        """``msg`` is a command of this node (call before publishing it): hosted, it comes back without a
        caller id."""
        if self.host is not None:
            with self.lock:
                self._sent.append(msg)

    def _connections(self):
        try:
            sub = getattr(self.sub, 'sub', self.sub)     # hosted: the rospy subscriber of the bus's subscription
            return list(sub.impl.connections)
        except Exception:     # rospy internals changed: the commands heard still work (by their header)
            return []

    def _my_uri(self):
        try:
            import rospy
            return rospy.get_node_uri()
        except Exception:
            return None

    def publishers(self):
        """The other nodes connected to this node as publishers of the command topic (from the subscriber's
        connections: no master call), sorted; they may be idle (a controller that stood down)."""
        my_uri = self._my_uri()
        names = [commander_label((c.header or {}).get('callerid', ''), getattr(c, 'endpoint_id', None), my_uri,
                                 (self.me, self.host)) for c in self._connections() if c.header]
        return sorted(set(n for n in names if n and n != self.host))

    def _on_command(self, msg):
        header = getattr(msg, '_connection_header', None) or {}
        claimed = header.get('callerid', '')
        if not claimed and self.host is not None and not header:       # hosted: from an instance of this host
            with self.lock:
                if any(m is msg for m in self._sent):
                    return
            caller = '%s (an instance of this host)' % self.host
        else:
            endpoint = next((getattr(c, 'endpoint_id', None) for c in self._connections() if c.header is header),
                            None)
            caller = commander_label(claimed, endpoint, self._my_uri(), (self.me, self.host))
            if caller and endpoint and endpoint != 'unknown':
                with self.lock:
                    self._endpoints[caller] = endpoint
        if caller and caller != self.me:
            with self.lock:
                self.guard.on_command(caller, time.monotonic())

    def check(self):
        """DOWN (publish nothing), RESUMED (reset the controller, then command) or CLEAR, for this cycle."""
        with self.lock:
            state = self.guard.check(time.monotonic())
            others = self.guard.others(time.monotonic()) if state == DOWN else []
            self.silent = state in (DOWN, LISTEN)
        if state == DOWN and others != self._others:
            self.ctx.logerr('%s: second commander on %s: %s publishes piloting commands too; standing down (no '
                            'command: the firmware hover brake stops the drone) until it is gone (episode %d)',
                            self.me, self.topic, ', '.join(others), self.guard.episodes)
        elif state == RESUMED:
            self.ctx.logwarn('%s: the other commander on %s is gone: commanding again', self.me, self.topic)
        self._others = others
        return state

    def check_presence(self):
        """Whether each other commander still publishes the topic and still answers (wall-clock thread)."""
        with self.lock:
            callers = list(self.guard.heard)
        if not callers:
            return
        master = rosgraph.Master(self.me)
        try:
            publishers = dict(master.getSystemState()[0]).get(self.topic, [])
        except Exception:     # master unreachable: keep what is known (the quiet time still applies)
            return
        with self.lock:
            endpoints = dict(self._endpoints)
        for caller in callers:
            present = False
            try:
                if caller in endpoints:     # identified by its URI: one of the topic's publishers still has it
                    uri = endpoints[caller]
                    present = any(master.lookupNode(p) == uri for p in publishers) and _answers(uri, self.me)
                elif caller in publishers:
                    present = _answers(master.lookupNode(caller), self.me)
            except Exception:
                present = False
            with self.lock:
                self.guard.set_present(caller, present)

    def message(self):
        """The ERROR message while standing down, else None."""
        with self.lock:
            if not self.guard.down:
                return None
            others = self.guard.others(time.monotonic())
        return 'second commander: %s also publishes %s; no command, firmware hover brake until it is gone' % (
            ', '.join(others) or 'another node', self.topic)

    def values(self):
        with self.lock:
            values = [('second commander episodes', self.guard.episodes),
                      ('commands heard from other nodes', self.guard.foreign_commands)]
        return values + [('other publishers of the command topic', ' '.join(self.publishers()) or 'none')]
