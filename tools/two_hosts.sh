#!/bin/bash
# Two ROS "machines" on this one: two network namespaces joined by a veth pair, the "Sphinx host" running
# roscore + sphinx_host.launch (simulated Anafi + interface), the "Gazebo host" running gazebo_host.launch
# (world + mirror + controller [+ scenario]). Every ROS message between the two crosses the veth link, as
# between two PCs; ROS_MASTER_URI / ROS_IP are set per host as docs/two_hosts.md describes.
#
#   tools/two_hosts.sh [--controller mpc|pid|none] [--scenario NAME | --scenario-file PATH]
#                      [--netem "delay 5ms loss 1%" | --userspace-link DELAY_MS,LOSS_PCT] [--single-host]
#                      [--log-dir DIR] [--ready-timeout S] [-- COMMAND [ARGS...]]
#
# Without a COMMAND it runs until Ctrl-C. With one it runs COMMAND on the Gazebo host (its environment:
# ROS_MASTER_URI, ROS_IP, ROS_HOME set) once both launches are up, then stops everything and exits with
# COMMAND's status. --single-host runs both launches in ONE namespace (same script, no link: the baseline).
# --netem adds `tc qdisc ... netem SPEC` on both ends of the link (needs the kernel's sch_netem).
# --userspace-link joins the namespaces by two TUN devices and tools/two_hosts_link.py instead of the veth
# pair: each packet delayed DELAY_MS and dropped with LOSS_PCT % per direction (netem's job in user space,
# for kernels without sch_netem; 0,0 = the user-space link alone, its own cost).
# Needs root (or CAP_NET_ADMIN) and iproute2; exits 77 with "SKIP: reason" when they are missing, 78 when
# --netem is asked for and the kernel has no netem. Run inside env.bash (ROS on PATH). Namespaces, veth and
# processes are named/owned per run (suffix = this script's PID) and removed on exit, so parallel runs and
# the machine's own network are untouched; addresses (10.213.0.1/30 Sphinx, .2 Gazebo) exist only inside
# the namespaces. Logs: LOG_DIR/{roscore,sphinx_host,gazebo_host}.log (default a fresh mktemp folder under TMPDIR).
set -u

CONTROLLER=mpc
SCENARIO=
SCENARIO_FILE=
NETEM=
USERSPACE=
SINGLE=0
LOG_DIR=
READY_TIMEOUT=60
CMD=()
while [ $# -gt 0 ]; do
    case "$1" in
        --controller) CONTROLLER=$2; shift 2 ;;
        --scenario) SCENARIO=$2; shift 2 ;;
        --scenario-file) SCENARIO_FILE=$2; shift 2 ;;
        --netem) NETEM=$2; shift 2 ;;
        --single-host) SINGLE=1; shift ;;
        --log-dir) LOG_DIR=$2; shift 2 ;;
        --ready-timeout) READY_TIMEOUT=$2; shift 2 ;;
        --) shift; CMD=("$@"); break ;;
        --userspace-link) USERSPACE=$2; shift 2 ;;
        -h|--help) awk 'NR > 1 && /^#/ {sub(/^# ?/, ""); print; next} NR > 1 {exit}' "$0"; exit 0 ;;
        *) echo "two_hosts.sh: unknown argument $1 (see --help)" >&2; exit 2 ;;
    esac
done

skip() { echo "SKIP: $*" >&2; exit 77; }
[ "$(id -u)" = 0 ] || skip "two_hosts.sh needs root (network namespaces); running as uid $(id -u)"
command -v ip >/dev/null 2>&1 || skip "iproute2's ip is not installed"
command -v roslaunch >/dev/null 2>&1 || { echo "two_hosts.sh: roslaunch not on PATH (source env.bash)" >&2; exit 2; }

TAG=ah$$
NS_S=${TAG}s                     # the Sphinx host
NS_G=${TAG}g                     # the Gazebo host
IF_S=${TAG}s0
IF_G=${TAG}g0
IP_S=10.213.0.1
IP_G=10.213.0.2
[ "$SINGLE" = 1 ] && { NS_G=$NS_S; IP_G=$IP_S; }
MASTER=http://$IP_S:11311
LOG_DIR=${LOG_DIR:-$(mktemp -d -t two_hosts.XXXXXX)}
mkdir -p "$LOG_DIR"
PIDS=()

stop_group() {   # stop_group PID: SIGINT to its process group, SIGKILL after 10 s
    local pid=$1 i
    kill -INT -- "-$pid" 2>/dev/null || return 0
    for i in $(seq 50); do kill -0 -- "-$pid" 2>/dev/null || return 0; sleep 0.2; done
    kill -KILL -- "-$pid" 2>/dev/null
    wait "$pid" 2>/dev/null
}
cleanup() {
    trap - EXIT INT TERM
    local i
    # last started first: the launches, then roscore, then the link they talk over
    for ((i = ${#PIDS[@]} - 1; i >= 0; i--)); do stop_group "${PIDS[$i]}"; done
    # roslaunch starts each node in its own session: whatever is left in our namespaces is ours, end it
    local ns left
    for ns in "$NS_S" "$NS_G"; do
        left=$(ip netns pids "$ns" 2>/dev/null)
        [ -n "$left" ] && kill -TERM $left 2>/dev/null
    done
    sleep 1
    for ns in "$NS_S" "$NS_G"; do
        left=$(ip netns pids "$ns" 2>/dev/null)
        [ -n "$left" ] && kill -KILL $left 2>/dev/null
    done
    ip netns del "$NS_S" 2>/dev/null
    [ "$NS_G" != "$NS_S" ] && ip netns del "$NS_G" 2>/dev/null
    return 0
}
trap 'exit 130' INT TERM
trap cleanup EXIT

ip netns add "$NS_S" 2>"$LOG_DIR/netns.err" || skip "ip netns unavailable: $(cat "$LOG_DIR/netns.err")"
ip -n "$NS_S" link set lo up
if [ "$SINGLE" = 1 ]; then
    # one host: its address on the loopback device (no link)
    ip -n "$NS_S" addr add "$IP_S/32" dev lo
elif [ -n "$USERSPACE" ]; then
    ip netns add "$NS_G"
    ip -n "$NS_G" link set lo up
    setsid python "$(dirname "$0")/two_hosts_link.py" "$NS_S" "$IF_S" "$NS_G" "$IF_G" \
        --delay-ms "${USERSPACE%%,*}" --loss-pct "${USERSPACE##*,}" --ready-file "$LOG_DIR/link.ready" \
        >"$LOG_DIR/link.log" 2>&1 &
    PIDS+=($!)
    for i in $(seq 100); do [ -e "$LOG_DIR/link.ready" ] && break; sleep 0.1; done
    [ -e "$LOG_DIR/link.ready" ] || { echo "two_hosts.sh: user-space link did not start:" >&2; cat "$LOG_DIR/link.log" >&2; exit 1; }
    ip -n "$NS_S" addr add "$IP_S/30" dev "$IF_S"
    ip -n "$NS_G" addr add "$IP_G/30" dev "$IF_G"
    ip -n "$NS_S" link set "$IF_S" up
    ip -n "$NS_G" link set "$IF_G" up
else
    ip netns add "$NS_G"
    ip -n "$NS_G" link set lo up
    ip link add "$IF_S" netns "$NS_S" type veth peer name "$IF_G" netns "$NS_G" \
        || { echo "two_hosts.sh: cannot create the veth pair" >&2; exit 1; }
    ip -n "$NS_S" addr add "$IP_S/30" dev "$IF_S"
    ip -n "$NS_G" addr add "$IP_G/30" dev "$IF_G"
    ip -n "$NS_S" link set "$IF_S" up
    ip -n "$NS_G" link set "$IF_G" up
    if [ -n "$NETEM" ]; then
        command -v tc >/dev/null 2>&1 || { echo "two_hosts.sh: tc (iproute2) not installed" >&2; exit 78; }
        for end in "$NS_S:$IF_S" "$NS_G:$IF_G"; do
            if ! ip netns exec "${end%%:*}" tc qdisc add dev "${end##*:}" root netem $NETEM 2>"$LOG_DIR/netem.err"; then
                echo "two_hosts.sh: tc netem unavailable: $(cat "$LOG_DIR/netem.err") (kernel module sch_netem missing?)" >&2
                exit 78
            fi
        done
    fi
fi

# run_on NS IP NAME CMD...: CMD in namespace NS as host IP, its own process group, output to LOG_DIR/NAME.log
run_on() {
    local ns=$1 ip=$2 name=$3
    shift 3
    mkdir -p "$LOG_DIR/ros_home_$name"
    setsid ip netns exec "$ns" env -u ROS_HOSTNAME ROS_MASTER_URI="$MASTER" ROS_IP="$ip" \
        ROS_HOME="$LOG_DIR/ros_home_$name" ROS_LOG_DIR="$LOG_DIR/ros_home_$name/log" \
        "$@" >"$LOG_DIR/$name.log" 2>&1 &
    PIDS+=($!)
}
in_ns() {   # in_ns NS IP CMD...: CMD in the foreground as that host
    local ns=$1 ip=$2
    shift 2
    ip netns exec "$ns" env -u ROS_HOSTNAME ROS_MASTER_URI="$MASTER" ROS_IP="$ip" ROS_HOME="$LOG_DIR/ros_home_cmd" "$@"
}

ARGS=(controller:="$CONTROLLER")
[ -n "$SCENARIO" ] && ARGS+=(scenario:="$SCENARIO")
[ -n "$SCENARIO_FILE" ] && ARGS+=(scenario_file:="$SCENARIO_FILE")
ARGS+=(out_dir:="$LOG_DIR")

run_on "$NS_S" "$IP_S" roscore roscore -p 11311
deadline=$((SECONDS + READY_TIMEOUT))
until in_ns "$NS_G" "$IP_G" rosparam get /rosdistro >/dev/null 2>&1; do
    [ $SECONDS -ge $deadline ] && { echo "two_hosts.sh: roscore not reachable at $MASTER from the Gazebo host" >&2; tail -5 "$LOG_DIR/roscore.log" >&2; exit 1; }
    sleep 0.5
done
run_on "$NS_S" "$IP_S" sphinx_host roslaunch --wait anafi_sim sphinx_host.launch
run_on "$NS_G" "$IP_G" gazebo_host roslaunch --wait anafi_sim gazebo_host.launch "${ARGS[@]}"
echo "two_hosts.sh: Sphinx host $NS_S ($IP_S, roscore), Gazebo host $NS_G ($IP_G)$([ "$SINGLE" = 1 ] && echo ' [single host]')$([ -n "$NETEM" ] && echo " netem: $NETEM")$([ -n "$USERSPACE" ] && echo " user-space link: delay ms,loss % $USERSPACE"); logs in $LOG_DIR" >&2

if [ ${#CMD[@]} -eq 0 ]; then
    echo "two_hosts.sh: running, Ctrl-C stops. A shell on the Gazebo host: ip netns exec $NS_G env ROS_MASTER_URI=$MASTER ROS_IP=$IP_G bash" >&2
    wait
    exit 0
fi
in_ns "$NS_G" "$IP_G" "${CMD[@]}"
exit $?
