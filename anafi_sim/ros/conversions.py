"""Message conversions shared by the nodes (ROS glue): geometry_msgs builders, the one nav_msgs/Odometry ->
numbers conversion (``anafi_control.frames.odometry_to_world`` on the message's fields), and the controllers'
inputs (Odometry + Waypoint -> ``on_state`` / ``on_waypoint`` of a controller or an input gate)."""
import rospy
from geometry_msgs.msg import Pose, TransformStamped, Twist
from nav_msgs.msg import Odometry

from anafi_control import frames
from anafi_control.contract import LEVEL_WARN, LIMIT_DEFAULTS, Envelope
from anafi_control.waypoint_admission import DEFAULTS as ADMISSION_DEFAULTS, WaypointAdmission
from anafi_sim.ros import waypoints


def pose(position, orientation):
    """Pose from (x, y, z) [m] and a quaternion (x, y, z, w)."""
    p = Pose()
    p.position.x, p.position.y, p.position.z = position
    p.orientation.x, p.orientation.y, p.orientation.z, p.orientation.w = orientation
    return p


def transform(stamp, parent, child, translation, rotation):
    """TransformStamped ``parent`` -> ``child`` at ``stamp`` from a translation (x, y, z) [m] and a quaternion."""
    t = TransformStamped()
    t.header.stamp = stamp
    t.header.frame_id = parent
    t.child_frame_id = child
    t.transform.translation.x, t.transform.translation.y, t.transform.translation.z = translation
    r = t.transform.rotation
    r.x, r.y, r.z, r.w = rotation
    return t


def twist(linear, angular):
    """Twist from linear (x, y, z) [m/s] and angular (x, y, z) [rad/s] vectors."""
    t = Twist()
    t.linear.x, t.linear.y, t.linear.z = linear
    t.angular.x, t.angular.y, t.angular.z = angular
    return t


def odometry_numbers(msg):
    """(position (x, y, z), orientation (x, y, z, w), linear twist (x, y, z)) of a nav_msgs/Odometry, as
    stored (pose in header.frame_id, twist in child_frame_id): what ``Controller.on_state`` takes."""
    p, q, v = msg.pose.pose.position, msg.pose.pose.orientation, msg.twist.twist.linear
    return (p.x, p.y, p.z), (q.x, q.y, q.z, q.w), (v.x, v.y, v.z)


def odometry_state(msg, twist_frame=None):
    """(position, world velocity, (roll, pitch, yaw)) of a nav_msgs/Odometry, or None when unusable.

    ``twist_frame`` 'child' or 'world'; None = from the message's frame names
    (``anafi_control.frames.odometry_twist_frame``)."""
    if twist_frame is None:
        twist_frame = frames.odometry_twist_frame(msg.header.frame_id, msg.child_frame_id)
    return frames.odometry_to_world(*odometry_numbers(msg), twist_frame=twist_frame)


def waypoint_numbers(msg):
    """(x, y, z [m], vx, vy, vz [m/s], yaw [deg]) of a waypoint of either type (``anafi_sim.ros.waypoints``):
    what ``on_waypoint`` takes."""
    return waypoints.waypoint_numbers(msg)


#: the waypoint source of the messages of an instance of this host (the shared layout's bus: no connection)
LOCAL_SOURCE = 'this host process'


def subscribe_inputs(target, lock, state_topic, waypoint_topic, waypoint_type=waypoints.DEFAULT_WAYPOINT_TYPE,
                     admission=None, ctx=None):
    """Feed ``target.on_state`` / ``target.on_waypoint`` (an ``anafi_control.contract`` Controller or
    InputGate) from nav_msgs/Odometry on ``state_topic`` and waypoints of ``waypoint_type`` (``anafi_sim`` or
    the reference implementation's ``anafi_control``) on ``waypoint_topic``, with the ROS time of receipt,
    under ``lock``. A refused sample is logged (throttled, with the count of ``target.counters``).
    ``admission`` (``anafi_control.waypoint_admission.WaypointAdmission``): waypoints whose header stamp or
    frame it refuses are dropped before the target (counted there, logged throttled); a waypoint type without a
    header (``anafi_control``) is not checked. ``ctx``: the NodeContext of the node instance, which also logs
    (default the process's node). Returns the resolved (state topic, waypoint topic)."""
    if ctx is None:
        resolve, subscribe, me, log = rospy.resolve_name, rospy.Subscriber, rospy.get_name(), rospy
        deferred = {}
    else:       # hosted: off the publisher's thread (the feed waits while the controller solves)
        resolve, subscribe, me, log = ctx.resolve, ctx.subscriber, ctx.name, ctx
        deferred = {'deferred': True}
    resolved = resolve(state_topic), resolve(waypoint_topic)
    subscription = {}

    def source_of(msg):
        """(the XML-RPC URI of the publisher the message's connection was made to, the URIs of every current
        connection): from the master's publisher list, never the header; (LOCAL_SOURCE, None) for a message of
        an instance of this host (no connection), (None, None) when unknown."""
        header = getattr(msg, '_connection_header', None)
        if not header:
            return (LOCAL_SOURCE, None) if ctx is not None else (None, None)
        try:
            sub = subscription['sub']
            connections = list(getattr(sub, 'sub', sub).impl.connections)
        except Exception:     # rospy internals changed: no source check
            return None, None
        endpoint = next((c.endpoint_id for c in connections if c.header is header), None)
        return endpoint, set(c.endpoint_id for c in connections)

    def on_waypoint(msg):
        if admission is not None and hasattr(msg, 'header'):
            source, live = source_of(msg)
            with lock:
                if live is not None and admission.source not in (None, LOCAL_SOURCE) and admission.source not in live:
                    admission.release_source()      # the source left the topic: the next publisher takes over
                ok, why = admission.admit(rospy.get_time(), msg.header.stamp.to_sec(), msg.header.frame_id, source)
                dropped = admission.dropped
            if not ok:
                log.logwarn_throttle(5.0, '%s: waypoint on %s dropped (%d so far): %s'
                                     % (me, resolved[1], dropped, why))
                return
        feed('waypoint', (waypoint_numbers(msg),), resolved[1])

    def feed(kind, numbers, topic):
        with lock:
            ok = getattr(target, 'on_' + kind)(rospy.get_time(), *numbers)
            refused = target.counters['rejected_%ss' % kind]
        if not ok:
            log.logwarn_throttle(5.0, '%s: unusable %s on %s refused (%d so far): %s'
                                 % (me, kind, topic, refused,
                                    'holding position' if kind == 'waypoint' else 'no command'))

    subscribe(state_topic, Odometry, lambda m: feed('state', odometry_numbers(m), resolved[0]),
              queue_size=5, tcp_nodelay=True, **deferred)
    subscription['sub'] = subscribe(waypoint_topic, waypoints.waypoint_class(waypoint_type), on_waypoint,
                                    queue_size=5, tcp_nodelay=True, **deferred)
    return resolved


def waypoint_admission(p):
    """The controllers' ``WaypointAdmission`` from the node's ParamReader ``p``: ~waypoint_max_age [s],
    ~waypoint_frame (defaults ``waypoint_admission.DEFAULTS``); ValueError on bad values."""
    d = ADMISSION_DEFAULTS
    return WaypointAdmission(p.positive('waypoint_max_age', d['waypoint_max_age']),
                             p.ros_name('waypoint_frame', d['waypoint_frame']))


def amend_health(health, admission):
    """``health`` (a contract.Health) with the waypoints ``admission`` dropped since the previous call: WARN
    (at least) and their count in the message; the drop counters added to the values."""
    news = admission.news()
    values = list(health.values) + admission.values()
    if not news:
        return health._replace(values=values)
    return health._replace(level=max(health.level, LEVEL_WARN), message='%s; %s' % (health.message, news),
                           values=values)


def waypoint_limits(p):
    """The controllers' flight envelope (``anafi_control.envelope.Envelope``) from the node's ParamReader ``p``:
    ~geofence_radius, ~min_altitude, ~max_altitude, ~max_waypoint_jump [m], ~max_reference_speed,
    ~max_reference_vertical_speed [m/s], ~max_reference_acceleration [m/s^2], ~max_command_tilt_deg [deg]
    (defaults ``contract.LIMIT_DEFAULTS``); ValueError on bad values (the node exits with a FATAL message)."""
    signed = ('min_altitude', 'max_altitude')
    return Envelope(**dict((k, p.number(k, v) if k in signed else p.number(k, v, minimum=0.0)
                            if k == 'geofence_margin' else p.positive(k, v)) for k, v in LIMIT_DEFAULTS.items()))


def drone_data(msg, s, stamp, frame_id):
    """``msg`` (an anafi_sim/DroneData) filled with the telemetry sample ``s`` (TelemetrySample, SI units, world
    ENU and body FLU frames), stamped ``stamp`` (rospy.Time) in ``frame_id``; returns it."""
    msg.header.stamp = stamp
    msg.header.frame_id = frame_id
    msg.posX, msg.posY, msg.posZ = s.x, s.y, s.z
    msg.velXENU, msg.velYENU, msg.velZENU = s.vx, s.vy, s.vz
    msg.attitudeX, msg.attitudeY, msg.attitudeZ = s.roll, s.pitch, s.yaw
    msg.velXABC, msg.velYABC, msg.velZABC = s.body_vx, s.body_vy, s.body_vz
    msg.angVelXABC, msg.angVelYABC, msg.angVelZABC = s.body_wx, s.body_wy, s.body_wz
    msg.accXABC, msg.accYABC, msg.accZABC = s.body_ax, s.body_ay, s.body_az
    msg.angAccXABC, msg.angAccYABC, msg.angAccZABC = s.body_alpha_x, s.body_alpha_y, s.body_alpha_z
    msg.timeStamp = s.timestamp
    msg.gimbalPitchMotorAngle = s.gimbal_pitch
    msg.gimbalRollMotorAngle = s.gimbal_roll
    return msg
