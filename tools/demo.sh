#!/usr/bin/env bash
# The main job (run inside env.bash by `make demo`): a private ROS master on a free port, then the
# tracking demo (the mirrored Anafi following a circle; CONTROLLER=mpc|pid). DEMO_LAUNCH/DEMO_ARGS override.
set -euo pipefail
port=$(python -c 'from anafi_sim.harness import free_port; print(free_port())')
export ROS_MASTER_URI="http://127.0.0.1:$port"
export ROS_HOSTNAME=127.0.0.1
echo "[demo] ROS master at $ROS_MASTER_URI"
exec roslaunch anafi_sim ${DEMO_LAUNCH:-demo.launch} ${DEMO_ARGS:-controller:=${CONTROLLER:-mpc}}
