"""Keeping models spawned in a Gazebo world that may go away and come back (pure, no ROS).

Stage: mirror / scene actors -> **Gazebo's spawn API** (or the kinematic stand-in world).

``SpawnTracker`` is the bookkeeping: which models are in the world, when to (re)spawn, world restarts
(service endpoint changed, models missing from /gazebo/model_states). ``SpawnDriver`` runs it against one
world through calls the node hands in (spawn service contact and URI lookup, spawn, delete) and holds the
world-loss rule, so the Gazebo mirror and the airship node share it:

- the spawn service is contacted first and its URI looked up after: the other order can return the URI of
  a world that was killed without unregistering while the contact already reaches its successor, and the
  next check would take that successor for one more restart (a double respawn);
- a lost world is confirmed by a second check before the models count as gone (one missed check of a busy
  world is not a loss);
- spawn and delete calls run with time limits, so a world that hangs cannot stop the node.

Times are seconds on one monotonic clock (``clock``, default ``time.monotonic``).
"""
import threading
import time

INFO, WARN, ERROR = 'info', 'warn', 'error'
"""Levels of the log lines ``SpawnDriver`` returns (the node logs them)."""


class SpawnTracker(object):
    """Spawn bookkeeping of a set of models against one world (Gazebo or the stand-in).

    States per model: 'absent' (to spawn), 'delete' (exists from an earlier run: delete, then spawn),
    'spawned'. ``retry_period`` [s] between attempts per model; ``missing_grace`` [s] after a spawn before
    a model missing from /gazebo/model_states counts as gone. Times in seconds on any monotonic clock.
    """

    def __init__(self, names, retry_period=1.0, missing_grace=1.0):
        if not retry_period > 0 or not missing_grace >= 0:
            raise ValueError('retry_period must be > 0 and missing_grace >= 0')
        self.names = tuple(names)
        self.retry_period = float(retry_period)
        self.missing_grace = float(missing_grace)
        self.state = dict((n, 'absent') for n in self.names)
        self._next_attempt = dict((n, None) for n in self.names)
        self._spawned_at = dict((n, None) for n in self.names)
        self.world_available = False
        self.world_id = None
        self.world_seen = False      # a world was available at least once
        self.spawns = 0              # successful spawns (first ones and respawns)
        self.respawns = 0            # successful spawns after the first one of a model
        self.spawn_failures = 0
        self.world_losses = 0        # world went away while models were spawned
        self.world_restarts = 0      # world endpoint changed
        self.models_missing = 0      # spawned models found missing in model_states
        self.last_error = ''
        self._ever_spawned = set()

    def _forget(self, now):
        for n in self.names:
            if self.state[n] == 'spawned':
                self.state[n] = 'absent'
            self._next_attempt[n] = now

    def on_world(self, available, world_id, now):
        """Report the world's spawn service: ``available`` bool, ``world_id`` (e.g. the service URI)."""
        if not available:
            if self.world_available and any(s == 'spawned' for s in self.state.values()):
                self.world_losses += 1
            if self.world_available:
                self._forget(now)
            self.world_available = False
            return
        if self.world_id is not None and world_id != self.world_id:
            self.world_restarts += 1
            self._forget(now)
        self.world_id = world_id
        self.world_available = True
        self.world_seen = True

    def on_model_states(self, names, now):
        """Names listed by /gazebo/model_states; spawned models missing past the grace period -> respawn."""
        present = set(names)
        for n in self.names:
            if self.state[n] != 'spawned':
                continue
            if n not in present and now - self._spawned_at[n] >= self.missing_grace:
                self.state[n] = 'absent'
                self._next_attempt[n] = now
                self.models_missing += 1

    def due_actions(self, now):
        """[(action, name)] to do now: action 'spawn' or 'delete' (only while the world is available)."""
        if not self.world_available:
            return []
        actions = []
        for n in self.names:
            due = self._next_attempt[n]
            if due is not None and now < due:
                continue
            if self.state[n] == 'absent':
                actions.append(('spawn', n))
            elif self.state[n] == 'delete':
                actions.append(('delete', n))
        return actions

    def on_spawn_result(self, name, success, message, now):
        """Result of a spawn call (``message``: the world's status message or the exception text)."""
        if success:
            self.state[name] = 'spawned'
            self._spawned_at[name] = now
            self.spawns += 1
            if name in self._ever_spawned:
                self.respawns += 1
            self._ever_spawned.add(name)
            return
        self.spawn_failures += 1
        self.last_error = '%s: %s' % (name, message)
        if 'exist' in str(message).lower():  # left over from an earlier run: replace it with ours
            self.state[name] = 'delete'
            self._next_attempt[name] = now
        else:
            self._next_attempt[name] = now + self.retry_period

    def on_delete_result(self, name, success, message, now):
        """Result of a delete call made for a 'delete' model (absent afterwards either way; spawn next)."""
        if not success:
            self.last_error = '%s: delete failed: %s' % (name, message)
        self.state[name] = 'absent'
        self._next_attempt[name] = now if success else now + self.retry_period

    def is_spawned(self, name):
        return self.state.get(name) == 'spawned'

    @property
    def all_spawned(self):
        return all(s == 'spawned' for s in self.state.values())

    def spawned_names(self):
        return [n for n in self.names if self.state[n] == 'spawned']


def call_with_timeout(function, timeout):
    """Run ``function()`` in a daemon thread: (True, its result) or (False, error text), also on timeout."""
    box = {}

    def run():
        try:
            box['result'] = function()
        except Exception as error:  # service exceptions, shutdown, ...
            box['error'] = '%s: %s' % (type(error).__name__, error)

    thread = threading.Thread(target=run)
    thread.daemon = True
    thread.start()
    thread.join(timeout)
    if thread.is_alive():
        return False, 'no answer within %.1f s' % timeout
    if 'error' in box:
        return False, box['error']
    return True, box['result']


class SharedCheck(object):
    """One world check for the drivers of one process (a fleet host's mirrors): ``check()`` (e.g. the first
    driver's ``probe``) runs at most once per ``max_age`` s; a caller in between gets its last answer, a caller
    during it waits for it."""

    def __init__(self, check, max_age, clock=time.monotonic):
        if not max_age > 0:
            raise ValueError('max_age must be > 0, got %r' % (max_age,))
        self._check = check
        self.max_age = float(max_age)
        self._clock = clock
        self._lock = threading.Lock()
        self._at = None
        self._answer = None
        self.checks = 0

    def __call__(self):
        with self._lock:
            if self._at is None or self._clock() - self._at >= self.max_age:
                self._answer = self._check()
                self._at = self._clock()
                self.checks += 1
            return self._answer


class SpawnDriver(object):
    """Keeps the models of a ``SpawnTracker`` in one world; the calls come from the node (no ROS here).

    - ``contact(timeout)``: returns when the spawn service answers; raises (or returns False) when it does
      not within ``timeout`` s (rospy.wait_for_service);
    - ``lookup()``: the spawn service's URI (the world's identity), None or an exception when unknown;
    - ``spawn(name)``, ``delete(name)``: ``(success, message)``; an exception or no answer within
      ``spawn_timeout`` / ``delete_timeout`` s is a failure with that text.

    ``poll(now)`` (call it often) checks the world every ``check_period`` s while it is available and every
    ``tracker.retry_period`` s while it is not, then makes the due calls; every method returns the log lines
    ``[(level, text)]`` (levels INFO, WARN, ERROR; text prefixed with ``label``) for the node to log.
    ``lock`` guards the tracker (share it with the code feeding ``on_model_states``).
    """

    def __init__(self, tracker, contact, lookup, spawn, delete, service='/gazebo/spawn_urdf_model',
                 label='mirror', check_period=0.5, contact_timeout=0.5, spawn_timeout=30.0,
                 delete_timeout=5.0, absent_log_period=5.0, lock=None, clock=time.monotonic):
        if not min(check_period, contact_timeout, spawn_timeout, delete_timeout, absent_log_period) > 0:
            raise ValueError('periods and timeouts must be > 0, got %r' % (
                (check_period, contact_timeout, spawn_timeout, delete_timeout, absent_log_period),))
        self.tracker = tracker
        self._contact, self._lookup, self._spawn, self._delete = contact, lookup, spawn, delete
        self.service = service
        self.label = label
        self.check_period = float(check_period)
        self.contact_timeout = float(contact_timeout)
        self.spawn_timeout = float(spawn_timeout)
        self.delete_timeout = float(delete_timeout)
        self.absent_log_period = float(absent_log_period)
        self.lock = lock if lock is not None else threading.Lock()
        self._clock = clock
        self.shared_check = None      # a SharedCheck of several drivers in one process (None: own checks)
        self.missed_checks = 0        # checks that found the world gone, not (yet) confirmed
        self._missed = False
        self._next_check = None
        self._last_absent_log = None

    def _say(self, level, text, *args):
        return level, ('%s: ' + text) % ((self.label,) + args)

    # ------------------------------------------------------------------ inputs
    def on_model_states(self, names, now):
        """Names in /gazebo/model_states (see ``SpawnTracker.on_model_states``)."""
        with self.lock:
            self.tracker.on_model_states(names, now)

    # ------------------------------------------------------------------ the world
    def endpoint(self):
        """URI of the reachable spawn service, or None (contacted first, looked up after: see module doc);
        through ``shared_check`` when one is set."""
        if self.shared_check is not None:
            return self.shared_check()
        return self.probe()

    def probe(self):
        """Contact the spawn service, then look up its URI: the URI, or None."""
        try:
            if self._contact(self.contact_timeout) is False:
                return None
        except Exception:  # not registered, or registered but dead (killed without unregistering)
            return None
        try:
            return self._lookup()
        except Exception:  # no provider, master unreachable, ...
            return None

    def check_world(self):
        """One world check (the world-loss rule); returns log lines."""
        uri = self.endpoint()
        now = self._clock()
        with self.lock:
            was = self.tracker.world_available
            if uri is None and was and not self._missed:
                self._missed = True   # one missed check of a busy world is not a loss: confirm it next time
                self.missed_checks += 1
                return []
            self._missed = False
            restarts = self.tracker.world_restarts
            self.tracker.on_world(uri is not None, uri, now)
            restarted = self.tracker.world_restarts > restarts
        if uri is None:
            if was:
                self._last_absent_log = now
                return [self._say(ERROR, 'Gazebo went away (%s no longer reachable); will respawn the models '
                                         'when it is back', self.service)]
            if self._last_absent_log is None or now - self._last_absent_log >= self.absent_log_period:
                self._last_absent_log = now
                return [self._say(ERROR, 'Gazebo not available: service %s does not exist or does not answer. '
                                         'Start Gazebo (gazebo_ros) or the kinematic world (roslaunch anafi_sim '
                                         'world.launch); retrying every %.1f s', self.service,
                                  self.tracker.retry_period)]
            return []
        if restarted:
            return [self._say(WARN, 'Gazebo restarted (%s now at %s); respawning', self.service, uri)]
        if not was:
            return [self._say(INFO, 'Gazebo available at %s', uri)]
        return []

    # ------------------------------------------------------------------ calls
    def _call(self, function, name, timeout):
        ok, result = call_with_timeout(lambda: function(name), timeout)
        if not ok:
            return False, result
        success, message = result
        return bool(success), message

    def do_actions(self):
        """The spawn / delete calls due now; returns log lines."""
        with self.lock:
            actions = self.tracker.due_actions(self._clock())
        logs = []
        for action, name in actions:
            if action == 'delete':
                success, message = self._call(self._delete, name, self.delete_timeout)
                with self.lock:
                    self.tracker.on_delete_result(name, success, message, self._clock())
                logs.append(self._say(INFO, 'deleted the existing model %s before spawning ours (%s)', name,
                                      message))
                continue
            success, message = self._call(self._spawn, name, self.spawn_timeout)
            with self.lock:
                before = self.tracker.respawns
                self.tracker.on_spawn_result(name, success, message, self._clock())
                respawn = self.tracker.respawns > before
            if success:
                logs.append(self._say(INFO, '%s %s (%s)', 'respawned' if respawn else 'spawned', name, message))
            else:
                logs.append(self._say(WARN, 'spawning %s failed: %s; retrying', name, message))
        return logs

    def poll(self, now=None):
        """World check and calls when a check is due at ``now`` (default: the clock); returns log lines."""
        now = self._clock() if now is None else now
        if self._next_check is not None and now < self._next_check:
            return []
        logs = self.check_world() + self.do_actions()
        with self.lock:
            available = self.tracker.world_available
        self._next_check = self._clock() + (self.check_period if available else self.tracker.retry_period)
        return logs

    def delete_all(self, timeout=2.0):
        """Delete every spawned model (on shutdown), each call limited to ``timeout`` s; returns log lines."""
        with self.lock:
            names = self.tracker.spawned_names()
        logs = []
        for name in names:
            success, message = self._call(self._delete, name, timeout)
            if success:
                logs.append(self._say(INFO, 'deleted %s', name))
            else:
                logs.append(self._say(WARN, 'could not delete %s on shutdown: %s', name, message))
        return logs
