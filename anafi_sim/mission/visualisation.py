"""What rviz shows of a drone (pure core of visualisation_node.py): the flown trail, the reference (waypoint
stream), the controller's predicted path and the current waypoint, as plain marker specifications.

Positions are world ENU [m], times [s] (ROS time: simulation time under /use_sim_time). ``Trail`` keeps a
bounded, thinned history of positions; ``markers`` turns a drone's trails, predicted path and waypoint into
``MarkerSpec`` tuples (one per rviz marker, namespace ``<drone>/<kind>``) that the node converts into a
visualization_msgs/MarkerArray, so ONE rviz display shows every drone of a fleet. The colours live here
(``COLOURS``): anafi_sim/config/anafi.rviz and the rviz screenshot test look for them.
"""
import collections
import math

#: RGBA in 0..1 per kind of marker (distinct hues on rviz's light background of anafi.rviz)
COLOURS = {
    'trail': (0.0, 0.55, 0.0, 1.0),        # flown positions (ground truth): green
    'reference': (0.0, 0.45, 1.0, 1.0),    # the waypoints received: blue
    'predicted': (1.0, 0.0, 1.0, 1.0),     # the controller's predicted path: magenta
    'waypoint': (1.0, 0.5, 0.0, 1.0),      # the current waypoint: orange sphere + yaw arrow (tf x axes: red)
}
#: defaults of the node's parameters (anafi_sim/config/visualisation.yaml must agree: unit-tested)
DEFAULTS = {
    'rate': 5.0,              # Hz of marker updates
    'trail_spacing': 0.02,    # m between kept trail points
    'trail_length': 60.0,     # s of history kept (trail and reference)
    'max_points': 5000,       # per trail
    'line_width': 0.04,       # m
    'waypoint_size': 0.12,    # m, sphere diameter
}

MarkerSpec = collections.namedtuple('MarkerSpec', 'ns id kind points colour scale')
"""ns: '<drone>/<kind>'; kind: 'line' (points = the strip), 'sphere' (points = [centre]), 'arrow' (points =
[tail, head]); colour: RGBA 0..1; scale: line width / sphere diameter / arrow shaft diameter [m]."""


class Trail(object):
    """Bounded history of positions: a point is kept when at least ``spacing`` m from the last kept one; when
    one is kept, points older than ``length`` s before it and beyond ``max_points`` are dropped (so a hovering
    drone keeps the trail of its last ``length`` s of motion); time going backwards (a restarted simulation)
    clears it. Non-finite positions are refused (counted in ``refused``)."""

    def __init__(self, spacing=DEFAULTS['trail_spacing'], length=DEFAULTS['trail_length'],
                 max_points=DEFAULTS['max_points']):
        if not spacing >= 0.0 or not length > 0.0 or int(max_points) < 2:
            raise ValueError('need spacing >= 0, length > 0, max_points >= 2; got %r, %r, %r'
                             % (spacing, length, max_points))
        self.spacing, self.length = float(spacing), float(length)
        self.samples = collections.deque(maxlen=int(max_points))    # (t, (x, y, z))
        self.refused = 0
        self.cleared = 0

    def add(self, t, position):
        """Offer a sample; True when kept."""
        position = tuple(float(v) for v in position)
        if len(position) != 3 or not all(math.isfinite(v) for v in position) or not math.isfinite(t):
            self.refused += 1
            return False
        if self.samples and t < self.samples[-1][0]:
            self.samples.clear()
            self.cleared += 1
        if self.samples and _distance(self.samples[-1][1], position) < self.spacing:
            return False
        while self.samples and self.samples[0][0] < t - self.length:
            self.samples.popleft()
        self.samples.append((t, position))
        return True

    def points(self):
        return [p for _, p in self.samples]

    def __len__(self):
        return len(self.samples)


def _distance(a, b):
    return math.sqrt(sum((x - y) ** 2 for x, y in zip(a, b)))


def markers(drone, trail, reference, predicted=None, waypoint=None, line_width=DEFAULTS['line_width'],
            waypoint_size=DEFAULTS['waypoint_size']):
    """MarkerSpecs of one drone: trail and reference line strips (when >= 2 points), the predicted path
    (``predicted``: list of positions, or None), the waypoint sphere and a 1 m yaw arrow (``waypoint``:
    (position, yaw [rad]) or None)."""
    out = []
    for kind, points in (('trail', trail.points()), ('reference', reference.points()),
                         ('predicted', list(predicted or []))):
        if len(points) >= 2:
            out.append(MarkerSpec('%s/%s' % (drone, kind), 0, 'line', points, COLOURS[kind], line_width))
    if waypoint is not None:
        position, yaw = waypoint
        position = tuple(float(v) for v in position)
        head = (position[0] + math.cos(yaw), position[1] + math.sin(yaw), position[2])
        out.append(MarkerSpec('%s/waypoint' % drone, 0, 'sphere', [position], COLOURS['waypoint'], waypoint_size))
        out.append(MarkerSpec('%s/waypoint' % drone, 1, 'arrow', [position, head], COLOURS['waypoint'],
                              0.3 * waypoint_size))
    return out
