"""Kinematic world: the pure core of our stand-in for Gazebo (no ROS).

Stage: mirror -> **world** (what ``/gazebo/*`` services act on). Holds spawned
models, their pose and twist, and advances them with ``step(dt)``.

Spawnable descriptions (``describe_model``): a plain URDF (links, gravity,
static flag and geometry read by ``anafi_sim.gazebo.urdf_model.parse_urdf``; joint
origins and collision names read here to place each collision in the model
frame), or a minimal SDF ``<sdf><model>`` with ``<static>``, ``<link>``
(``<pose>``, ``<gravity>``, ``<inertial><mass>``, ``<collision name>`` with
box/sphere/cylinder/mesh geometry) and joints. Geom names follow Gazebo's
URDF->SDF conversion: ``LINK_collision`` for an unnamed collision,
``LINK_collision_NAME`` for a named one; SDF names as written.

Motion:

- pose += twist * dt (linear and angular velocity in the world frame, as
  Gazebo's ModelState twist), so a model extrapolates between updates;
- a model whose links have gravity ON accelerates downward between
  ``set_state`` calls, a = g * (mass on gravity-on links / total mass) (link
  count instead of mass when some link has no <inertial>); ``set_state``
  resets the velocity to the commanded twist. This is the jitter the paper
  avoids by switching gravity off: a gravity-on mirrored model sags by
  0.5 a t^2 after each update (0.49 mm after 10 ms at a = 9.81 m/s^2);
- static models never move except through ``set_state`` (twist ignored).

Collisions (no physics response, contacts are only reported): every
collision geometry is approximated by its world axis-aligned bounding box
(box/cylinder rotated into the world, then boxed: conservative), except
sphere-vs-sphere, which is exact; a mesh is a sphere of radius
``MESH_RADIUS`` times its largest scale. Pairs of different models that
both have collision geometry are checked after every step (no
self-collision; two static models are not checked); a contact *event* is
counted when a pair starts touching. ``report(name)`` sums a model up for
diagnostics (gravity links, geoms, sag, updates, contact events); ``health``
gives the node's /diagnostics statuses. ``advance(duration, max_step)`` is a
node cycle: equal substeps, the contact events of each (``contact_record``:
their JSON objects).

Units and frames: SI (m, s, rad, m/s, rad/s), world frame ENU ("" or
"world"), quaternions (x, y, z, w). A model name is also accepted as
reference frame (pose and twist expressed in that model's frame, as Gazebo
does). Status messages follow gazebo_ros_api_plugin's wording.
Not modelled: joints move nothing (all at zero), fixed-joint lumping
(every link stays a body), ``model::link`` frames, contact forces, xacro.
"""
import collections
import math
import xml.etree.ElementTree as ET

import numpy as np

from anafi_control import frames
from anafi_sim.gazebo import urdf_model
from anafi_sim.interface.ground_truth import OK, WARN, Health

Result = collections.namedtuple('Result', 'success status_message')
"""Outcome of a service-like call: bool, Gazebo-style message."""

State = collections.namedtuple('State', 'position orientation linear angular')
"""position (x, y, z) [m]; orientation quaternion (x, y, z, w); linear [m/s] and angular [rad/s] velocity,
all in the requested reference frame (world by default)."""

Properties = collections.namedtuple('Properties', 'parent_model_name canonical_body_name body_names geom_names '
                                                  'joint_names child_model_names is_static')
"""Fields of gazebo_msgs/GetModelPropertiesResponse (without success/status_message)."""

Contact = collections.namedtuple('Contact', 'model_a model_b geom_a geom_b depth')
"""model_a < model_b (names sorted); geom names of the first overlapping pair; depth [m] (smallest overlap)."""

ContactEvents = collections.namedtuple('ContactEvents', 'begun ended')
"""Contacts that started and pairs (model_a, model_b) that stopped touching during a step."""

ContactEvent = collections.namedtuple('ContactEvent', 'event time model_a model_b geom_a geom_b depth')
"""One contact event for ~contacts_topic: event 'begin' | 'end', world time [s], model and geom names
('' for an end), depth [m] (0 for an end). ``contact_record`` gives its JSON object."""


def contact_record(event):
    """The JSON object (dict) of a ContactEvent on ~contacts_topic (time and depth rounded to 1 um / 1 us)."""
    return {'event': event.event, 'time': round(event.time, 6), 'model_a': event.model_a,
            'model_b': event.model_b, 'geom_a': event.geom_a, 'geom_b': event.geom_b,
            'depth': round(event.depth, 6)}

WORLD_FRAMES = ('', 'world')

GROUND_PLANE_SDF = """<sdf version="1.6"><model name="ground_plane"><static>true</static>
<link name="link"><collision name="collision"><pose>0 0 -0.01 0 0 0</pose>
<geometry><box><size>1000 1000 0.02</size></box></geometry></collision></link></model></sdf>"""
"""Gazebo's ground_plane as a thin static box whose top face is z = 0 (Gazebo's is an infinite plane)."""

MESH_RADIUS = 0.1
"""Bounding radius [m] of a mesh collision of scale 1 (mesh files are not read)."""

Geom = collections.namedtuple('Geom', 'name kind size xyz rpy')
"""A collision geometry: Gazebo geom name; kind 'box' (size x, y, z), 'sphere' (radius,), 'cylinder'
(radius, length), 'mesh' (scale sx, sy, sz); pose in the model (root link) frame: xyz [m], rpy [rad]."""

WorldLink = collections.namedtuple('WorldLink', 'name gravity mass geoms')
"""A body: gravity flag, mass [kg] (None without <inertial>), tuple of Geom."""

ModelDescription = collections.namedtuple('ModelDescription', 'name format is_static links joint_names')
"""What the world knows of a spawned model: format 'urdf'/'sdf'; links: tuple of WorldLink, canonical first."""


class ModelFormatError(ValueError):
    """model_xml is neither a readable URDF nor a supported minimal SDF."""


def _compose(parent_xyz, parent_rpy, xyz, rpy):
    """(xyz, rpy) of a frame given in the ``parent`` frame, expressed where ``parent`` is given."""
    r_parent = frames.rotation_matrix(*parent_rpy)
    position = np.asarray(parent_xyz, dtype=float) + r_parent.dot(np.asarray(xyz, dtype=float))
    rotation = r_parent.dot(frames.rotation_matrix(*rpy))
    rpy_out = (math.atan2(rotation[2, 1], rotation[2, 2]),
               math.atan2(-rotation[2, 0], math.hypot(rotation[0, 0], rotation[1, 0])),   # accurate at +-90 deg
               math.atan2(rotation[1, 0], rotation[0, 0]))
    return tuple(float(v) for v in position), rpy_out


def _numbers(text, count, what):
    try:
        values = tuple(float(v) for v in (text or '').split())
    except ValueError:
        values = ()
    if len(values) != count or not frames.is_finite(*values):
        raise ModelFormatError('%s: expected %d finite numbers, got %r' % (what, count, text))
    return values


def _flag(text, what):
    value = (text or '').strip().lower()
    if value not in ('0', '1', 'true', 'false'):
        raise ModelFormatError('%s: expected true/false/1/0, got %r' % (what, text))
    return value in ('1', 'true')


def _urdf_link_poses(root, link_names):
    """{link: (xyz, rpy) in the root link frame} from the URDF joint origins (joints at zero)."""
    children = {}
    child_links = set()
    for joint in root.findall('joint'):
        parent, child = joint.find('parent'), joint.find('child')
        parent = parent.get('link') if parent is not None else None
        child = child.get('link') if child is not None else None
        name = joint.get('name', '')
        if parent not in link_names or child not in link_names:
            raise ModelFormatError('joint %r refers to an unknown link' % name)
        if child in child_links:
            raise ModelFormatError('link %r has two parent joints' % child)
        child_links.add(child)
        origin = joint.find('origin')
        xyz = _numbers(origin.get('xyz', '0 0 0'), 3, 'joint %s origin xyz' % name) if origin is not None \
            else (0.0, 0.0, 0.0)
        rpy = _numbers(origin.get('rpy', '0 0 0'), 3, 'joint %s origin rpy' % name) if origin is not None \
            else (0.0, 0.0, 0.0)
        children.setdefault(parent, []).append((child, xyz, rpy))
    roots = [n for n in link_names if n not in child_links]
    if len(roots) != 1:
        raise ModelFormatError('expected exactly one root link, found %r' % roots)
    poses = {roots[0]: ((0.0, 0.0, 0.0), (0.0, 0.0, 0.0))}
    stack = [roots[0]]
    while stack:
        parent = stack.pop()
        for child, xyz, rpy in children.get(parent, ()):
            poses[child] = _compose(poses[parent][0], poses[parent][1], xyz, rpy)
            stack.append(child)
    if len(poses) != len(link_names):
        raise ModelFormatError('links not connected to the root link: %r' % sorted(set(link_names) - set(poses)))
    return roots[0], poses


def _describe_urdf(text, root):
    try:
        parsed = urdf_model.parse_urdf(text)
    except urdf_model.UrdfError as error:
        raise ModelFormatError('URDF: %s' % error)
    root_link, poses = _urdf_link_poses(root, parsed.link_names)
    collision_names = dict((e.get('name'), [c.get('name') for c in e.findall('collision')])
                           for e in root.findall('link'))
    links = []
    for name in [root_link] + [n for n in parsed.link_names if n != root_link]:
        link = parsed.links[name]
        link_xyz, link_rpy = poses[name]
        geoms = []
        for collision, cname in zip(link.collisions, collision_names[name]):
            if collision.type == 'mesh':
                size = tuple(float(v) for v in collision.size[1])
                if len(size) != 3:
                    raise ModelFormatError('link %s: mesh scale needs 3 numbers' % name)
            else:
                size = tuple(float(v) for v in collision.size)
            if not frames.is_finite(*(size + collision.origin[0] + collision.origin[1])):
                raise ModelFormatError('link %s: collision size or origin is not finite' % name)
            xyz, rpy = _compose(link_xyz, link_rpy, *collision.origin)
            geoms.append(Geom(name + '_collision' + ('_' + cname if cname else ''), collision.type, size,
                              xyz, rpy))
        links.append(WorldLink(name, bool(link.gravity), link.mass, tuple(geoms)))
    return ModelDescription(parsed.name, 'urdf', bool(parsed.is_static), tuple(links),
                            [j[0] for j in parsed.joints])


def _sdf_pose(element, what):
    pose = element.find('pose')
    if pose is None or not (pose.text or '').strip():
        return (0.0, 0.0, 0.0), (0.0, 0.0, 0.0)
    values = _numbers(pose.text, 6, what + ' <pose>')
    return values[:3], values[3:]


def _sdf_geometry(collision, what):
    geometry = collision.find('geometry')
    if geometry is None or len(geometry) == 0:
        raise ModelFormatError('%s has no <geometry>' % what)
    shape = geometry[0]
    if shape.tag == 'box':
        return 'box', _numbers(shape.findtext('size'), 3, what + ' box size')
    if shape.tag == 'sphere':
        return 'sphere', _numbers(shape.findtext('radius'), 1, what + ' sphere radius')
    if shape.tag == 'cylinder':
        return 'cylinder', (_numbers(shape.findtext('radius'), 1, what + ' cylinder radius')
                            + _numbers(shape.findtext('length'), 1, what + ' cylinder length'))
    if shape.tag == 'mesh':
        return 'mesh', _numbers(shape.findtext('scale') or '1 1 1', 3, what + ' mesh scale')
    raise ModelFormatError('%s: unsupported geometry <%s>' % (what, shape.tag))


def _describe_sdf(root):
    model = root.find('model')
    if model is None:
        raise ModelFormatError('SDF without <model> (worlds and nested models are not supported)')
    name = model.get('name', '')
    static = model.find('static')
    links = []
    for element in model.findall('link'):
        lname = element.get('name')
        if not lname:
            raise ModelFormatError('SDF model %r: <link> without a name' % name)
        link_xyz, link_rpy = _sdf_pose(element, 'link %s' % lname)
        geoms = []
        for collision in element.findall('collision'):
            what = 'link %s collision' % lname
            kind, size = _sdf_geometry(collision, what)
            xyz, rpy = _compose(link_xyz, link_rpy, *_sdf_pose(collision, what))
            geoms.append(Geom(collision.get('name') or lname + '_collision', kind, size, xyz, rpy))
        gravity = element.find('gravity')
        mass = element.findtext('inertial/mass')
        links.append(WorldLink(lname, _flag(gravity.text, 'link %s gravity' % lname) if gravity is not None
                               else True,
                               _numbers(mass, 1, 'link %s mass' % lname)[0] if mass is not None else None,
                               tuple(geoms)))
    if not links:
        raise ModelFormatError('SDF model %r has no <link>' % name)
    return ModelDescription(name, 'sdf', _flag(static.text, '<static>') if static is not None else False,
                            tuple(links), [j.get('name', '') for j in model.findall('joint')])


def describe_model(model_xml):
    """ModelDescription of URDF (``<robot>``) or minimal SDF (``<sdf><model>``) text; raises ModelFormatError.

    An SDF model's own <pose> is ignored: the spawn request's initial pose places the model."""
    if not isinstance(model_xml, str) or not model_xml.strip():
        raise ModelFormatError('empty model_xml')
    try:
        root = ET.fromstring(model_xml.strip())
    except ET.ParseError as error:
        raise ModelFormatError('malformed XML: %s' % error)
    if root.tag == 'robot':
        return _describe_urdf(model_xml.strip(), root)
    if root.tag == 'sdf':
        return _describe_sdf(root)
    raise ModelFormatError('root element <%s> is neither <robot> (URDF) nor <sdf>' % root.tag)


def geom_names(description):
    """Gazebo geom (collision) names of every link, canonical link first; empty when there are none."""
    return [geom.name for link in description.links for geom in link.geoms]


def gravity_links(description):
    """Names of the links gravity acts on."""
    return [link.name for link in description.links if link.gravity]


IDENTITY = (0.0, 0.0, 0.0, 1.0)


def _unit(q):
    """Unit quaternion; a zero quaternion becomes the identity (as Gazebo's Normalize does)."""
    try:
        return frames.normalize_quaternion(q, 1e-12)
    except ValueError:
        return IDENTITY


def _finite(values):
    """frames.is_finite(*values), quicker when all are finite: a sum of finite numbers is finite unless it
    overflows (then, and for anything a sum refuses, every value is checked)."""
    try:
        if math.isfinite(sum(values)):
            return True
    except Exception:       # not numbers: is_finite decides
        pass
    return frames.is_finite(*values)


def _floats(vector):
    """A numpy 3-vector as a tuple of floats."""
    return (float(vector[0]), float(vector[1]), float(vector[2]))


def _conjugate(q):
    return (-q[0], -q[1], -q[2], q[3])


def _rotation_vector_quaternion(v):
    """Quaternion of a rotation by |v| [rad] about v."""
    angle = math.sqrt(float(v[0]) ** 2 + float(v[1]) ** 2 + float(v[2]) ** 2)
    if angle < 1e-12:
        return (0.0, 0.0, 0.0, 1.0)
    s = math.sin(0.5 * angle) / angle
    return (v[0] * s, v[1] * s, v[2] * s, math.cos(0.5 * angle))


def _texts(values):
    """(key, value) pairs with the values as diagnostics text (floats %.6g, lists comma-separated)."""
    out = []
    for key, value in values:
        if isinstance(value, float):
            value = '%.6g' % value
        elif isinstance(value, (list, tuple)):
            value = ','.join(str(v) for v in value)
        out.append((key, str(value)))
    return out


ZERO = (0.0, 0.0, 0.0)


class _Model(object):
    """Internal record of one spawned model: pose and twist in the world as tuples of floats (plain Python
    arithmetic on 3-vectors: numpy's per-call overhead would dominate)."""

    def __init__(self, name, description, gravity_acceleration):
        self.name = name
        self.description = description
        self.position = ZERO
        self.orientation = (0.0, 0.0, 0.0, 1.0)
        self.linear = ZERO
        self.angular = ZERO
        self.reported = None     # (orientation, its unit quaternion as get_state reports it in the world)
        self.acceleration = 0.0 if description.is_static else gravity_acceleration
        self.since_set = 0.0
        self.sag = 0.0
        self.max_sag = 0.0
        self.updates = 0
        self.contact_events = 0
        self.geoms = []  # (Geom, offset in model frame, rotation in model frame)
        for link in description.links:
            for geom in link.geoms:
                self.geoms.append((geom, np.asarray(geom.xyz, dtype=float), frames.rotation_matrix(*geom.rpy)))


def _gravity_fraction(description):
    """Share of the model that falls: mass on gravity-on links / total mass (link count if a mass is missing)."""
    links = description.links
    if all(link.mass is not None and link.mass > 0.0 for link in links):
        return sum(link.mass for link in links if link.gravity) / sum(link.mass for link in links)
    return sum(1.0 for link in links if link.gravity) / len(links)


def _geom_box(model, geom):
    """(kind, center, half extents or radius) of a collision geometry in the world."""
    geometry, offset, rotation = geom
    r_model = frames.quaternion_matrix(model.orientation)
    center = np.asarray(model.position) + r_model.dot(offset)
    if geometry.kind == 'sphere':
        return 'sphere', center, geometry.size[0]
    if geometry.kind == 'mesh':
        return 'sphere', center, MESH_RADIUS * max(abs(v) for v in geometry.size)
    if geometry.kind == 'box':
        half = 0.5 * np.asarray(geometry.size, dtype=float)
    else:  # cylinder, axis along its local z
        radius, length = geometry.size
        half = np.array([radius, radius, 0.5 * length])
    world_half = np.abs(r_model.dot(rotation)).dot(half)
    return 'box', center, world_half


def _overlap(a, b):
    """Penetration depth [m] (> 0) of two (kind, center, size) approximations, or None."""
    kind_a, center_a, size_a = a
    kind_b, center_b, size_b = b
    if kind_a == 'sphere' and kind_b == 'sphere':
        depth = size_a + size_b - float(np.linalg.norm(center_a - center_b))
        return depth if depth > 0.0 else None
    half_a = np.full(3, size_a) if kind_a == 'sphere' else size_a
    half_b = np.full(3, size_b) if kind_b == 'sphere' else size_b
    overlap = half_a + half_b - np.abs(center_a - center_b)
    depth = float(np.min(overlap))
    return depth if depth > 0.0 else None


class KinematicWorld(object):
    """Models, their states, kinematic integration, contacts. Methods take and return plain numbers/tuples."""

    def __init__(self, gravity=9.81, ground_plane=False):
        """gravity [m/s^2] >= 0 (magnitude, acting along -z); ground_plane: spawn Gazebo's 'ground_plane'."""
        if not frames.is_finite(gravity) or gravity < 0.0:
            raise ValueError('gravity must be a finite number >= 0 m/s^2, got %r' % (gravity,))
        self.gravity = float(gravity)
        self.time = 0.0
        self._models = collections.OrderedDict()
        self._contacts = {}
        self.counters = collections.OrderedDict(
            (key, 0) for key in ('spawned', 'deleted', 'state_updates', 'rejected', 'contact_events'))
        if ground_plane:
            result = self.spawn('ground_plane', GROUND_PLANE_SDF)
            assert result.success, result.status_message

    # ------------------------------------------------------------------ model management
    def names(self):
        """Model names in spawn order."""
        return list(self._models)

    def spawn(self, name, model_xml, position=(0.0, 0.0, 0.0), orientation=(0.0, 0.0, 0.0, 1.0),
              reference_frame=''):
        """Add a model from URDF or SDF text at a pose given in ``reference_frame``; velocity zero."""
        try:
            description = describe_model(model_xml)
        except ModelFormatError as error:
            return self._reject('SpawnModel: Failure - model_xml is not a valid URDF or SDF: %s' % error)
        name = name or description.name
        if not name:
            return self._reject('SpawnModel: Failure - empty model name and no name in model_xml')
        if name in self._models:
            return self._reject('SpawnModel: Failure - entity already exists.')      # gazebo_ros's words
        if not frames.is_finite(*(tuple(position) + tuple(orientation))):
            return self._reject('SpawnModel: Failure - initial_pose is not finite')
        frame = self._frame(reference_frame)
        if frame is None:
            return self._reject('SpawnModel: Failure - reference frame [%s] does not exist' % reference_frame)
        model = _Model(name, description, self.gravity * _gravity_fraction(description))
        model.position, model.orientation = self._to_world_pose(frame, position, orientation)
        self._models[name] = model
        self.counters['spawned'] += 1
        return Result(True, 'SpawnModel: Successfully spawned entity')

    def delete(self, name):
        """Remove a model (and its contacts)."""
        if name not in self._models:
            return self._reject('DeleteModel: model does not exist')
        del self._models[name]
        for pair in [p for p in self._contacts if name in p]:
            del self._contacts[pair]
        self.counters['deleted'] += 1
        return Result(True, 'DeleteModel: successfully deleted model')

    def set_state(self, name, position, orientation, linear=(0.0, 0.0, 0.0), angular=(0.0, 0.0, 0.0),
                  reference_frame=''):
        """Teleport a model and set its velocity to the commanded twist (all in ``reference_frame``)."""
        model = self._models.get(name)
        if model is None:
            return self._reject('SetModelState: model does not exist')
        position, orientation, linear, angular = tuple(position), tuple(orientation), tuple(linear), tuple(angular)
        values = position + orientation + linear + angular
        if (len(position), len(orientation), len(linear), len(angular)) != (3, 4, 3, 3) or not _finite(values):
            return self._reject('SetModelState: Failure - pose or twist of [%s] is not finite' % name)
        if reference_frame in WORLD_FRAMES:
            # the world frame: the general path below with an identity transform, done on floats with the
            # same values (x + 0.0 adds the frame's zero origin; a zero twist component may lose its sign)
            px, py, pz, qx, qy, qz, qw, lx, ly, lz, ax, ay, az = values
            model.position = (float(px) + 0.0, float(py) + 0.0, float(pz) + 0.0)
            model.orientation = _unit(frames.quaternion_multiply(IDENTITY, _unit((qx, qy, qz, qw))))
            if model.description.is_static:
                model.linear, model.angular = ZERO, ZERO
            else:
                model.linear = (float(lx) + 0.0, float(ly) + 0.0, float(lz) + 0.0)
                model.angular = (float(ax) + 0.0, float(ay) + 0.0, float(az) + 0.0)
        else:
            frame = self._frame(reference_frame)
            if frame is None:
                return self._reject('SetModelState: specified reference frame entity does not exist')
            model.position, model.orientation = self._to_world_pose(frame, position, orientation)
            if model.description.is_static:
                model.linear, model.angular = ZERO, ZERO
            else:
                rotation = frames.quaternion_matrix(frame[1])
                model.linear = _floats(rotation.dot(np.asarray(linear, dtype=float)))
                model.angular = _floats(rotation.dot(np.asarray(angular, dtype=float)))
        model.since_set = 0.0
        model.sag = 0.0
        model.updates += 1
        self.counters['state_updates'] += 1
        return Result(True, 'SetModelState: set model state done')

    def get_state(self, name, relative_entity_name=''):
        """(Result, State or None): pose and twist of ``name`` in ``relative_entity_name``'s frame."""
        model = self._models.get(name)
        if model is None:
            return self._reject('GetModelState: model does not exist'), None
        if relative_entity_name in WORLD_FRAMES:
            return Result(True, 'GetModelState: got properties'), self._world_state(model)
        frame = self._frame(relative_entity_name)
        if frame is None:
            return self._reject('GetModelState: reference relative_entity_name not found, did you forget to '
                                'scope the body by model name?'), None
        f_position, f_orientation, f_linear, f_angular = frame
        r_frame_t = frames.quaternion_matrix(f_orientation).T
        position = r_frame_t.dot(np.asarray(model.position) - f_position)
        orientation = _unit(frames.quaternion_multiply(_conjugate(f_orientation), model.orientation))
        linear = r_frame_t.dot(np.asarray(model.linear) - f_linear)
        angular = r_frame_t.dot(np.asarray(model.angular) - f_angular)
        state = State(tuple(float(v) for v in position), orientation,
                      tuple(float(v) for v in linear), tuple(float(v) for v in angular))
        return Result(True, 'GetModelState: got properties'), state

    def states(self):
        """[(name, State in world)] for every model, in spawn order (what /gazebo/model_states carries)."""
        return [(name, self._world_state(model)) for name, model in self._models.items()]

    @staticmethod
    def _world_state(model):
        """State of a model in the world frame: get_state's general path with an identity frame (the
        orientation is normalised once more, as the product with the frame's conjugate is)."""
        reported = model.reported
        if reported is None or reported[0] is not model.orientation:
            reported = model.reported = (model.orientation,
                                         _unit(frames.quaternion_multiply(_conjugate(IDENTITY), model.orientation)))
        return State(model.position, reported[1], model.linear, model.angular)

    def properties(self, name):
        """(Result, Properties or None) as GetModelProperties reports them."""
        model = self._models.get(name)
        if model is None:
            return self._reject('GetModelProperties: model does not exist'), None
        description = model.description
        return Result(True, 'GetModelProperties: got properties'), Properties(
            parent_model_name='',
            canonical_body_name=description.links[0].name,
            body_names=[link.name for link in description.links],
            geom_names=geom_names(description),
            joint_names=list(description.joint_names),
            child_model_names=[],
            is_static=bool(description.is_static))

    def report(self, name):
        """Per-model health facts for diagnostics: gravity and collision set-up, sag, updates, contacts."""
        model = self._models[name]
        return collections.OrderedDict([
            ('gravity_links', gravity_links(model.description)),
            ('gravity_acceleration', model.acceleration),
            ('geom_names', geom_names(model.description)),
            ('is_static', bool(model.description.is_static)),
            ('state_updates', model.updates),
            ('sag', model.sag),
            ('max_sag', model.max_sag),
            ('contact_events', model.contact_events),
        ])

    def health(self, loop_values=(), overruns=0):
        """[(status name, Health)] for /diagnostics: 'world' (models, contacts, counters and the node's
        ``loop_values`` (key, value) pairs; WARN when ``overruns`` > 0: running slower than rtf), then
        'model NAME' for every model (its ``report``). Values are formatted as text."""
        names = self.names()
        contacts = len(self._contacts)
        events = self.counters['contact_events']
        message = '%d models, %d contacts now, %d contact events%s' % (
            len(names), contacts, events, ', %d overruns (running slower than rtf)' % overruns if overruns else '')
        values = [('time', self.time)] + list(loop_values) + [('current_contacts', contacts), ('models', names)] \
            + sorted(self.counters.items())
        out = [('world', Health(WARN if overruns else OK, message, _texts(values)))]
        for name in names:
            report = self.report(name)
            message = '%s, %s%s' % (
                'gravity ON (%s)' % ','.join(report['gravity_links']) if report['gravity_links'] else 'gravity off',
                'collision geoms %s' % ','.join(report['geom_names']) if report['geom_names']
                else 'no collision geometry', ', static' if report['is_static'] else '')
            out.append(('model %s' % name, Health(OK, message, _texts(report.items()))))
        return out

    # ------------------------------------------------------------------ time
    def step(self, dt):
        """Advance every model by ``dt`` [s] (> 0, finite) and update contacts; returns ContactEvents."""
        if not frames.is_finite(dt) or dt <= 0.0:
            raise ValueError('step dt must be a finite number > 0 s, got %r' % (dt,))
        for model in self._models.values():
            if model.description.is_static:
                continue
            gravity = -model.acceleration        # along z; x and y: 0.0 (adding it turns -0.0 into 0.0)
            (px, py, pz), (lx, ly, lz) = model.position, model.linear
            model.position = (px + lx * dt + 0.0, py + ly * dt + 0.0, pz + lz * dt + 0.5 * gravity * dt * dt)
            model.linear = (lx + 0.0, ly + 0.0, lz + gravity * dt)
            ax, ay, az = model.angular
            if ax or ay or az:
                dq = _rotation_vector_quaternion((ax * dt, ay * dt, az * dt))
                model.orientation = _unit(frames.quaternion_multiply(dq, model.orientation))
            model.since_set += dt
            model.sag = 0.5 * model.acceleration * model.since_set ** 2
            if model.sag > model.max_sag:
                model.max_sag = model.sag
        self.time += dt
        return self._update_contacts()

    def advance(self, duration, max_step):
        """Advance by ``duration`` [s] in equal substeps of at most ``max_step`` [s]; returns the
        ContactEvents of every substep, in order, stamped with the time at the end of the advance."""
        substeps = max(1, int(math.ceil(duration / max_step - 1e-9)))
        events = []
        for _ in range(substeps):
            begun, ended = self.step(duration / substeps)
            events.extend(('begin', c.model_a, c.model_b, c.geom_a, c.geom_b, c.depth) for c in begun)
            events.extend(('end', a, b, '', '', 0.0) for a, b in ended)
        return [ContactEvent(kind, self.time, a, b, geom_a, geom_b, depth)
                for kind, a, b, geom_a, geom_b, depth in events]

    # ------------------------------------------------------------------ contacts
    def contacts(self):
        """Contacts currently touching, sorted by model pair."""
        return [self._contacts[pair] for pair in sorted(self._contacts)]

    def _update_contacts(self):
        models = [m for m in self._models.values() if m.geoms]
        if all(m.description.is_static for m in models):      # no pair to check (static pairs never are)
            models = []
        boxes = dict((m.name, [(g[0].name, _geom_box(m, g)) for g in m.geoms]) for m in models)
        current = {}
        for i, a in enumerate(models):
            for b in models[i + 1:]:
                if a.description.is_static and b.description.is_static:
                    continue
                first, second = (a, b) if a.name < b.name else (b, a)
                contact = self._touch(first, second, boxes)
                if contact is not None:
                    current[(first.name, second.name)] = contact
        begun = [current[p] for p in sorted(current) if p not in self._contacts]
        ended = [p for p in sorted(self._contacts) if p not in current]
        for contact in begun:
            self.counters['contact_events'] += 1
            self._models[contact.model_a].contact_events += 1
            self._models[contact.model_b].contact_events += 1
        self._contacts = current
        return ContactEvents(begun, ended)

    @staticmethod
    def _touch(first, second, boxes):
        for geom_a, box_a in boxes[first.name]:
            for geom_b, box_b in boxes[second.name]:
                depth = _overlap(box_a, box_b)
                if depth is not None:
                    return Contact(first.name, second.name, geom_a, geom_b, depth)
        return None

    # ------------------------------------------------------------------ helpers
    def _reject(self, message):
        self.counters['rejected'] += 1
        return Result(False, message)

    def _frame(self, name):
        """(position, orientation, linear, angular) of a reference frame in the world, or None if unknown."""
        if name in WORLD_FRAMES:
            return np.zeros(3), (0.0, 0.0, 0.0, 1.0), np.zeros(3), np.zeros(3)
        model = self._models.get(name)
        if model is None:
            return None
        return np.array(model.position), model.orientation, np.array(model.linear), np.array(model.angular)

    @staticmethod
    def _to_world_pose(frame, position, orientation):
        f_position, f_orientation = frame[0], frame[1]
        world_position = f_position + frames.quaternion_matrix(f_orientation).dot(np.asarray(position, dtype=float))
        world_orientation = _unit(frames.quaternion_multiply(f_orientation, _unit(orientation)))
        return _floats(world_position), world_orientation
