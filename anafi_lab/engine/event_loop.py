"""Virtual time for the in-process engine: one event queue and the ROS mechanics a graph's timing rests on
(pure, no ROS).

Stage: experiments (the clockwork under ``anafi_lab.engine.engine``). Times are integer nanoseconds of
simulation time (as rospy.Time / rospy.Duration hold them), so periods such as 1/30 s add up exactly as in
the nodes and two runs order their events identically.

- ``EventLoop``: callbacks at simulation times; events at the same time run by ``order`` (``ACTION``
  first, then ``PHYSICS``: the simulator's step publishes /clock before anything at that instant looks at
  the clock, then ``DELIVERY`` of messages, then ``TIMER`` callbacks), then first come, first served;
- ``NodeClock``: what ``rospy.get_time()`` returns in a node under /use_sim_time: the newest /clock value
  it has received. /clock comes after every physics step (a grid of ``period``) and reaches the node
  ``latency`` later;
- ``Timer``: ``rospy.Timer`` / ``rospy.Rate`` on simulation time: due at ``start + k period`` (the Rate
  adds its period to the previous due time, not to the time it woke up), the callback runs as soon as
  the node's clock reaches the due time, i.e. on the first /clock tick at or after it, and reads that
  tick as "now";
- ``Topic``: a publisher's message reaches each subscriber's callback ``delay`` later (one TCPROS hop);
  a subscriber with delay None is called at once (a recorder: it stores stamps, its timing changes
  nothing). ``publish(msg, extra)`` adds the publisher's own latency (e.g. the time a solve takes after
  the cycle read the clock).

Nothing here sleeps or reads a wall clock: the loop runs as fast as the callbacks allow.
"""
import heapq
import itertools

NS = 1000000000
"""Nanoseconds per second."""

ACTION, PHYSICS, DELIVERY, TIMER = -1, 0, 1, 2
"""Orders of events at the same simulation time: an action on the simulated world (it changes the state the
step of that instant starts from), the physics step (publishes /clock), message deliveries, timer callbacks."""


def to_ns(seconds):
    """Seconds (float) -> integer nanoseconds (rounded to the nearest)."""
    return int(round(float(seconds) * NS))


def to_s(ns):
    """Integer nanoseconds -> seconds, as rospy.Time.to_sec() computes it (secs + nsecs / 1e9)."""
    secs, nsecs = divmod(int(ns), NS)
    return secs + nsecs / 1e9


class EventLoop(object):
    """A queue of callbacks at simulation times [ns]; ``run`` executes them in time order."""

    def __init__(self):
        self.now = 0
        self.events = 0           # callbacks run so far
        self._queue = []
        self._seq = itertools.count()
        self._stopped = False

    def at(self, t, callback, *args, order=DELIVERY):
        """Run ``callback(*args)`` at time ``t`` [ns] (>= now); keyword ``order`` (default DELIVERY)."""
        t = int(t)
        if t < self.now:
            raise ValueError('cannot schedule at %d ns, before now (%d ns)' % (t, self.now))
        heapq.heappush(self._queue, (t, order, next(self._seq), callback, args))

    def after(self, delay, callback, *args, order=DELIVERY):
        """Run ``callback(*args)`` ``delay`` ns from now."""
        self.at(self.now + int(delay), callback, *args, order=order)

    def stop(self):
        """End ``run`` after the current callback."""
        self._stopped = True

    @property
    def pending(self):
        """Number of queued events."""
        return len(self._queue)

    def next_time(self):
        """Time [ns] of the next event, None when the queue is empty."""
        return self._queue[0][0] if self._queue else None

    def run(self, until=None):
        """Run events in order until the queue is empty, ``stop()`` was called, or the next event lies after
        ``until`` [ns] (then now = until). Returns True when stopped."""
        queue = self._queue
        pop = heapq.heappop
        self._stopped = False
        while queue:
            if until is not None and queue[0][0] > until:
                self.now = max(self.now, int(until))
                return False
            t, _, _, callback, args = pop(queue)
            self.now = t
            self.events += 1
            callback(*args)
            if self._stopped:
                return True
        if until is not None:
            self.now = max(self.now, int(until))
        return False


class NodeClock(object):
    """A node's ROS time under /use_sim_time: the newest /clock tick (a grid of ``period`` ns from 0) that
    arrived by now, /clock taking ``latency`` ns to arrive."""

    def __init__(self, loop, period, latency=0):
        if int(period) <= 0 or int(latency) < 0:
            raise ValueError('need period > 0 and latency >= 0 [ns], got %r, %r' % (period, latency))
        self.loop = loop
        self.period = int(period)
        self.latency = int(latency)

    def now(self):
        """The node's time [ns] (0 before the first tick arrived)."""
        t = self.loop.now - self.latency
        return t - t % self.period if t > 0 else 0

    def now_s(self):
        """The node's time [s], as rospy.get_time()."""
        return to_s(self.now())

    def reaches(self, t):
        """Event time [ns] at which the node's clock first reads >= ``t`` [ns]."""
        period = self.period
        tick = -(-int(t) // period) * period      # first tick at or after t
        return tick + self.latency


class Timer(object):
    """rospy.Timer / rospy.Rate on a ``NodeClock``: ``callback(now_ns)`` for due times start + k * period,
    k = ``first``, first + 1, ... (rospy.Timer: first = 1; a ``while: work; rate.sleep()`` loop: first = 0);
    each runs when the node's clock reaches its due time. ``cancel()`` stops it."""

    def __init__(self, loop, clock, period, callback, start=0, first=1, order=TIMER):
        if int(period) <= 0:
            raise ValueError('timer period must be > 0 ns, got %r' % (period,))
        self.loop, self.clock, self.callback = loop, clock, callback
        self.period = int(period)
        self.order = order
        self.due = int(start) + int(first) * self.period
        self.fired = 0
        self.cancelled = False
        loop.at(max(loop.now, clock.reaches(self.due)), self._fire, order=order)

    def cancel(self):
        self.cancelled = True

    def _fire(self):
        if self.cancelled:
            return
        self.fired += 1
        self.callback(self.clock.now())
        self.due += self.period
        if not self.cancelled:
            self.loop.at(max(self.loop.now, self.clock.reaches(self.due)), self._fire, order=self.order)


class Topic(object):
    """A topic: ``publish(msg)`` hands ``msg`` to every subscriber, each after its own transport delay [ns]
    (None: called synchronously, for recorders whose timing does not matter)."""

    def __init__(self, loop, name=''):
        self.loop = loop
        self.name = name
        self.subscribers = []
        self.published = 0

    def subscribe(self, callback, delay=None):
        """``callback(msg)`` for every message, ``delay`` ns after its publication (None: at once)."""
        self.subscribers.append((callback, None if delay is None else int(delay)))

    def publish(self, msg, extra=0):
        """Publish ``msg`` now; it leaves the publisher ``extra`` ns later (the publisher's own latency)."""
        self.published += 1
        loop = self.loop
        for callback, delay in self.subscribers:
            if delay is None:
                callback(msg)
            else:           # loop.at(now + delay + extra, callback, msg, order=DELIVERY), without its checks
                t = loop.now + delay + int(extra)
                if t < loop.now:
                    raise ValueError('cannot schedule at %d ns, before now (%d ns)' % (t, loop.now))
                heapq.heappush(loop._queue, (t, DELIVERY, next(loop._seq), callback, (msg,)))
