"""Everything that speaks Gazebo's API: the mirror, keeping models spawned, the kinematic world stand-in, URDF facts, the airship path."""
