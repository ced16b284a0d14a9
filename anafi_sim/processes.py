"""Processes (pure Python, no rospy): ports, process groups, private masters, node pids, CPU time.

Used by nodes (the fleet launcher's ports and shutdown, the experiment monitor's controller CPU), the lab's
ROS batch, tools/demo.sh, the rostests and the benchmarks; no core module imports it.

- ports: ``free_port`` (the OS's pick, or a free one in a range);
- processes: ``start`` runs a command in a session (process group) of its own, ``stop`` ends it and
  everything it started: SIGINT to its group (ROS nodes and roslaunch shut down cleanly on it), then
  SIGTERM, SIGKILL, then SIGKILL to the descendants collected meanwhile (roslaunch starts every node
  in a session of its own, out of reach of a signal to its group); ``Processes`` keeps named ones
  with their log files;
- ROS masters over plain XML-RPC: ``master_pid``, ``node_pid``, ``start_master`` (a roscore on a
  free port that is proven to be ours), ``private_master`` (the same with its processes' environment);
- CPU accounting: ``cpu_seconds`` of a process, ``cpu_snapshot`` / ``cpu_delta`` of named pids,
  ``TreeCpu`` of a process tree over a window, ``CpuWindow`` (trees + load + machine busy share),
  ``machine_busy``, ``cpu_model``, ``machine`` (the line a result names its machine and load with).

psutil is optional: without it the descendants are not collected (only the process group is
signalled) and the CPU figures are NaN / unavailable.
"""
import os
import platform
import random
import signal
import socket
import subprocess
import sys
import time
import xmlrpc.client

try:
    import psutil
except ImportError:     # process groups still work; trees and CPU time need psutil
    psutil = None

HARNESS_CALLER = '/anafi_harness'


# ----------------------------------------------------------------------------- waiting, ports
def wait_for(predicate, timeout, step=0.05):
    """Poll ``predicate`` every ``step`` s of wall time until it is true or ``timeout`` s passed; its last value."""
    deadline = time.time() + timeout
    while time.time() < deadline:
        if predicate():
            return True
        time.sleep(step)
    return bool(predicate())


def require(predicate, timeout, what, detail=None, step=0.1):
    """``wait_for``, raising TimeoutError('timed out after N s waiting for <what>' + ``detail()``) when it fails."""
    if not wait_for(predicate, timeout, step):
        raise TimeoutError('timed out after %.0f s waiting for %s\n%s' % (timeout, what, detail() if detail else ''))


def free_port(lo=None, hi=None):
    """A free TCP port on 127.0.0.1: the OS's pick, or a random free one in [lo, hi)."""
    if lo is None:
        s = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        try:
            s.bind(('127.0.0.1', 0))
            return s.getsockname()[1]
        finally:
            s.close()
    candidates = list(range(lo, hi))
    random.shuffle(candidates)
    for port in candidates:
        s = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        try:
            s.bind(('127.0.0.1', port))
            return port
        except OSError:
            continue
        finally:
            s.close()
    raise RuntimeError('no free port in [%d, %d)' % (lo, hi))


def ros_env(master_uri=None, ros_home=None, log_dir=None, base=None, **extra):
    """Environment of a process on the master ``master_uri``: ``base`` (default os.environ) with ROS_MASTER_URI
    (unless None), ROS_HOME and ROS_LOG_DIR (both default to ``ros_home``), unbuffered Python and ``extra``."""
    env = dict(os.environ if base is None else base)
    if master_uri:
        env['ROS_MASTER_URI'] = master_uri
    if ros_home:
        env['ROS_HOME'] = ros_home
    if log_dir or ros_home:
        env['ROS_LOG_DIR'] = log_dir or ros_home
    env['PYTHONUNBUFFERED'] = '1'
    env.update(extra)
    return env


def add_module_paths(env, *modules):
    """Append to ``env``'s PYTHONPATH the site directory of each importable module in ``modules`` (so nodes that
    run under another interpreter, e.g. /usr/bin/python3 relay scripts, find this one's packages); ``env``."""
    paths = [p for p in env.get('PYTHONPATH', '').split(os.pathsep) if p]
    for name in modules:
        try:
            module = __import__(name)
        except ImportError:
            continue
        site = os.path.dirname(os.path.dirname(os.path.abspath(module.__file__)))
        if site not in paths:
            paths.append(site)
    env['PYTHONPATH'] = os.pathsep.join(paths)
    return env


# ----------------------------------------------------------------------------- processes
def start(argv, env=None, log=None, **popen):
    """``subprocess.Popen(argv)`` in a session of its own (so ``stop`` reaches its group); output to ``log``
    (a path, truncated first; a file; or None: discarded), no stdin."""
    out = subprocess.DEVNULL if log is None else log
    if isinstance(log, str):
        out = open(log, 'wb')
    try:
        return subprocess.Popen(argv, env=env, stdin=subprocess.DEVNULL, stdout=out, stderr=subprocess.STDOUT,
                                start_new_session=True, **popen)
    finally:
        if isinstance(log, str):
            out.close()


def descendants(pid):
    """psutil.Process list of every process below ``pid`` (empty without psutil or when it is gone)."""
    if psutil is None:
        return []
    try:
        return psutil.Process(pid).children(recursive=True)
    except psutil.Error:
        return []


def alive(p):
    """Whether the psutil.Process ``p`` still runs (a zombie does not)."""
    try:
        return p.is_running() and p.status() != psutil.STATUS_ZOMBIE
    except psutil.Error:
        return False


def _leads_group(proc):
    try:
        return proc.poll() is None and os.getpgid(proc.pid) == proc.pid
    except OSError:
        return False


def _signal(proc, sig, group):
    """``sig`` to the process group ``proc`` leads (``group``: started by ``start``), else to ``proc`` alone."""
    if proc.poll() is not None:
        return
    try:
        if group:
            os.killpg(proc.pid, sig)
        else:
            proc.send_signal(sig)
    except OSError:
        pass


def stop(proc, grace=3.0, kill_wait=1.0):
    """End the Popen ``proc`` and everything it started; the pids still alive afterwards (normally none).

    SIGINT to its group, up to ``grace`` s for it and its descendants to end, then SIGTERM and SIGKILL
    (``kill_wait`` s each), then SIGKILL to the descendants still alive (collected before and while waiting).
    """
    group = _leads_group(proc)
    tree = descendants(proc.pid)
    _signal(proc, signal.SIGINT, group)
    deadline = time.monotonic() + grace
    while time.monotonic() < deadline and (proc.poll() is None or any(alive(p) for p in tree)):
        tree += [p for p in descendants(proc.pid) if p not in tree]
        time.sleep(0.05)
    for sig in (signal.SIGTERM, signal.SIGKILL):
        if proc.poll() is not None:
            break
        tree += [p for p in descendants(proc.pid) if p not in tree]
        _signal(proc, sig, group)
        try:
            proc.wait(kill_wait)
        except subprocess.TimeoutExpired:
            pass
    if group:
        try:
            os.killpg(proc.pid, signal.SIGKILL)   # stragglers of its session
        except OSError:
            pass
    killed = []
    for p in tree:
        if alive(p):
            try:
                p.kill()
                killed.append(p)
            except psutil.Error:
                pass
    if killed:
        psutil.wait_procs(killed, timeout=2.0)
    try:
        proc.wait(kill_wait)
    except subprocess.TimeoutExpired:
        pass
    return [p.pid for p in tree if alive(p)] + ([proc.pid] if proc.poll() is None else [])


class Processes(object):
    """Named processes, each in a session of its own with its output in ``<log_dir>/<name>.log``.

    ``stop(name)`` / ``stop_all()`` (reverse start order) end them and their trees with ``stop``.
    """

    def __init__(self, log_dir, grace=3.0):
        self.log_dir = log_dir
        self.grace = grace
        self.started = []  # (name, Popen, log path), start order

    def start(self, name, argv, env=None):
        path = os.path.join(self.log_dir, name + '.log')
        proc = start(argv, env=env, log=path)
        self.started.append((name, proc, path))
        return proc

    def log_path(self, name):
        for nm, _, path in reversed(self.started):
            if nm == name:
                return path
        return None

    def log_tail(self, name, n=20):
        """The last ``n`` lines of ``name``'s log ('' when there is none)."""
        path = self.log_path(name)
        if path is None or not os.path.exists(path):
            return ''
        with open(path, 'rb') as f:
            return b''.join(f.readlines()[-n:]).decode('utf-8', 'replace')

    def stop(self, name, grace=None):
        """Stop every process started as ``name``; the pids that survived."""
        left = []
        for entry in [e for e in self.started if e[0] == name]:
            self.started.remove(entry)
            left += stop(entry[1], self.grace if grace is None else grace)
        return left

    def stop_all(self, grace=None):
        left = []
        for name, proc, _ in reversed(list(self.started)):
            try:
                left += stop(proc, self.grace if grace is None else grace)
            except Exception as exc:  # keep cleaning up the others
                left.append(proc.pid)
                sys.stderr.write('cleanup of %s (pid %d) failed: %s\n' % (name, proc.pid, exc))
        self.started = []
        return left


# ----------------------------------------------------------------------------- ROS masters (XML-RPC)
class _Transport(xmlrpc.client.Transport):
    """XML-RPC over HTTP with a socket timeout (a peer that accepts and never answers does not hang us)."""

    def __init__(self, timeout):
        xmlrpc.client.Transport.__init__(self)
        self.timeout = timeout

    def make_connection(self, host):
        conn = xmlrpc.client.Transport.make_connection(self, host)
        conn.timeout = self.timeout
        return conn


def xmlrpc_proxy(uri, timeout=10.0):
    """An XML-RPC client of ``uri`` whose calls give up after ``timeout`` s (a ROS master or node)."""
    return xmlrpc.client.ServerProxy(uri, transport=_Transport(timeout))


def master_pid(master_uri, caller=HARNESS_CALLER):
    """Process id of the ROS master answering at ``master_uri``, or None when none answers."""
    try:
        code, _, pid = xmlrpc_proxy(master_uri).getPid(caller)
    except (OSError, xmlrpc.client.Error):
        return None
    return pid if code == 1 else None


def node_pid(name, master_uri=None, caller=HARNESS_CALLER):
    """Process id of the ROS node ``name`` (through the master, default $ROS_MASTER_URI), or None when it
    is not registered or does not answer."""
    master_uri = master_uri or os.environ.get('ROS_MASTER_URI', 'http://localhost:11311')
    try:
        code, _, uri = xmlrpc_proxy(master_uri).lookupNode(caller, name)
        if code != 1:
            return None
        code, _, pid = xmlrpc_proxy(uri).getPid(caller)
    except (OSError, xmlrpc.client.Error):
        return None
    return pid if code == 1 else None


def start_master(procs, env, port=None, port_range=None, timeout=30.0, attempts=5, name='roscore'):
    """Start ``roscore`` (as ``name`` in the Processes ``procs``) on a free port and wait until it answers;
    the master URI ('http://127.0.0.1:<port>'); ``env`` gets ROS_MASTER_URI.

    The master answering must be a process of that roscore: a master someone else started on the port
    meanwhile would mix two runs (roslaunch silently joins any master on its port), so then another port
    is tried, up to ``attempts`` times.
    """
    for _ in range(attempts):
        port = port or free_port(*(port_range or ()))
        uri = 'http://127.0.0.1:%d' % port
        env['ROS_MASTER_URI'] = uri
        core = procs.start(name, ['roscore', '-p', str(port)], env)
        if wait_for(lambda: core.poll() is not None or master_pid(uri) is not None, timeout, 0.1):
            pid = master_pid(uri)
            if pid is not None and (psutil is None or pid in [p.pid for p in descendants(core.pid)]):
                return uri
        procs.stop(name)
        port = None
    raise RuntimeError('could not start a ROS master of our own (%d attempts); last log:\n%s'
                       % (attempts, procs.log_tail(name)))


def private_master(procs, ros_home, log_dir=None, port_range=None, join=False):
    """A ROS master of our own (``start_master``) and the environment of the processes on it (``ros_env``, with
    this interpreter's directory first on PATH); with ``join`` this process's os.environ points at it too
    (for a rospy.init_node here). Returns (master URI, env)."""
    env = ros_env(ros_home=ros_home, log_dir=log_dir)
    env['PATH'] = os.path.dirname(sys.executable) + os.pathsep + env.get('PATH', '')
    uri = start_master(procs, env, port_range=port_range)
    if join:
        os.environ.update((k, env[k]) for k in ('ROS_MASTER_URI', 'ROS_HOME', 'ROS_LOG_DIR') if k in env)
    return uri, env


# ----------------------------------------------------------------------------- CPU accounting
def cpu_model():
    """The CPU's model name from /proc/cpuinfo (or what platform knows)."""
    try:
        with open('/proc/cpuinfo') as f:
            for line in f:
                if line.startswith('model name'):
                    return line.split(':', 1)[1].strip()
    except IOError:
        pass
    return platform.processor() or 'unknown'


def load_average():
    """The 1-min load average of the machine (NaN where the OS does not tell)."""
    try:
        return os.getloadavg()[0]
    except (AttributeError, OSError):
        return float('nan')


def machine(load=None):
    """The machine a figure was measured on, for result pages: '<CPU model> (<arch>), <n> cores, load <L>,
    Python <version>'; ``load``: the 1-min load average when the measurement started (default: now)."""
    load = load_average() if load is None else load
    return '%s (%s), %d cores, load %.1f, Python %s' % (cpu_model(), platform.machine(), os.cpu_count() or 0, load,
                                                         platform.python_version())


def cpu_seconds(pid):
    """User + system CPU time [s] of process ``pid`` (all its threads), NaN when unknown."""
    if psutil is None:
        return float('nan')
    try:
        t = psutil.Process(pid).cpu_times()
        return t.user + t.system
    except psutil.Error:
        return float('nan')


def cpu_snapshot(pids):
    """{name: (pid, user+system CPU seconds, wall time)} now, for ``pids`` {name: pid}."""
    return dict((name, (pid, cpu_seconds(pid), time.time())) for name, pid in pids.items())


def cpu_delta(a, b):
    """CPU seconds per name between two ``cpu_snapshot``s (names whose pid changed are left out), and the total."""
    per_node = {}
    for name in a:
        if name in b and a[name][0] == b[name][0]:
            per_node[name] = b[name][1] - a[name][1]
    return {'per_node': per_node, 'total': sum(per_node.values())}


def machine_busy(before, after):
    """Busy share of all cores between two psutil.cpu_times() [%]."""
    idle = (after.idle + getattr(after, 'iowait', 0.0)) - (before.idle + getattr(before, 'iowait', 0.0))
    total = sum(after) - sum(before)
    return 100.0 * (1.0 - idle / total) if total > 0 else float('nan')


class TreeCpu(object):
    """CPU time (user+sys) of a process and all its descendants over a window, polled with ``poll``.

    Every process is keyed by (pid, create_time); its CPU counts from the window start (or its
    creation) to its last poll, so processes that end during the window keep their share up to then.
    ``roles(psutil.Process, is_root)`` names the role a process is counted under.
    """

    def __init__(self, pid, roles=lambda p, is_root: 'root' if is_root else 'child'):
        self.pid = pid
        self.roles = roles
        self.base = {}
        self.last = {}
        self.role = {}
        self.ended = 0

    def _snapshot(self):
        out = {}
        try:
            root = psutil.Process(self.pid)
            procs = [root] + root.children(recursive=True)
        except psutil.Error:
            return out
        for p in procs:
            try:
                with p.oneshot():
                    key = (p.pid, p.create_time())
                    t = p.cpu_times()
                    out[key] = t.user + t.system
                    if key not in self.role:
                        self.role[key] = self.roles(p, p.pid == self.pid)
            except psutil.Error:
                continue
        return out

    def start_window(self):
        self.base = self._snapshot()
        self.last = dict(self.base)
        self.ended = 0

    def poll(self):
        snap = self._snapshot()
        self.last.update(snap)
        return snap

    def processes(self):
        """[(role, CPU seconds in the window)] of every process seen (after ``end_window``), largest first."""
        return sorted(((self.role.get(key, 'other'), cpu - self.base.get(key, 0.0)) for key, cpu in self.last.items()),
                      key=lambda item: -item[1])

    def end_window(self):
        """{role: [CPU seconds in the window, processes]}; ``ended`` = processes gone during the window."""
        snap = self.poll()
        self.ended = sum(1 for k in self.last if k not in snap)
        per_role = {}
        for key, cpu in self.last.items():
            role = self.role.get(key, 'other')
            entry = per_role.setdefault(role, [0.0, 0])
            entry[0] += cpu - self.base.get(key, 0.0)
            entry[1] += 1
        return per_role


class CpuWindow(object):
    """One measurement window of ``duration`` s: CPU of some ``TreeCpu``s (polled every second), the load
    average before and after, the machine's busy share and this process's own CPU."""

    def __init__(self, trees, duration):
        self.trees = trees  # name -> TreeCpu
        self.duration = duration

    def run(self):
        me = psutil.Process()
        self.load_before = os.getloadavg()
        cpu0 = psutil.cpu_times()
        me0 = me.cpu_times()
        for tree in self.trees.values():
            tree.start_window()
        self.t0 = time.time()
        end = self.t0 + self.duration
        while True:
            left = end - time.time()
            if left <= 0:
                break
            time.sleep(min(1.0, left))
            for tree in self.trees.values():
                tree.poll()
        self.t1 = time.time()
        self.cpu = dict((name, tree.end_window()) for name, tree in self.trees.items())
        self.ended = dict((name, tree.ended) for name, tree in self.trees.items())
        me1 = me.cpu_times()
        self.bench_cpu = (me1.user + me1.system) - (me0.user + me0.system)
        self.busy = machine_busy(cpu0, psutil.cpu_times())
        self.load_after = os.getloadavg()
        self.wall = self.t1 - self.t0
        return self

    def share(self, name, role=None):
        """CPU [% of one core] of a tree (or one role in it) over the window."""
        cpu = sum(v[0] for r, v in self.cpu[name].items() if role is None or r == role)
        return 100.0 * cpu / self.wall

    def count(self, name, role=None):
        """Processes of a tree (or of one role in it) seen in the window."""
        return sum(v[1] for r, v in self.cpu[name].items() if role is None or r == role)
