"""bench_interface.py parts ``interface`` and ``paper``: the real interface node (and the paper's 24 pipelines)
on a private ROS master, fed by a TelemetryServer hosted here; latency and CPU per measurement window.

Window A: ``interface_node.py`` alone (its ``~telemetry_command`` is the stand-in CLI
``tlm_data_logger.py -r 0`` pointed at our server). Window B: ``paper_interface.py`` beside it on the
same server. CPU = user+sys of each whole process tree (processes.TreeCpu, polled every second).
"""
import os
import shutil
import sys
import tempfile
import time

from anafi_sim import processes
from anafi_sim.telemetry.protocol import key_map
from anafi_sim.telemetry.server import TelemetryServer
from interface_samples import flight_samples
from interface_stream import Feeder, Recorder, analyse

BENCH = os.path.dirname(os.path.abspath(__file__))
CLI_SCRIPT = os.path.join(os.path.dirname(BENCH), 'anafi_sim', 'scripts', 'tlm_data_logger.py')
NODE_SCRIPT = os.path.join(os.path.dirname(BENCH), 'anafi_sim', 'scripts', 'interface_node.py')
PAPER_SCRIPT = os.path.join(BENCH, 'paper_interface.py')


def role_of(p, is_root):
    """Role a process of an interface's tree is counted under: node, CLI, grep, sh or its name."""
    if is_root:
        return 'node'
    try:
        name = p.name()
        cmd = ' '.join(p.cmdline())
    except processes.psutil.Error:
        return 'other'
    if 'tlm_data_logger' in cmd and name not in ('sh', 'dash', 'bash'):
        return 'CLI'
    if name == 'grep':
        return 'grep'
    if name in ('sh', 'dash', 'bash'):
        return 'sh'
    return name


def bench_ros(parts, duration, rate, tcp_nodelay, log):
    """Parts 'interface' and/or 'paper'; returns a dict of results."""
    try:
        import rospy
        from anafi_sim.msg import DroneData
    except ImportError as exc:
        raise SystemExit('cannot import ROS / the generated messages (%s): source env.bash (or the catkin '
                         'workspace devel/setup.bash) first' % exc)
    if shutil.which('roscore') is None:
        raise SystemExit('roscore not found on PATH: source env.bash first')
    results = {}
    tmp = tempfile.mkdtemp(prefix='bench_interface_')
    procs = processes.Processes(tmp)
    server = TelemetryServer(host='127.0.0.1', port=0)
    feeder = None
    ros_started = False
    try:
        uri, env = processes.private_master(procs, tmp, join=True)
        log('roscore at %s (logs in %s)' % (uri, tmp))
        rospy.init_node('bench_interface', disable_signals=True)
        ros_started = True

        port = server.start()
        epoch = float(int(time.time())) - 10.0
        feeder = Feeder(server, flight_samples(3000, seed=2), rate, epoch)
        feeder.start()
        cli = '%s -r 0' % CLI_SCRIPT      # the package's stand-in (a known tool: run as is, no interpreter)

        ours_rx, paper_rx = Recorder(), Recorder()
        rospy.Subscriber('/anafi/ground_truth/drone_data', DroneData, ours_rx, queue_size=1000, tcp_nodelay=tcp_nodelay)
        rospy.set_param('/anafi/interface/telemetry_command', '%s inet:127.0.0.1:%d' % (cli, port))
        rospy.set_param('/anafi/interface/rate', float(rate))
        node_env = dict(env, ROS_NAMESPACE='/anafi')
        log('starting interface_node.py (telemetry command: %s inet:127.0.0.1:%d)' % (cli, port))
        node = procs.start('interface', [sys.executable, NODE_SCRIPT, '__name:=interface'], node_env)
        processes.require(lambda: ours_rx.count_since(time.time() - 1.0) > 0.8 * rate, 30, 'interface messages',
                        lambda: procs.log_tail('interface'))
        time.sleep(3.0)  # warm-up
        ours_tree = processes.TreeCpu(node.pid, role_of)

        if 'interface' in parts:
            log('window A: interface alone, %.0f s ...' % duration)
            win = processes.CpuWindow({'ours': ours_tree}, duration).run()
            results['A'] = dict(window=win, ours=analyse(ours_rx.rx, win.t0, win.t1, feeder),
                                clients=server.client_count)
        if 'paper' in parts:
            rospy.Subscriber('/paper/sphinx/drone_data', DroneData, paper_rx, queue_size=1000,
                             tcp_nodelay=tcp_nodelay)
            for k, v in (('cli', cli), ('host', '127.0.0.1'), ('port', port), ('rate', float(rate))):
                rospy.set_param('/paper/paper_interface/' + k, v)
            log('starting paper_interface.py (24 pipelines "%s inet:127.0.0.1:%d | grep --line-buffered KEY")'
                % (cli, port))
            paper = procs.start('paper', [sys.executable, PAPER_SCRIPT, '__name:=paper_interface'],
                                dict(env, ROS_NAMESPACE='/paper'))
            n_keys = len(key_map())
            processes.require(lambda: server.client_count >= 1 + n_keys and paper_rx.rx and
                            paper_rx.rx[-1][1].timeStamp > 0 and
                            paper_rx.count_since(time.time() - 1.0) > 0.8 * rate, 60, 'paper pipelines',
                            lambda: procs.log_tail('paper'))
            time.sleep(3.0)
            log('window B: ours and the paper\'s side by side, %.0f s ...' % duration)
            win = processes.CpuWindow({'ours': ours_tree, 'paper': processes.TreeCpu(paper.pid, role_of)},
                                    duration).run()
            results['B'] = dict(window=win, ours=analyse(ours_rx.rx, win.t0, win.t1, feeder),
                                paper=analyse(paper_rx.rx, win.t0, win.t1, feeder), clients=server.client_count)
        results['late_ticks'] = feeder.late
        results['ticks'] = len(feeder.times)
        results['slow_drops'] = server.clients_dropped_slow
    finally:
        if feeder is not None:
            feeder.stop()
        procs.stop_all()
        server.stop()
        if ros_started:
            rospy.signal_shutdown('benchmark done')
        shutil.rmtree(tmp, ignore_errors=True)
    return results
