#!/usr/bin/env bash
# The main job (run inside env.bash by `make demo`): a private ROS master on a free port, then the
# tracking demo (the mirrored Anafi following a circle; CONTROLLER=mpc|pid|preview_mpc; CONDITIONS=real_flights: in
# the wind of the paper's outdoor flights). DEMO_LAUNCH/DEMO_ARGS override.
#
# A run that ended well: the experiment monitor (the required node) ends roslaunch as Ctrl-C would and
# says "finished: ending the launch" -> a green "[demo] finished". A run that failed: the monitor exits
# non-zero, roslaunch prints a red "REQUIRED process [...] has died!" -> a red line naming the node and
# how it died (exit status 1). A bad or undeclared launch argument: the check's one line naming it, then it
# ends roslaunch (exit status 143).
set -euo pipefail
port=$(python -c 'from anafi_sim.processes import free_port; print(free_port())')
export ROS_MASTER_URI="http://127.0.0.1:$port"
export ROS_HOSTNAME=127.0.0.1
echo "[demo] ROS master at $ROS_MASTER_URI"
set +e
# each run writes into its own folder ~/.ros/anafi_demo/<run>-<date>-<time>-<pid> (~/.ros/anafi_demo/latest)
run_id="$(date +%Y%m%d-%H%M%S)-$$"
# shellcheck disable=SC2086
roslaunch anafi_sim ${DEMO_LAUNCH:-demo.launch} ${DEMO_ARGS:-controller:=${CONTROLLER:-mpc} ${CONDITIONS:+conditions:=$CONDITIONS}} \
    $([ -z "${DEMO_LAUNCH:-}" ] && echo "run_id:=$run_id") 2>&1 \
    | python -u -c '
import re, sys
RED, GREEN, OFF = "\033[1;31m", "\033[1;32m", "\033[0m"
ESC = re.compile(r"\x1b\[[0-9;]*m")
required, status = None, 0
for line in sys.stdin:
    plain = ESC.sub("", line)
    if "finished: ending the launch" in plain:       # the monitor ends roslaunch as Ctrl-C would
        sys.stdout.write(line)
        sys.stdout.write("%s[demo] finished%s\n" % (GREEN, OFF))
        continue
    m = re.search(r"REQUIRED process \[(.+?)\] has died!", plain)
    if m:
        required = m.group(1).rsplit("-", 1)[0]      # "anafi/experiment_monitor-9" -> node name
        continue
    if required is not None and plain.strip():
        if "finished cleanly" in plain:
            sys.stdout.write("%s[demo] finished: the required node %s ended the launch cleanly%s\n"
                             % (GREEN, required, OFF))
        else:
            sys.stdout.write("%s[demo] FAILED: the REQUIRED node %s died (%s); see its log above%s\n"
                             % (RED, required, plain.strip(), OFF))
            status = 1
        required = None
        continue
    sys.stdout.write(line)
sys.exit(status)
'
codes=("${PIPESTATUS[@]}")
if [ "${codes[1]}" != 0 ]; then exit "${codes[1]}"; fi
exit "${codes[0]}"
