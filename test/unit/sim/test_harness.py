"""anafi_sim.processes: free ports, process groups and their teardown, XML-RPC master lookups, CPU accounting."""
import os
import socket
import sys
import threading
import time
from xmlrpc.server import SimpleXMLRPCServer

import pytest

from anafi_sim import processes

psutil = pytest.importorskip('psutil')


def test_free_port_is_bindable_and_respects_a_range():
    for port in (processes.free_port(), processes.free_port(20000, 20100)):
        s = socket.socket()
        s.bind(('127.0.0.1', port))
        s.close()
    assert 20000 <= processes.free_port(20000, 20100) < 20100
    taken = socket.socket()
    taken.bind(('127.0.0.1', 0))
    port = taken.getsockname()[1]
    with pytest.raises(RuntimeError):
        processes.free_port(port, port + 1)
    taken.close()


def test_wait_for_and_require():
    t0 = time.time()
    assert processes.wait_for(lambda: time.time() > t0 + 0.1, 2.0)
    assert not processes.wait_for(lambda: False, 0.1)
    with pytest.raises(TimeoutError, match='the impossible\nnothing'):
        processes.require(lambda: False, 0.1, 'the impossible', lambda: 'nothing')


def _pids_alive(pids):
    return [p for p in pids if psutil.pid_exists(p) and psutil.Process(p).status() != psutil.STATUS_ZOMBIE]


def test_stop_ends_the_group_and_children_in_other_sessions(tmp_path):
    # a leader ignoring SIGINT and SIGTERM, with a child that escaped into a session of its own (as roslaunch's nodes)
    script = ('import os, signal, subprocess, sys, time\n'
              'signal.signal(signal.SIGINT, signal.SIG_IGN); signal.signal(signal.SIGTERM, signal.SIG_IGN)\n'
              'subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"], start_new_session=True)\n'
              'print("up", flush=True); time.sleep(60)\n')
    log = str(tmp_path / 'leader.log')
    proc = processes.start([sys.executable, '-c', script], log=log)
    assert processes.wait_for(lambda: len(processes.descendants(proc.pid)) == 1 and 'up' in open(log).read(), 10.0)
    child = processes.descendants(proc.pid)[0].pid
    assert os.getpgid(proc.pid) == proc.pid and os.getpgid(child) != proc.pid
    t0 = time.monotonic()
    assert processes.stop(proc, grace=0.3, kill_wait=0.5) == []
    # behaviour: stop escalated instead of waiting for the 60 s the leader and its child would live
    assert time.monotonic() - t0 < 30.0
    assert proc.poll() is not None and not _pids_alive([child])


def test_stop_a_plain_child_that_shuts_down_on_sigint():
    import subprocess
    proc = subprocess.Popen([sys.executable, '-c', 'import time; time.sleep(60)'])   # not a group leader
    time.sleep(0.2)
    assert processes.stop(proc, grace=5.0) == []
    assert proc.returncode not in (None, -9)          # KeyboardInterrupt, not SIGKILL


def test_processes_keep_logs_and_stop_all(tmp_path):
    procs = processes.Processes(str(tmp_path), grace=0.5)
    a = procs.start('a', [sys.executable, '-c', 'print("hello a", flush=True); import time; time.sleep(60)'])
    procs.start('b', [sys.executable, '-c', 'import time; time.sleep(60)'])
    assert processes.wait_for(lambda: 'hello a' in procs.log_tail('a'), 10.0)
    assert procs.log_tail('nobody') == ''
    assert procs.stop('a') == [] and a.poll() is not None
    assert [name for name, _, _ in procs.started] == ['b']
    b = procs.started[0][1]
    assert procs.stop_all() == [] and b.poll() is not None and procs.started == []


def test_node_and_master_pid_over_xmlrpc():
    node = SimpleXMLRPCServer(('127.0.0.1', 0), logRequests=False, allow_none=True)
    node.register_function(lambda caller: (1, 'pid', 4242), 'getPid')
    node_uri = 'http://127.0.0.1:%d/' % node.server_address[1]
    master = SimpleXMLRPCServer(('127.0.0.1', 0), logRequests=False, allow_none=True)
    master.register_function(lambda caller: (1, 'pid', 99), 'getPid')
    master.register_function(lambda caller, name: (1, '', node_uri) if name == '/talker' else (-1, 'unknown', ''),
                             'lookupNode')
    master_uri = 'http://127.0.0.1:%d/' % master.server_address[1]
    for server in (node, master):
        threading.Thread(target=server.serve_forever, daemon=True).start()
    try:
        assert processes.master_pid(master_uri) == 99
        assert processes.node_pid('/talker', master_uri) == 4242
        assert processes.node_pid('/nobody', master_uri) is None
        assert processes.master_pid('http://127.0.0.1:%d/' % processes.free_port()) is None
    finally:
        node.shutdown()
        master.shutdown()


def test_ros_env():
    env = processes.ros_env('http://127.0.0.1:1234', ros_home='/tmp/h', base={'PATH': '/bin'}, X='1')
    assert env == {'PATH': '/bin', 'ROS_MASTER_URI': 'http://127.0.0.1:1234', 'ROS_HOME': '/tmp/h',
                   'ROS_LOG_DIR': '/tmp/h', 'PYTHONUNBUFFERED': '1', 'X': '1'}


def test_cpu_accounting_of_a_busy_process():
    proc = processes.start([sys.executable, '-c', 'import time\nt = time.time()\nwhile time.time() - t < 30: pass'])
    try:
        tree = processes.TreeCpu(proc.pid)
        window = processes.CpuWindow({'busy': tree}, 0.6).run()
        assert window.share('busy') > 5.0 and window.count('busy') == 1 and window.count('busy', 'root') == 1
        [(role, cpu)] = tree.processes()                # one process: its CPU is the tree's
        assert role == 'root' and 100.0 * cpu / window.wall == window.share('busy')
        snap0 = processes.cpu_snapshot({'busy': proc.pid})
        time.sleep(0.3)
        delta = processes.cpu_delta(snap0, processes.cpu_snapshot({'busy': proc.pid}))
        assert delta['per_node']['busy'] > 0.0 and delta['total'] == delta['per_node']['busy']
    finally:
        processes.stop(proc, grace=0.5)
    assert processes.cpu_seconds(proc.pid) != processes.cpu_seconds(proc.pid)     # gone: NaN
    assert processes.cpu_model()
