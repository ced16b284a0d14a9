"""URDF facts Gazebo acts on: links, per-link gravity, collision geometry, sensors (pure, no ROS).

Stage: mirror (what the mirrored models look like to the world).

``parse_urdf(xml)`` reads a plain URDF string (no xacro) and returns a
``UrdfModel``: its links with their gravity flag as Gazebo applies it
(``<gazebo reference="LINK"><gravity>0</gravity></gazebo>``, or the legacy
``<turnGravityOff>true</turnGravityOff>``; default on), their ``<collision>``
geometry (none = the link cannot collide), visuals, mass, and the Gazebo
``<sensor>`` elements attached to them. Lengths in m, masses in kg.
``set_gravity(xml, enabled)`` rewrites a URDF with every link's gravity
switched (used to build the deliberately gravity-on test copy).
"""
import collections
import xml.etree.ElementTree as ET

Geometry = collections.namedtuple('Geometry', 'type size origin')
"""type: 'box' | 'cylinder' | 'sphere' | 'mesh'; size: (x, y, z) for a box, (radius, length) for a cylinder,
(radius,) for a sphere, (filename, scale) for a mesh (lengths in m); origin: ((x, y, z) [m], (roll, pitch,
yaw) [rad]) of the geometry in the link frame."""

Sensor = collections.namedtuple('Sensor', 'name type link update_rate plugins camera')
"""A Gazebo ``<sensor>``: plugins = tuple of plugin filenames; camera = dict (horizontal_fov [rad], width,
height, format, near, far [m]) for camera sensors, else None."""

Link = collections.namedtuple('Link', 'name gravity collisions visuals mass inertia')
"""gravity: bool as Gazebo applies it; collisions / visuals: tuples of ``Geometry``; mass [kg] or None
without ``<inertial>``; inertia: (ixx, ixy, ixz, iyy, iyz, izz) [kg m^2] or None."""

_FALSE = ('0', 'false')
_TRUE = ('1', 'true')


class UrdfError(ValueError):
    """The string is not a URDF this module can read."""


class UrdfModel(object):
    """A parsed URDF: ``name``, ``links`` (ordered dict name -> Link), ``joints`` (list of (name, type,
    parent, child)), ``sensors`` (tuple of Sensor), ``is_static`` (bool), ``plugins`` (model-level plugin
    filenames)."""

    def __init__(self, name, links, joints, sensors, is_static, plugins):
        self.name = name
        self.links = links
        self.joints = joints
        self.sensors = sensors
        self.is_static = is_static
        self.plugins = plugins

    @property
    def link_names(self):
        return list(self.links)

    @property
    def gravity_links(self):
        """Names of the links gravity acts on."""
        return [n for n, link in self.links.items() if link.gravity]

    @property
    def collision_links(self):
        """Names of the links that have collision geometry."""
        return [n for n, link in self.links.items() if link.collisions]

    @property
    def has_gravity(self):
        return bool(self.gravity_links)

    @property
    def has_collisions(self):
        return bool(self.collision_links)

    @property
    def root_link(self):
        """The link that is no joint's child (Gazebo's canonical body)."""
        children = set(j[3] for j in self.joints)
        for name in self.links:
            if name not in children:
                return name
        return None


def _float(text, what):
    try:
        return float(text)
    except (TypeError, ValueError):
        raise UrdfError('%s: not a number: %r' % (what, text))


def _floats(text, what):
    return tuple(_float(v, what) for v in (text or '').split())


def _origin(parent, what):
    origin = parent.find('origin')
    if origin is None:
        return (0.0, 0.0, 0.0), (0.0, 0.0, 0.0)
    xyz = _floats(origin.get('xyz', '0 0 0'), what + ' origin xyz')
    rpy = _floats(origin.get('rpy', '0 0 0'), what + ' origin rpy')
    if len(xyz) != 3 or len(rpy) != 3:
        raise UrdfError('%s: origin xyz and rpy need 3 numbers each' % what)
    return xyz, rpy


def _geometry(parent, what):
    origin = _origin(parent, what)
    geom = parent.find('geometry')
    if geom is None or len(geom) == 0:
        raise UrdfError('%s has no <geometry>' % what)
    shape = geom[0]
    if shape.tag == 'box':
        size = _floats(shape.get('size'), what + ' box size')
        if len(size) != 3:
            raise UrdfError('%s: box size needs 3 numbers' % what)
        return Geometry('box', size, origin)
    if shape.tag == 'cylinder':
        return Geometry('cylinder', (_float(shape.get('radius'), what + ' radius'),
                                     _float(shape.get('length'), what + ' length')), origin)
    if shape.tag == 'sphere':
        return Geometry('sphere', (_float(shape.get('radius'), what + ' radius'),), origin)
    if shape.tag == 'mesh':
        scale = _floats(shape.get('scale', '1 1 1'), what + ' mesh scale')
        return Geometry('mesh', (shape.get('filename', ''), scale), origin)
    raise UrdfError('%s: unknown geometry <%s>' % (what, shape.tag))


def _gravity_setting(gazebo):
    """True/False if this <gazebo> block sets gravity, else None (later blocks win, as in Gazebo)."""
    value = None
    for child in gazebo:
        text = (child.text or '').strip().lower()
        if child.tag == 'gravity':
            if text in _FALSE:
                value = False
            elif text in _TRUE:
                value = True
            else:
                raise UrdfError('<gravity> must be 0/1/true/false, got %r' % child.text)
        elif child.tag == 'turnGravityOff':
            if text in _TRUE:
                value = False
            elif text in _FALSE:
                value = True
            else:
                raise UrdfError('<turnGravityOff> must be true/false, got %r' % child.text)
    return value


def _sensor(elem, link):
    plugins = tuple(p.get('filename', '') for p in elem.findall('plugin'))
    rate = elem.findtext('update_rate')
    camera = None
    cam = elem.find('camera')
    if cam is not None:
        image = cam.find('image')
        clip = cam.find('clip')
        camera = {
            'horizontal_fov': _float(cam.findtext('horizontal_fov'), 'camera horizontal_fov'),
            'width': int(_float(image.findtext('width'), 'image width')) if image is not None else None,
            'height': int(_float(image.findtext('height'), 'image height')) if image is not None else None,
            'format': image.findtext('format') if image is not None else None,
            'near': _float(clip.findtext('near'), 'clip near') if clip is not None else None,
            'far': _float(clip.findtext('far'), 'clip far') if clip is not None else None,
        }
    return Sensor(elem.get('name', ''), elem.get('type', ''), link,
                  _float(rate, 'sensor update_rate') if rate is not None else None, plugins, camera)


def parse_urdf(xml):
    """Parse a URDF string into a ``UrdfModel``; raises ``UrdfError`` on anything unreadable."""
    try:
        root = ET.fromstring(xml)
    except ET.ParseError as exc:
        raise UrdfError('not well-formed XML: %s' % exc)
    if root.tag != 'robot':
        raise UrdfError('root element is <%s>, expected <robot>' % root.tag)
    links = collections.OrderedDict()
    raw = {}
    for elem in root.findall('link'):
        name = elem.get('name')
        if not name:
            raise UrdfError('<link> without a name')
        if name in raw:
            raise UrdfError('duplicate link %r' % name)
        collisions = tuple(_geometry(c, 'link %s collision' % name) for c in elem.findall('collision'))
        visuals = tuple(_geometry(v, 'link %s visual' % name) for v in elem.findall('visual'))
        mass = inertia = None
        inertial = elem.find('inertial')
        if inertial is not None:
            m = inertial.find('mass')
            if m is not None:
                mass = _float(m.get('value'), 'link %s mass' % name)
            i = inertial.find('inertia')
            if i is not None:
                inertia = tuple(_float(i.get(k, '0'), 'link %s %s' % (name, k))
                                for k in ('ixx', 'ixy', 'ixz', 'iyy', 'iyz', 'izz'))
        raw[name] = (collisions, visuals, mass, inertia)
    if not raw:
        raise UrdfError('URDF has no <link>')
    joints = []
    for elem in root.findall('joint'):
        parent, child = elem.find('parent'), elem.find('child')
        joints.append((elem.get('name', ''), elem.get('type', ''),
                       parent.get('link') if parent is not None else None,
                       child.get('link') if child is not None else None))
    gravity = dict((name, True) for name in raw)
    sensors = []
    plugins = []
    is_static = False
    for gz in root.findall('gazebo'):
        ref = gz.get('reference')
        if ref is None:  # model-level block
            static = gz.findtext('static')
            if static is not None:
                is_static = static.strip().lower() in _TRUE
            plugins.extend(p.get('filename', '') for p in gz.findall('plugin'))
            continue
        if ref not in raw:
            continue  # joint references and unknown links do not change a link
        setting = _gravity_setting(gz)
        if setting is not None:
            gravity[ref] = setting
        sensors.extend(_sensor(s, ref) for s in gz.findall('sensor'))
    for name, (collisions, visuals, mass, inertia) in raw.items():
        links[name] = Link(name, gravity[name], collisions, visuals, mass, inertia)
    return UrdfModel(root.get('name', ''), links, joints, tuple(sensors), is_static, tuple(plugins))


def set_gravity(xml, enabled):
    """Return ``xml`` with gravity switched on (``enabled``) or off for every link, as ``<gravity>`` tags.

    Existing ``<gravity>`` / ``<turnGravityOff>`` settings of the links are replaced.
    """
    root = ET.fromstring(xml)
    names = [link.get('name') for link in root.findall('link')]
    covered = set()
    for gz in root.findall('gazebo'):
        ref = gz.get('reference')
        if ref not in names:
            continue
        for child in list(gz):
            if child.tag in ('gravity', 'turnGravityOff'):
                gz.remove(child)
        if ref not in covered:
            ET.SubElement(gz, 'gravity').text = '1' if enabled else '0'
            covered.add(ref)
    for name in names:
        if name not in covered:
            gz = ET.SubElement(root, 'gazebo', {'reference': name})
            ET.SubElement(gz, 'gravity').text = '1' if enabled else '0'
    return ET.tostring(root, encoding='unicode')
