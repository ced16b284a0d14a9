"""The pre-flight check before a controller flies a real drone (pure core, no rospy).

Stage: bridge state + scenario -> go / wait. ``real_anafi.launch`` starts the scenario (and so gives the
controller its first waypoint: until then it has none and sends no command) only when

- the state is fresh: a drone/odom sample (from bridge_state.py) within ``state_timeout`` [s];
- the drone flies: drone/state is 'flying' (the bridge's flying state; take off with the bridge or the
  remote first);
- the first waypoint is within reach: at most ``max_reach`` [m] from the drone's position.

``state_from`` (text) names where drone/odom comes from (the bridge topics), in the waiting line.
``check(now)`` returns (ready, waiting): the list of what is still missing, one clause each, for the one
line the node logs while it waits.
"""
import collections
import math

DEFAULTS = collections.OrderedDict([
    ('max_reach', 5.0),        # [m] largest distance of the first waypoint from the drone
    ('state_timeout', 0.5),    # [s] oldest state that counts as fresh (the controllers' state_timeout)
])

FLYING = 'flying'


class PreflightCheck(object):
    """Go / wait for a first waypoint (x, y, z) [m], world ENU."""

    def __init__(self, first_waypoint, max_reach=DEFAULTS['max_reach'], state_timeout=DEFAULTS['state_timeout'],
                 state_from=''):
        for name, value in (('max_reach', max_reach), ('state_timeout', state_timeout)):
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0.0):
                raise ValueError('%s must be a finite number > 0, got %r' % (name, value))
        try:
            self.first = tuple(float(v) for v in first_waypoint)
        except (TypeError, ValueError):
            raise ValueError('first waypoint must be 3 numbers, got %r' % (first_waypoint,))
        if len(self.first) != 3 or not all(math.isfinite(v) for v in self.first):
            raise ValueError('first waypoint must be 3 finite numbers, got %r' % (first_waypoint,))
        self.state_from = str(state_from)   # where drone/odom comes from, named while it is missing
        self.max_reach = float(max_reach)
        self.state_timeout = float(state_timeout)
        self.state_time = None
        self.position = None
        self.drone_state = None
        self.bad_states = 0

    def on_state(self, now, position):
        """A state sample (position x, y, z [m]) received at ``now`` [s]; False if unusable (counted)."""
        try:
            p = tuple(float(v) for v in position)
        except (TypeError, ValueError):
            p = ()
        if len(p) != 3 or not all(math.isfinite(v) for v in p) or not math.isfinite(now):
            self.bad_states += 1
            return False
        self.state_time, self.position = float(now), p
        return True

    def on_drone_state(self, text):
        self.drone_state = str(text)

    def distance(self):
        """Distance [m] of the first waypoint from the last position, None before a state."""
        if self.position is None:
            return None
        return math.sqrt(sum((a - b) ** 2 for a, b in zip(self.first, self.position)))

    def check(self, now):
        waiting = []
        if self.state_time is None:
            waiting.append('a state on drone/odom (none yet%s)' % (
                '; from %s' % self.state_from if self.state_from else ''))
        elif now - self.state_time > self.state_timeout:
            waiting.append('a fresh state on drone/odom (last %.1f s ago%s)' % (
                now - self.state_time, '; from %s' % self.state_from if self.state_from else ''))
        if self.drone_state != FLYING:
            waiting.append('drone/state %s (now %s)' % (FLYING, self.drone_state or 'not heard'))
        d = self.distance()
        if d is not None and d > self.max_reach:
            waiting.append('the first waypoint (%.2f, %.2f, %.2f) within %.1f m (now %.1f m away)'
                           % (self.first + (self.max_reach, d)))
        elif d is None:
            waiting.append('the drone within %.1f m of the first waypoint (%.2f, %.2f, %.2f)'
                           % ((self.max_reach,) + self.first))
        return not waiting, waiting
