"""The rviz view of a fleet (pure, no ROS): one model and one marker display per drone, and a camera that frames
the whole fleet.

Stage: experiments (next to ``visualisation`` and ``fleet``). ``fleet_launcher.py`` writes ``fleet_rviz(fleet)``
to ``<out_dir>/fleet.rviz`` and the generated fleet launch file starts rviz on it (``fleet.launch rviz:=true``).

The template is ``anafi_sim/config/anafi.rviz`` (one drone): its grid, tf display, background and window are kept;
its single RobotModel (``/anafi/robot_description``, TF prefix ``anafi``) and shared MarkerArray are replaced by
one ``rviz/Group`` per drone NAME holding a RobotModel (``/NAME/robot_description``, TF prefix NAME) and a
MarkerArray on ``/NAME/visualisation/markers`` (that drone's trail, reference, predicted path and waypoint, as
``visualisation_node.py ~markers_topic: visualisation/markers`` publishes them); the view stops orbiting
``anafi/base_link`` (the estimate's) and looks at the fleet from the world frame (``fleet_view``).

Camera model (rviz's Orbit view): the eye sits at focal point + distance * (cos(yaw) cos(pitch), sin(yaw)
cos(pitch), sin(pitch)) in the fixed frame and looks at the focal point; rviz keeps Ogre's vertical field of
view of 45 deg, the horizontal one follows the 3D view's aspect ratio.
"""
import copy
import math

import yaml

from anafi_sim import paths

TEMPLATE = 'anafi.rviz'
FOV_Y = math.radians(45.0)       # rviz's (Ogre's default) vertical field of view
PITCH = 0.6                      # rad above the horizon: the fleet seen from above at an angle
MARGIN = 1.25                    # the framed extent times this (the drones' trails reach past their paths)
MIN_DISTANCE = 6.0               # m: one drone is framed as anafi.rviz frames it
SAMPLES = 200                    # points per scenario sampled for the framing
MAX_SAMPLED = 600.0              # s of a scenario sampled (a long static hold adds nothing)
MARKERS_TOPIC = 'visualisation/markers'   # per drone, relative to its namespace (rviz.launch markers_topic)
PANEL_WIDTH = 380.0              # px of the window left of the 3D view (the Displays panel)
BARS_HEIGHT = 90.0               # px of the window above and below it (menu, tools, status)


def load_template(name=TEMPLATE):
    with open(paths.config_path(name)) as f:
        return yaml.safe_load(f)


def scenario_points(scenario, samples=SAMPLES, max_time=MAX_SAMPLED):
    """Positions (x, y, z) [m] of a ``trajectory.Scenario``'s waypoints over its duration (at most
    ``max_time`` s), ``samples`` of them, the start included."""
    end = min(scenario.duration, max_time)
    out = [(scenario.start.x, scenario.start.y, scenario.start.z)]
    for i in range(samples + 1):
        w = scenario.waypoint(end * i / float(samples))
        out.append((w.x, w.y, w.z))
    return out


def fleet_view(points, aspect, fov_y=FOV_Y, pitch=PITCH, margin=MARGIN, min_distance=MIN_DISTANCE):
    """Orbit view (dict: focal (x, y, z), distance, yaw, pitch [rad]) that shows every point of ``points``
    (world ENU [m]) in a 3D view of ``aspect`` = width / height.

    The camera looks across the fleet's longer horizontal side (yaw perpendicular to it, from the side of
    smaller x or y), so a row of drones spreads over the width of the screen; the distance is the larger of
    what the width and the height need for the extent times ``margin``, plus the depth in front of the
    focal point, and at least ``min_distance``."""
    pts = [tuple(float(v) for v in p) for p in points]
    if not pts or not all(len(p) == 3 and all(math.isfinite(v) for v in p) for p in pts):
        raise ValueError('fleet_view needs finite (x, y, z) points, got %r' % (points,))
    if not aspect > 0.0 or not 0.0 < fov_y < math.pi:
        raise ValueError('need aspect > 0 and 0 < fov_y < pi, got %r, %r' % (aspect, fov_y))
    lo = [min(p[i] for p in pts) for i in range(3)]
    hi = [max(p[i] for p in pts) for i in range(3)]
    focal = tuple(0.5 * (a + b) for a, b in zip(lo, hi))
    span_x, span_y, span_z = (b - a for a, b in zip(lo, hi))
    if span_y >= span_x:       # the long side along y: look along +x (eye at -x); screen width = y
        yaw, width, depth = math.pi, span_y, span_x
    else:                      # along x: look along +y (eye at -y); screen width = x
        yaw, width, depth = -0.5 * math.pi, span_x, span_y
    tan_y = math.tan(0.5 * fov_y)
    tan_x = aspect * tan_y
    height = span_z * math.cos(pitch) + depth * math.sin(pitch)     # the box's extent across the screen
    distance = max(0.5 * margin * width / tan_x, 0.5 * margin * height / tan_y) + 0.5 * depth * math.cos(pitch)
    return {'focal': focal, 'distance': max(distance, min_distance), 'yaw': yaw, 'pitch': pitch}


def project(view, point, size, fov_y=FOV_Y):
    """Pixel (column, row) of world point ``point`` in a 3D view of ``size`` (width, height) px seen from
    ``view`` (``fleet_view``'s dict), or None behind the camera. Used by the screenshot test to say where
    each drone should be."""
    fx, fy, fz = view['focal']
    yaw, pitch, d = view['yaw'], view['pitch'], view['distance']
    back = (math.cos(yaw) * math.cos(pitch), math.sin(yaw) * math.cos(pitch), math.sin(pitch))  # focal -> eye
    eye = (fx + d * back[0], fy + d * back[1], fz + d * back[2])
    forward = tuple(-c for c in back)
    right = (forward[1], -forward[0], 0.0)            # forward x up(z), normalised
    norm = math.hypot(right[0], right[1])
    right = (right[0] / norm, right[1] / norm, 0.0)
    up = (right[1] * forward[2] - right[2] * forward[1], right[2] * forward[0] - right[0] * forward[2],
          right[0] * forward[1] - right[1] * forward[0])
    rel = tuple(p - e for p, e in zip(point, eye))
    z = sum(a * b for a, b in zip(rel, forward))
    if z <= 0.0:
        return None
    x = sum(a * b for a, b in zip(rel, right))
    y = sum(a * b for a, b in zip(rel, up))
    width, height = size
    focal_px = 0.5 * height / math.tan(0.5 * fov_y)
    return (0.5 * width + focal_px * x / z, 0.5 * height - focal_px * y / z)


def drone_group(name, template_model):
    """The rviz/Group of drone ``name``: its RobotModel (a copy of the template's, on the drone's robot
    description and TF prefix) and its MarkerArray."""
    model = copy.deepcopy(template_model)
    model.update({'Name': '%s model' % name, 'Robot Description': '/%s/robot_description' % name,
                  'TF Prefix': name})
    markers = {'Class': 'rviz/MarkerArray', 'Enabled': True, 'Marker Topic': '/%s/%s' % (name, MARKERS_TOPIC),
               'Name': '%s trail, reference, predicted path, waypoint' % name, 'Namespaces': {},
               'Queue Size': 100, 'Value': True}
    return {'Class': 'rviz/Group', 'Displays': [model, markers], 'Enabled': True, 'Name': name, 'Value': True}


def view_size(config):
    """(width, height) px of the 3D view of a config: its window less the Displays panel on the left (rviz
    shows it: 360 px in a 1200 x 800 window), the menu, tool and status bars (90 px), as the screenshot test
    measures them."""
    geometry = config['Window Geometry']
    return float(geometry['Width']) - PANEL_WIDTH, float(geometry['Height']) - BARS_HEIGHT


def grid_cells(points, focal, minimum=12):
    """Cells (1 m) of a grid centred on ``focal`` that covers every point's x and y, even, >= ``minimum``."""
    reach = max(max(abs(p[0] - focal[0]), abs(p[1] - focal[1])) for p in points)
    cells = int(math.ceil(2.0 * reach)) + 4
    return max(minimum, cells + cells % 2)


def fleet_config(names, points, template=None):
    """The rviz config mapping for drones ``names`` framing ``points`` (world [m]); ``template``: the mapping
    of anafi.rviz (default: read)."""
    if not names:
        raise ValueError('a fleet view needs at least one drone')
    config = copy.deepcopy(template if template is not None else load_template())
    manager = config['Visualization Manager']
    displays = manager['Displays']
    models = [d for d in displays if d.get('Class') == 'rviz/RobotModel']
    if len(models) != 1:
        raise ValueError('the rviz template needs exactly one rviz/RobotModel display, has %d' % len(models))
    kept = [d for d in displays if d.get('Class') not in ('rviz/RobotModel', 'rviz/MarkerArray')]
    width, height = view_size(config)
    view = fleet_view(points, width / height)
    for d in kept:
        if d.get('Class') == 'rviz/TF':
            d['Show Names'] = False          # three drones' frame names over each other hide the drones
        if d.get('Class') == 'rviz/Grid':    # under the whole fleet
            d['Offset'] = {'X': round(view['focal'][0]), 'Y': round(view['focal'][1]), 'Z': 0}
            d['Plane Cell Count'] = grid_cells(points, view['focal'])
    manager['Displays'] = kept + [drone_group(n, models[0]) for n in names]
    current = manager['Views']['Current']
    current['Target Frame'] = '<Fixed Frame>'
    current['Focal Point'] = dict(zip('XYZ', (round(v, 3) for v in view['focal'])))
    current['Distance'] = round(view['distance'], 3)
    current['Yaw'] = round(view['yaw'], 4)
    current['Pitch'] = round(view['pitch'], 4)
    return config, view


def fleet_points(fleet, scenarios):
    """The points a fleet's view frames: every drone's take-off point (at 1 m) and the waypoints of its
    scenario (``scenarios``: {name: trajectory.Scenario}; a drone following a model adds its take-off point)."""
    out = []
    for drone in fleet.drones:
        out.append((drone.start[0], drone.start[1], 1.0))
        if drone.name in scenarios:
            out += scenario_points(scenarios[drone.name])
    return out


def header(fleet):
    return ('# rviz view of fleet %s (%d drones: %s), generated by fleet_launcher.py '
            '(anafi_sim/mission/rviz_config.py) from anafi_sim/config/anafi.rviz. Do not edit.\n'
            % (fleet.name, len(fleet.drones), ', '.join(d.name for d in fleet.drones)))


def fleet_rviz(fleet, scenarios, template=None):
    """(text of the .rviz file, view dict) of ``fleet`` (``fleet.Fleet``) flying ``scenarios``."""
    config, view = fleet_config([d.name for d in fleet.drones], fleet_points(fleet, scenarios), template)
    return header(fleet) + yaml.safe_dump(config, default_flow_style=False, sort_keys=False), view
