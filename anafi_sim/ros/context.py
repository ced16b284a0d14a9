"""Where a node instance lives in the ROS graph: its name, its ~params and its topics (the nodes' one handle).

Stage: ROS wiring only. A node class takes a ``NodeContext`` and asks it, never rospy's globals, for its
parameters (``ctx.params()``, a checked ParamReader over ``<name>/...``), its names (``ctx.resolve``) and its
publishers, subscribers and services. Two kinds:

- ``NodeContext.process()``: the process's own node (what ``rospy.init_node`` made; the per-drone layout,
  one node per process as in the paper). Names resolve through rospy, remappings included; publishers and
  subscribers are plain rospy ones.
- ``NodeContext(name, bus)``: one of the instances a host process runs (the shared layout of a fleet:
  ``anafi_sim/nodes/fleet_host.py``). Its names resolve against ``name`` (e.g. /anafi1/interface), so every drone
  keeps its own topics, parameters and services. Messages between instances of one host go through the
  host's ``LocalBus``: handed over in the process (no serialisation, no socket, no thread woken): the
  publishing thread calls the local subscribers' callbacks, in publication order, each guarded (a failing
  callback is counted and logged; the others and the publisher go on). So a node publishes outside its own
  locks, as every node here does. A subscription made ``deferred`` runs on the host's one delivery thread
  instead (woken once for the messages waiting): for callbacks that may wait on a lock their node holds long
  (a controller's, during its solve), which must not hold up the publisher (the simulators' loop). Other processes still see every topic: a publication goes to rospy as
  well when a subscriber outside the host listens (or the topic is latched), and each local subscription also subscribes
  through rospy for publishers outside the host (its copies of the host's own publications are dropped by
  the publisher's caller id).

A delivered message is shared by every local subscriber, as with roscpp's nodelets: callbacks read it and
do not change it. Its ``_connection_header`` names the publishing instance as 'callerid', as rospy's
received messages name the publishing node.

Log lines: a node class logs through its context (``ctx.logwarn(text, *args)``, ``ctx.logwarn_throttle(period,
text, *args)``: rospy's arguments). The process's node: rospy's own functions, same text, rospy's throttle (per
line of code, ROS time); /rosout names the node. Hosted: /rosout names the host, so the text starts with the
instance's name in square brackets ('[/anafi3/interface] interface: ...'), and a throttled line passes at most
once per ``period`` s of monotonic wall time per (instance, call site): one drone's warning never hides
another's (the first line of each always passes).
"""
import collections
import sys
import threading
import time

import rosgraph.names
import rospy
import tf2_ros
from tf2_msgs.msg import TFMessage

from anafi_sim.ros.params import ParamReader


class NodeContext(object):
    """A node instance: ``name`` (global, e.g. /anafi1/interface), ``bus`` (a LocalBus: hosted; None: the
    process's own node)."""

    def __init__(self, name, bus=None):
        self.name = rosgraph.names.canonicalize_name(name)
        self.namespace = rosgraph.names.namespace(self.name)
        self.bus = bus
        self.wiring = {'publishes': [], 'subscribes': [], 'services': []}   # global names, in creation order
        self._log_lock = threading.Lock()
        self._last_logged = {}     # hosted: call site -> time.monotonic() [s] of the last throttled line it logged

    @classmethod
    def process(cls):
        """The process's own node (after rospy.init_node)."""
        return cls(rospy.get_name())

    @property
    def hosted(self):
        return self.bus is not None

    @property
    def namespace_id(self):
        """The namespace without its slashes, 'anafi' at the root (hardware ids, default drone names)."""
        return self.namespace.strip('/') or 'anafi'

    def resolve(self, name):
        """A global name: ~x -> <name>/x, relative -> <namespace>/x (the process's node: rospy's resolution)."""
        if self.bus is None:
            return rospy.resolve_name(name)
        return rosgraph.names.resolve_name(name, self.name)

    # ------------------------------------------------------------------ log lines
    def logdebug(self, text, *args):
        self._log('logdebug', text, args)

    def loginfo(self, text, *args):
        self._log('loginfo', text, args)

    def logwarn(self, text, *args):
        self._log('logwarn', text, args)

    def logerr(self, text, *args):
        self._log('logerr', text, args)

    def logfatal(self, text, *args):
        self._log('logfatal', text, args)

    # rospy keys its throttle by the frame that called its log function's caller: the process's node calls
    # rospy.core._base_logger (what rospy.log*_throttle call) from here, so the key is the caller's line, as if
    # it had called rospy.log*_throttle itself.
    def loginfo_throttle(self, period, text, *args):
        """At most one line per ``period`` [s] from the calling line (hosted: per instance and calling line)."""
        if self.bus is None:
            rospy.core._base_logger(text, args, {}, throttle=period, level='info')
        else:
            self._throttled('loginfo', period, text, args)

    def logwarn_throttle(self, period, text, *args):
        """At most one line per ``period`` [s] from the calling line (hosted: per instance and calling line)."""
        if self.bus is None:
            rospy.core._base_logger(text, args, {}, throttle=period, level='warning')
        else:
            self._throttled('logwarn', period, text, args)

    def logerr_throttle(self, period, text, *args):
        """At most one line per ``period`` [s] from the calling line (hosted: per instance and calling line)."""
        if self.bus is None:
            rospy.core._base_logger(text, args, {}, throttle=period, level='error')
        else:
            self._throttled('logerr', period, text, args)

    def _log(self, level, text, args):
        if self.bus is None:
            getattr(rospy, level)(text, *args)
        else:
            getattr(rospy, level)('[%s] %s' % (self.name, text), *args)

    def _throttled(self, level, period, text, args):
        """Hosted: the line, unless the same call site (the caller of the log*_throttle method) of this instance
        logged one less than ``period`` s ago (monotonic wall clock)."""
        caller = sys._getframe(2)
        site = (caller.f_code, caller.f_lasti)       # the calling code and the call's instruction in it
        now = time.monotonic()
        with self._log_lock:
            last = self._last_logged.get(site)
            if last is not None and now - last < period:
                return
            self._last_logged[site] = now
        getattr(rospy, level)('[%s] %s' % (self.name, text), *args)

    # ------------------------------------------------------------------ parameters
    def private(self, name):
        """The global name of the private parameter ``name``."""
        return rosgraph.names.ns_join(self.name, name)

    def params(self):
        """A ParamReader over the instance's private parameters."""
        return ParamReader(lambda name, default: rospy.get_param(self.private(name), default))

    def get_param(self, name, default=None):
        """A private parameter's raw value (``default`` when unset)."""
        return rospy.get_param(self.private(name), default)

    def has_param(self, name):
        return rospy.has_param(self.private(name))

    def set_param(self, name, value):
        rospy.set_param(self.private(name), value)

    # ------------------------------------------------------------------ topics and services
    def publisher(self, name, data_class, **kwargs):
        """rospy.Publisher's arguments; hosted: a LocalPublisher on the host's bus."""
        self.wiring['publishes'].append(self.resolve(name))
        if self.bus is None:
            return rospy.Publisher(name, data_class, **kwargs)
        return self.bus.publisher(self.resolve(name), data_class, owner=self.name, **kwargs)

    def subscriber(self, name, data_class, callback, deferred=False, **kwargs):
        """rospy.Subscriber's arguments; hosted: a subscription on the host's bus (and through rospy).
        ``deferred``: hosted, the callback runs on the host's delivery thread, not the publisher's (for a
        callback that may wait on a lock its node holds long, e.g. a controller's during its solve)."""
        self.wiring['subscribes'].append(self.resolve(name))
        if self.bus is None:
            return rospy.Subscriber(name, data_class, callback, **kwargs)
        return self.bus.subscriber(self.resolve(name), data_class, callback, deferred=deferred, **kwargs)

    def record(self, role, *names):
        """Global ``names`` this instance uses that were made without the context ('publishes', 'subscribes' or
        'services'; e.g. a dynamic_reconfigure server's own topics)."""
        self.wiring[role].extend(names)

    def service(self, name, service_class, handler):
        self.wiring['services'].append(self.resolve(name))
        return rospy.Service(self.resolve(name), service_class, handler)

    def send_static_transforms(self, transforms):
        """Static transforms on /tf_static (hosted: the union of every instance's, one latched message)."""
        if self.bus is None:
            tf2_ros.StaticTransformBroadcaster().sendTransform(transforms)
        else:
            self.bus.send_static_transforms(transforms)


class LocalPublisher(object):
    """A publisher of a host: local subscribers get the message in the process; rospy gets it when another
    process listens (or the topic is latched)."""

    def __init__(self, bus, topic, pub, latch, owner):
        self.bus = bus
        self.header = {'callerid': owner, 'topic': topic}
        self.topic = topic
        self.pub = pub
        self.latch = latch
        self.name = topic
        self.resolved_name = topic
        self._counted = (None, 0, 0)     # (rospy's connection list, its length, external subscribers in it)

    def external_connections(self):
        """Subscribers of this topic outside the host (rospy's connections, less the host's own); counted again
        only when rospy's list changed (rospy replaces the list on every change, or empties it in place)."""
        connections = self.pub.impl.connections
        listed, length, count = self._counted
        if listed is connections and length == len(connections):
            return count
        own = self.bus.caller_id
        count = sum(1 for c in list(connections) if getattr(c, 'endpoint_id', None) != own)
        self._counted = (connections, len(connections), count)
        return count

    def get_num_connections(self):
        return self.external_connections() + len(self.bus.local_callbacks(self.topic))

    def publish(self, msg):
        msg._connection_header = self.header    # as rospy marks a received message: who published it
        self.bus.deliver(self.topic, msg, self.latch)
        if self.latch or self.external_connections():
            self.pub.publish(msg)

    def unregister(self):
        self.pub.unregister()


class LocalSubscription(object):
    """A subscription of a host: its local callback and its rospy subscriber (publishers elsewhere)."""

    def __init__(self, bus, topic, entry, sub):
        self.bus = bus
        self.topic = topic
        self.entry = entry
        self.sub = sub
        self.name = topic
        self.resolved_name = topic

    def get_num_connections(self):
        return self.sub.get_num_connections()

    def unregister(self):
        self.bus.remove(self.topic, self.entry)
        self.sub.unregister()


class LocalBus(object):
    """In-process delivery between the instances of one host process (``caller_id``: the host's node name,
    which the copies of its own publications that come back through rospy carry)."""

    def __init__(self, caller_id, on_error=None):
        self.caller_id = caller_id
        self.on_error = on_error           # (topic, exception) of a failing callback; None: log
        self._lock = threading.Lock()
        self._subscribers = {}             # topic -> tuple of callbacks
        self._latched = {}                 # topic -> last message of a latched publisher
        self._queue = collections.deque()     # (topic, deferred entries, message) for the delivery thread
        self._ready = threading.Condition(threading.Lock())
        self._thread = None
        self._static = collections.OrderedDict()    # (parent, child) -> TransformStamped
        self._static_pub = None
        self.delivered = 0
        self.callback_errors = 0
        self._shared = {}

    def shared(self, key, make):
        """The host's one object for ``key``, made by ``make()`` for the first instance that asks (e.g. one
        world check for every mirror of the host)."""
        with self._lock:
            if key not in self._shared:
                self._shared[key] = make()
            return self._shared[key]

    def publisher(self, topic, data_class, latch=False, owner=None, **kwargs):
        """A LocalPublisher of ``topic``; ``owner``: the publishing instance's name (the callerid local
        subscribers see in the message's ``_connection_header``; default the host's)."""
        pub = rospy.Publisher(topic, data_class, latch=latch, **kwargs)
        return LocalPublisher(self, topic, pub, latch, owner or self.caller_id)

    def subscriber(self, topic, data_class, callback, deferred=False, **kwargs):
        """A local subscription of ``topic`` (``deferred``: called on the delivery thread) and its rospy
        subscriber for publishers elsewhere."""
        entry = [callback, bool(deferred)]   # a list: identity for removal even when a callback is added twice
        if deferred:
            self._start_delivery()
        with self._lock:
            self._subscribers[topic] = self._subscribers.get(topic, ()) + (entry,)
            latched = self._latched.get(topic)
        if latched is not None:      # a latched topic: its last message, as rospy gives a late subscriber
            if deferred:
                with self._ready:
                    self._queue.append((topic, (entry,), latched))
                    self._ready.notify()
            else:
                self._call(topic, (entry,), latched)
        own = self.caller_id
        holder = []

        def from_elsewhere(msg):
            # the host's own publications arrived locally already: known by the publisher URI of the message's
            # connection (the master's publisher list), the header's callerid only when the connection is unknown
            header = getattr(msg, '_connection_header', None) or {}
            impl = getattr(holder[0], 'impl', None) if holder else None
            endpoint = next((getattr(c, 'endpoint_id', None) for c in getattr(impl, 'connections', ())
                             if c.header is header), None)
            mine = endpoint == rospy.get_node_uri() if endpoint not in (None, 'unknown') else \
                header.get('callerid') == own
            if not mine:
                callback(msg)
        sub = rospy.Subscriber(topic, data_class, from_elsewhere, **kwargs)
        holder.append(sub)
        return LocalSubscription(self, topic, entry, sub)

    def remove(self, topic, entry):
        with self._lock:
            self._subscribers[topic] = tuple(e for e in self._subscribers.get(topic, ()) if e is not entry)

    def local_callbacks(self, topic):
        return self._subscribers.get(topic, ())

    def deliver(self, topic, msg, latch=False):
        """Hand ``msg`` to the local subscribers of ``topic``, in the publishing thread (no thread to wake: a
        wake-up costs as much as a rospy hop's serialisation many times over)."""
        if latch:
            with self._lock:
                self._latched[topic] = msg
        entries = self._subscribers.get(topic)
        if not entries:
            return
        self.delivered += 1
        later = tuple(e for e in entries if e[1])
        self._call(topic, [e for e in entries if not e[1]] if later else entries, msg)
        if later:
            with self._ready:
                self._queue.append((topic, later, msg))
                self._ready.notify()

    def _call(self, topic, entries, msg):
        """Each callback of ``entries`` with ``msg``, guarded: one instance's failing callback is counted and
        logged, the others still get the message."""
        for entry in entries:
            try:
                entry[0](msg)
            except Exception as error:
                self.callback_errors += 1
                if self.on_error is not None:
                    self.on_error(topic, error)
                else:
                    rospy.logerr_throttle(5.0, 'host: a callback of %s failed (%d so far): %s: %s' % (
                        topic, self.callback_errors, type(error).__name__, error))

    def _start_delivery(self):
        with self._lock:
            if self._thread is not None:
                return
            self._thread = threading.Thread(target=self._deliver_deferred, name='local_bus', daemon=True)
        self._thread.start()

    def _deliver_deferred(self):
        """The delivery thread: deferred callbacks in publication order (woken once for what is waiting)."""
        queue = self._queue
        while True:
            with self._ready:
                while not queue:
                    self._ready.wait()
                batch = list(queue)
                queue.clear()
            for topic, entries, msg in batch:
                self._call(topic, entries, msg)

    def pending(self):
        """Deferred deliveries waiting for the delivery thread."""
        return len(self._queue)

    def send_static_transforms(self, transforms):
        """Add ``transforms`` to the host's static transforms and publish them all (one latched message)."""
        with self._lock:
            for t in transforms:
                self._static[(t.header.frame_id, t.child_frame_id)] = t
            if self._static_pub is None:
                self._static_pub = rospy.Publisher('/tf_static', TFMessage, queue_size=100, latch=True)
            msg = TFMessage(transforms=list(self._static.values()))
        self._static_pub.publish(msg)
