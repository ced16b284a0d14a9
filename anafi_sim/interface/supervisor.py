"""Runs the telemetry command as one supervised subprocess (pure: subprocess + threads, no ROS).

Stage: telemetry -> **interface** (the process that prints the telemetry).

``ProcessSupervisor`` starts the command in its own process group, hands
every stdout line to ``on_line(line, wall_time)`` (line as text, with its
newline if it had one; wall_time = ``time.time()`` [s] at receipt) from a
reader thread, and restarts the command when it exits, fails to start or
hangs (prints no byte for ``restart_timeout`` s, also right after start; the
timer runs on bytes, so a line that never ends still counts as output, and it
is bounded: see below). Restarts wait an exponential back-off
(``backoff_initial`` doubling up to ``backoff_max`` s), back to
``backoff_initial`` after a run that printed for at least ``healthy_time`` s
or that exited cleanly (code 0: e.g. the simulator stopped; it is retried at
once when it comes back). Nothing raised by the process or the callbacks
escapes: it is counted.

Lines are read with a cap of ``max_line`` bytes: a longer line is dropped
(counted in ``oversize_lines``, never handed to ``on_line``) and memory stays
bounded whatever the process prints; stderr is read with the same cap (only
the start of its last line is kept, ``last_stderr``; bytes counted in
``stderr_bytes``). ``sample_timeout`` [s] (None: off): the
process is also treated as hung when ``on_line`` has not returned True (= a
sample was completed) for that long while it prints (garbage only).

``prepare`` (None: off): ``prepare(argv) -> argv`` is called before every start
(e.g. to put in the port the simulator serves on now); a ValueError it raises
counts as a spawn failure (its message in ``last_error``), retried with back-off.
"""
import os
import shlex
import signal
import subprocess
import threading
import time


class ProcessSupervisor(object):
    """Keeps one subprocess running and streams its stdout lines.

    command: a string (shlex-split) or a list of arguments.
    on_line(line, wall_time): called from the reader thread for each stdout line.
    on_event(kind, info): optional; kind in 'start', 'exit', 'hang', 'spawn_failed', 'callback_error';
    info: a dict (pid, exit code, message ...).
    """

    def __init__(self, command, on_line, restart_timeout=2.0, backoff_initial=0.2, backoff_max=5.0,
                 on_event=None, healthy_time=1.0, kill_grace=0.2, poll_period=0.05, env=None, max_line=4096,
                 sample_timeout=None, prepare=None):
        if isinstance(command, str):
            argv = shlex.split(command)
        else:
            argv = [str(a) for a in command]
        if not argv:
            raise ValueError('empty command')
        for name, value in (('restart_timeout', restart_timeout), ('backoff_initial', backoff_initial),
                            ('backoff_max', backoff_max)):
            if not value > 0:
                raise ValueError('%s must be > 0, got %r' % (name, value))
        if isinstance(max_line, bool) or not isinstance(max_line, int) or max_line < 16:
            raise ValueError('max_line must be an integer >= 16 [bytes], got %r' % (max_line,))
        if sample_timeout is not None and not sample_timeout > 0:
            raise ValueError('sample_timeout must be > 0 or None, got %r' % (sample_timeout,))
        if backoff_max < backoff_initial:
            raise ValueError('backoff_max (%r) < backoff_initial (%r)' % (backoff_max, backoff_initial))
        self.argv = argv
        self.command_argv = list(argv)   # as given; ``argv`` is what ``prepare`` made of it for the last start
        self.prepare = prepare
        self.on_line = on_line
        self.on_event = on_event
        self.restart_timeout = float(restart_timeout)
        self.backoff_initial = float(backoff_initial)
        self.backoff_max = float(backoff_max)
        self.healthy_time = float(healthy_time)
        self.kill_grace = float(kill_grace)
        self.poll_period = float(poll_period)
        self.env = env
        self.max_line = max_line
        self.sample_timeout = None if sample_timeout is None else float(sample_timeout)
        # counters / state (read from any thread; written by the supervisor threads)
        self.attempts = 0          # launch attempts
        self.starts = 0            # successful spawns
        self.restarts = 0          # launch attempts after the first one
        self.exits = 0             # the process ended by itself
        self.hangs = 0             # killed for printing nothing for restart_timeout
        self.spawn_failures = 0    # could not start (missing executable, permissions ...)
        self.callback_errors = 0   # exceptions raised by on_line
        self.lines = 0
        self.oversize_lines = 0    # lines longer than max_line bytes, dropped
        self.stderr_bytes = 0      # bytes read from stderr (only the start of its last line is kept)
        self.stderr_oversize_lines = 0   # stderr lines longer than max_line bytes (their start kept)
        self.last_exit_code = None
        self.last_stderr = ''
        self.last_error = ''
        self.running = False
        self.pid = None
        self.backoff = self.backoff_initial  # delay before the next restart [s]
        self._proc = None
        self._stop = threading.Event()
        self._lock = threading.Lock()
        self._thread = None
        self._last_output = 0.0
        self._last_sample = 0.0
        self._first_output = None

    # -- public -----------------------------------------------------------------
    def start(self):
        """Start supervising (returns at once; the process runs in the background)."""
        if self._thread is not None:
            return
        self._stop.clear()
        self._thread = threading.Thread(target=self._supervise, name='supervisor', daemon=True)
        self._thread.start()

    def stop(self, timeout=3.0):
        """Kill the process (group) and stop the threads; True if supervision ended within ``timeout`` s."""
        self._stop.set()
        with self._lock:
            proc = self._proc
        if proc is not None:
            self._kill(proc)
        thread, self._thread = self._thread, None
        if thread is not None:
            thread.join(timeout)
            return not thread.is_alive()
        return True

    def snapshot(self):
        """Counters and state as a dict."""
        return dict(running=self.running, pid=self.pid, attempts=self.attempts, starts=self.starts,
                    restarts=self.restarts, exits=self.exits, hangs=self.hangs,
                    spawn_failures=self.spawn_failures, callback_errors=self.callback_errors,
                    lines=self.lines, oversize_lines=self.oversize_lines, stderr_bytes=self.stderr_bytes,
                    stderr_oversize_lines=self.stderr_oversize_lines,
                    last_exit_code=self.last_exit_code, last_stderr=self.last_stderr,
                    last_error=self.last_error, backoff=self.backoff)

    # -- internals ----------------------------------------------------------------
    def _event(self, kind, **info):
        if self.on_event is None:
            return
        try:
            self.on_event(kind, info)
        except Exception:  # a logging callback must not stop supervision
            self.callback_errors += 1

    def _supervise(self):
        while not self._stop.is_set():
            if self.attempts:
                self.restarts += 1
            self.attempts += 1
            healthy = self._run_once() or self.last_exit_code == 0
            if self._stop.is_set():
                break
            delay = self._next_delay(healthy)
            self.backoff = min(delay * 2.0, self.backoff_max)
            self._stop.wait(delay)

    def _next_delay(self, healthy):
        """Delay [s] before the next attempt after a run that was (not) healthy."""
        return self.backoff_initial if healthy else self.backoff

    def _run_once(self):
        """Run the command once; return True if it printed healthily for healthy_time."""
        try:
            if self.prepare is not None:
                self.argv = [str(a) for a in self.prepare(list(self.command_argv))]
            proc = subprocess.Popen(self.argv, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                                    stderr=subprocess.PIPE, start_new_session=True, env=self.env)
        except Exception as exc:  # missing executable, permission denied, bad argument ...
            self.spawn_failures += 1
            self.last_error = '%s: %s' % (type(exc).__name__, exc)
            self._event('spawn_failed', message=self.last_error, restart_in=self._next_delay(False))
            return False
        with self._lock:
            self._proc = proc
        self.starts += 1
        self.pid = proc.pid
        self.running = True
        self._first_output = None
        self._last_output = self._last_sample = time.monotonic()
        self._event('start', pid=proc.pid, argv=self.argv)
        readers = [threading.Thread(target=self._read_stdout, args=(proc,), name='stdout', daemon=True),
                   threading.Thread(target=self._read_stderr, args=(proc,), name='stderr', daemon=True)]
        for t in readers:
            t.start()
        hung = False
        while not self._stop.is_set():
            if proc.poll() is not None:
                break
            now = time.monotonic()
            if now - self._last_output > self.restart_timeout or (
                    self.sample_timeout is not None and now - self._last_sample > self.sample_timeout):
                hung = True
                break
            self._stop.wait(self.poll_period)
        first = self._first_output
        healthy = first is not None and self._last_output - first >= self.healthy_time
        if hung:
            self.hangs += 1
            self._event('hang', pid=proc.pid, silent_for=time.monotonic() - self._last_output,
                        restart_in=self._next_delay(healthy))
        if proc.poll() is None:
            self._kill(proc)
        else:  # the leader is gone: take any children left in its group with it
            self._killpg(proc.pid, signal.SIGKILL)
        for t in readers:
            t.join(1.0)
        code = proc.poll()
        self.last_exit_code = code
        self.running = False
        with self._lock:
            self._proc = None
        if not hung and not self._stop.is_set():
            self.exits += 1
            self._event('exit', pid=proc.pid, code=code, stderr=self.last_stderr,
                        restart_in=self._next_delay(healthy or code == 0))
        for stream in (proc.stdout, proc.stderr):
            try:
                stream.close()
            except Exception:
                pass
        return healthy

    def _kill(self, proc):
        """SIGTERM the process group, SIGKILL it after kill_grace, reap the process."""
        for sig, wait in ((signal.SIGTERM, self.kill_grace), (signal.SIGKILL, 2.0)):
            self._killpg(proc.pid, sig)
            try:
                proc.wait(wait)
                break
            except subprocess.TimeoutExpired:
                continue
            except Exception:
                break
        self._killpg(proc.pid, signal.SIGKILL)  # children left in the group after the leader died

    @staticmethod
    def _killpg(pgid, sig):
        try:
            os.killpg(pgid, sig)
        except OSError:  # already gone
            pass

    def _read_stdout(self, proc):
        readline = proc.stdout.readline
        on_line = self.on_line
        limit = self.max_line
        dropping = False          # inside a line longer than max_line: skip to its end
        while True:
            try:
                raw = readline(limit)
            except (ValueError, OSError):
                break
            if not raw:
                break
            now = time.monotonic()
            if self._first_output is None:
                self._first_output = now
            self._last_output = now
            complete = raw.endswith(b'\n')
            if dropping:
                dropping = not complete
                continue
            if not complete and len(raw) >= limit:
                self.oversize_lines += 1
                dropping = True
                continue
            self.lines += 1
            try:
                if on_line(raw.decode('utf-8', 'replace'), time.time()):
                    self._last_sample = now
            except Exception as exc:
                self.callback_errors += 1
                self.last_error = 'on_line: %s: %s' % (type(exc).__name__, exc)
                self._event('callback_error', message=self.last_error)

    def _read_stderr(self, proc):
        """stderr, read with the same cap as stdout: ``last_stderr`` = the start (500 characters) of the last
        non-empty line; the rest of a longer line is skipped as it comes (counted in ``stderr_bytes``), so
        memory stays bounded whatever the process prints there."""
        readline = proc.stderr.readline
        limit = self.max_line
        dropping = False          # inside a line longer than max_line: its start is kept, skip to its end
        while True:
            try:
                raw = readline(limit)
            except (ValueError, OSError):
                break
            if not raw:
                break
            self.stderr_bytes += len(raw)
            complete = raw.endswith(b'\n')
            if dropping:
                dropping = not complete
                continue
            if not complete and len(raw) >= limit:
                self.stderr_oversize_lines += 1
                dropping = True
            text = raw.decode('utf-8', 'replace').strip()
            if text:
                self.last_stderr = text[:500]
