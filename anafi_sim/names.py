"""Default topic and service names and the tf frame names, in one place for every node (ROS glue, no rospy needed).

Names without a leading '/' are relative to the node's namespace, the drone's (/<drone>/, default
/anafi/); nodes take most of them as ~params with these defaults. Gazebo's names are relative to its
namespace (~gazebo_namespace, default /gazebo): ``gazebo(name, namespace)``.
"""

# --- the anafi_ros bridge (simulated by anafi_sim_node.py; on a real drone, anafi_ros) ----------------
COMMAND = 'drone/rpyt'                  # olympe_bridge/PilotingCommand, in
TAKEOFF = 'drone/takeoff'               # std_msgs/Empty, in
LAND = 'drone/land'                     # std_msgs/Empty, in
ESTIMATE = 'drone/odom'                 # nav_msgs/Odometry: the drone's own estimate
POSE_ENU = 'drone/pose_enu'             # geometry_msgs/PoseStamped
ATTITUDE = 'drone/attitude'             # geometry_msgs/QuaternionStamped, north-west-up referenced
SPEED = 'drone/speed'                   # geometry_msgs/Vector3Stamped, world north-west-up (as the real bridge)
ALTITUDE = 'drone/altitude'             # std_msgs/Float32
RPY = 'drone/rpy'                       # geometry_msgs/Vector3Stamped [deg]
CAMERA_ATTITUDE = 'camera/attitude'     # geometry_msgs/QuaternionStamped, frame "/body" (NWU-referenced)
CAMERA_BASE_ATTITUDE = 'camera/base/attitude'  # the same without the gimbal's tilt (both real bridges' name)
STATE_ENU = 'position_control/state_enu'  # anafi_control/State: the reference implementation's bridge fork
DRONE_STATE = 'drone/state'             # std_msgs/String (latched): landed | taking_off | flying | landing
SIM_TRUTH = 'sim/truth'                 # nav_msgs/Odometry: the simulator's ground truth (anafi_sim only)

# --- the paper's Interface (interface_node.py) ----------------------------------------------------------
GROUND_TRUTH = 'ground_truth/odom'      # nav_msgs/Odometry, twist in the body frame
SPHINX_DATA = 'sphinx/drone_data'       # sphinx_with_gazebo/Sphinx: the reference implementation's type and name
DRONE_DATA = 'ground_truth/drone_data'  # anafi_sim/DroneData: every telemetry value, with a header

# --- control and experiments ----------------------------------------------------------------------------
WAYPOINT = 'position_control/waypoint'  # anafi_sim/Waypoint: the controllers' input
TRAJECTORY_BEGIN = 'trajectory/begin'   # std_msgs/Header (latched): start of the measured segment
TRAJECTORY_END = 'trajectory/end'       # std_msgs/Header (latched): its end
TRAJECTORY_STATUS = 'trajectory/status'  # std_msgs/String (latched YAML)
TRAJECTORY_COMMAND = 'trajectory_generator/command'  # std_msgs/String: start | stop | restart | switch NAME
EVALUATION_SUMMARY = 'evaluation/summary'  # std_msgs/String (latched YAML)
MPC_STATS = 'mpc/stats'                 # anafi_sim/MpcStats
TUNING_CHANGES = 'tuning/changes'       # std_msgs/String YAML, one per live tuning change (ros/reconfigure.py)
REFERENCE_PREVIEW = 'command/trajectory'  # trajectory_msgs/MultiDOFJointTrajectory: the generator's preview
PID_NAMESPACE = 'pid'                   # the distributed PID framework's loop topics: pid/<loop>/..., pid/pid_enable
PID_ENABLE = 'pid_enable'               # std_msgs/Bool (latched), under PID_NAMESPACE

# --- global ---------------------------------------------------------------------------------------------
CLOCK = '/clock'
DIAGNOSTICS = '/diagnostics'
TF = '/tf'                              # tf2_msgs/TFMessage

# --- tf frames (REP-105; docs/nodes.md#frames) ------------------------------------------------------------
# the drone's estimate: map -> <drone>/odom -> <drone>/base_link (the simulator); the ground truth:
# world -> <drone>/stability_axes -> <drone>/base_link_gt -> <drone>/camera (the interface). world -> map is
# the identity: the simulated estimate is expressed in the simulation's world frame.
WORLD_FRAME = 'world'                   # the simulation's world (Sphinx, Gazebo), ENU (REP-103)
MAP_FRAME = 'map'                       # REP-105's world-fixed frame of the drones' estimates


def odom_frame(drone):
    """REP-105's odom frame of ``drone``: the parent of its estimated base_link."""
    return drone + '/odom'


def base_link_frame(drone):
    """The body frame (FLU) of ``drone`` as its own estimate places it."""
    return drone + '/base_link'


def ground_truth_frame(drone):
    """The body frame (FLU) of ``drone`` as the ground truth places it (never the estimate's base_link)."""
    return drone + '/base_link_gt'

# --- Gazebo's ROS API (gazebo_ros, or the kinematic world), relative to GAZEBO_NAMESPACE ----------------
GAZEBO_NAMESPACE = '/gazebo'
SPAWN_URDF_MODEL = 'spawn_urdf_model'   # service gazebo_msgs/SpawnModel
SPAWN_SDF_MODEL = 'spawn_sdf_model'     # service gazebo_msgs/SpawnModel
DELETE_MODEL = 'delete_model'           # service gazebo_msgs/DeleteModel
SET_MODEL_STATE = 'set_model_state'     # service gazebo_msgs/SetModelState and topic gazebo_msgs/ModelState
GET_MODEL_STATE = 'get_model_state'     # service gazebo_msgs/GetModelState
GET_MODEL_PROPERTIES = 'get_model_properties'  # service gazebo_msgs/GetModelProperties
MODEL_STATES = 'model_states'           # topic gazebo_msgs/ModelStates
CONTACTS = 'contacts'                   # topic std_msgs/String (JSON contact events; the kinematic world)


def pid_topic(name, namespace=PID_NAMESPACE):
    """A topic of the distributed PID framework (``name`` relative to its namespace), e.g. 'pid/pid_enable'."""
    return '%s/%s' % (namespace.rstrip('/'), name)


def gazebo(name, namespace=GAZEBO_NAMESPACE):
    """``name`` (one of the Gazebo names above) under ``namespace``, e.g. '/gazebo/spawn_urdf_model'."""
    return '%s/%s' % (namespace.rstrip('/'), name)
