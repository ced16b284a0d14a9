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

A silent process is judged by ``hang_verdict`` (pure: numbers in, a verdict with its reason out) before it is
killed, so that a process starved of CPU on a loaded machine is not taken for a hung one:

- the reader's own wake-up lag: the supervisor's poll loop notes how late each of its wake-ups came against
  its schedule; the time the reader itself was not running (its lateness summed over the silent window) does
  not count as the process's silence;
- the process's own progress: its CPU time (utime + stime) and scheduler state from ``/proc/<pid>/stat``.
  A process that used CPU within the last ``restart_timeout`` s, or waits runnable for a CPU ('R') or on a
  disk ('D'), is working (starved, not hung: ``starved`` counts these verdicts, ``last_starved`` says why);
- still hung: a stopped process ('T', e.g. SIGSTOP), one blocked (sleeping, no CPU) for ``restart_timeout``
  s while the reader ran on time, one that burned ``spin_cpu`` CPU seconds without printing a byte (a busy
  loop), and any that stayed silent for ``patience`` x ``restart_timeout`` s of the reader's time whatever
  it did. Without ``/proc`` (another OS) the output timer alone decides, as a plain timeout.

Until a run's first byte ``start_timeout`` (default: ``restart_timeout``) replaces ``restart_timeout``: a tool
blocked on its source before that source streams (a simulator still starting on a loaded machine) is given
longer; a stopped one is still hung at once.

The sample timer (``sample_timeout``) runs from the first byte after the last sample (or the start), so a
silence before it (judged above) is not a silence without samples; it discounts the reader's lateness the same
way (the process prints, so it is not starved; it prints no sample).
"""
import os
import shlex
import signal
import subprocess
import threading
import time

#: diagnostics key of the interface: the largest lateness [s] of the reader's wake-ups since its previous report
READER_LAG_KEY = 'reader wake-up lag max [s]'
#: scheduler states of /proc/<pid>/stat: a process in these is waiting for a CPU or a disk (working)
WORKING_STATES = ('R', 'D')
#: ... stopped (SIGSTOP, traced) or gone: it will print nothing until something else acts
STOPPED_STATES = ('T', 't', 'Z', 'X', 'x')


class Verdict(object):
    """What ``hang_verdict`` decided: ``hung`` (kill and restart), ``kind`` (one word: 'quiet', 'reader late',
    'working', 'stopped', 'spinning', 'blocked', 'silent') and ``reason`` (a sentence with the figures)."""

    __slots__ = ('hung', 'kind', 'reason')

    def __init__(self, hung, kind, reason):
        self.hung = bool(hung)
        self.kind = kind
        self.reason = reason

    def __repr__(self):
        return 'Verdict(hung=%r, kind=%r, reason=%r)' % (self.hung, self.kind, self.reason)


def hang_verdict(silent_for, timeout, reader_late=0.0, state=None, cpu_recent=None, cpu_silent=None,
                 spin_cpu=5.0, patience=15.0):
    """Is a process that printed nothing for ``silent_for`` s hung (kill it) or live but starved (wait)?

    ``timeout`` [s]: the silence allowed; ``reader_late`` [s]: how late the reader's own wake-ups came during
    the silence, summed (the reader was not running then: that time is not the process's silence);
    ``state``: the process's scheduler state ('R', 'S', 'D', 'T', 'Z' ... of /proc/<pid>/stat; None:
    unknown); ``cpu_recent`` [s]: CPU time it used over the last ``timeout`` s; ``cpu_silent`` [s]: CPU time it
    used since its last output (None: unknown); ``spin_cpu`` [s]: CPU time without a byte of output that makes
    a busy loop; ``patience``: silence of ``patience`` x ``timeout`` s of the reader's time is a hang whatever
    the process does. Returns a ``Verdict``.
    """
    awake = silent_for - max(0.0, reader_late)      # the silence the reader was there to see
    if awake <= timeout:
        if silent_for <= timeout:
            return Verdict(False, 'quiet', 'silent for %.2f s (allowed %.2f s)' % (silent_for, timeout))
        return Verdict(False, 'reader late', 'silent for %.2f s, but the reader itself woke up %.2f s late in '
                       'that time (starved of CPU): %.2f s of its own time, allowed %.2f s'
                       % (silent_for, reader_late, awake, timeout))
    if state is not None and state in STOPPED_STATES:
        return Verdict(True, 'stopped', 'no output for %.2f s and the process is stopped (state %s)'
                       % (awake, state))
    if cpu_silent is not None and cpu_silent >= spin_cpu:
        return Verdict(True, 'spinning', 'no output for %.2f s while using %.2f s of CPU (>= %.2f s: a busy loop)'
                       % (awake, cpu_silent, spin_cpu))
    if awake > patience * timeout:
        return Verdict(True, 'silent', 'no output for %.2f s of the reader\'s time (> %g x %.2f s)'
                       % (awake, patience, timeout))
    if cpu_recent is not None and cpu_recent > 0.0:
        return Verdict(False, 'working', 'no output for %.2f s, but the process used %.3f s of CPU in the last '
                       '%.2f s (starved or starting, not hung)' % (awake, cpu_recent, timeout))
    if state is not None and state in WORKING_STATES:
        return Verdict(False, 'working', 'no output for %.2f s, but the process is waiting for %s (state %s: '
                       'starved, not hung)' % (awake, 'a CPU' if state == 'R' else 'a disk', state))
    if state is None and cpu_recent is None:
        return Verdict(True, 'silent', 'no output for %.2f s (allowed %.2f s; its progress cannot be read)'
                       % (awake, timeout))
    return Verdict(True, 'blocked', 'no output and no CPU time for %.2f s while the reader ran on time (%.2f s '
                   'late in total; state %s)' % (awake, max(0.0, reader_late), state or 'unknown'))


def parse_proc_stat(text, ticks_per_second):
    """(state, cpu seconds = utime + stime) of the text of /proc/<pid>/stat; None when it cannot be read."""
    try:
        rest = text[text.rindex(')') + 2:].split()    # the command name may hold spaces and parentheses
        return rest[0], (int(rest[11]) + int(rest[12])) / float(ticks_per_second)
    except (ValueError, IndexError):
        return None


def process_progress(pid):
    """(state, cpu seconds) of process ``pid`` from /proc, None when unavailable (gone, not Linux)."""
    try:
        with open('/proc/%d/stat' % pid) as f:
            text = f.read()
        ticks = os.sysconf('SC_CLK_TCK')
    except (OSError, ValueError, AttributeError):
        return None
    return parse_proc_stat(text, ticks)


class ProcessSupervisor(object):
    """Keeps one subprocess running and streams its stdout lines.

    command: a string (shlex-split) or a list of arguments.
    on_line(line, wall_time): called from the reader thread for each stdout line.
    on_event(kind, info): optional; kind in 'start', 'exit', 'hang', 'spawn_failed', 'callback_error';
    info: a dict (pid, exit code, message ...).
    """

    def __init__(self, command, on_line, restart_timeout=2.0, backoff_initial=0.2, backoff_max=5.0,
                 on_event=None, healthy_time=1.0, kill_grace=0.2, poll_period=0.05, env=None, max_line=4096,
                 sample_timeout=None, prepare=None, spin_cpu=5.0, patience=15.0, progress=process_progress,
                 start_timeout=None):
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
        self.spin_cpu = float(spin_cpu)
        self.start_timeout = self.restart_timeout if start_timeout is None else float(start_timeout)
        if not self.start_timeout > 0:
            raise ValueError('start_timeout must be > 0 or None, got %r' % (start_timeout,))
        self.patience = float(patience)
        self.progress = progress   # pid -> (state, cpu seconds) or None (tests give their own)
        # counters / state (read from any thread; written by the supervisor threads)
        self.attempts = 0          # launch attempts
        self.starts = 0            # successful spawns
        self.restarts = 0          # launch attempts after the first one
        self.exits = 0             # the process ended by itself
        self.hangs = 0             # killed for printing nothing for restart_timeout (``hang_verdict``)
        self.starved = 0           # silences past restart_timeout judged starved, not hung (not killed)
        self.last_starved = ''     # the reason of the latest of these
        self.reader_lag_max = 0.0  # [s] latest wake-up of the poll loop against its schedule, since start
        self.reader_lag_recent = 0.0   # [s] ... since the last ``take_reader_lag``
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
                    stderr_oversize_lines=self.stderr_oversize_lines, starved=self.starved,
                    reader_lag_max=self.reader_lag_max, last_exit_code=self.last_exit_code,
                    last_stderr=self.last_stderr,
                    last_error=self.last_error, backoff=self.backoff)

    def take_reader_lag(self):
        """[s] the largest lateness of the poll loop's wake-ups since the previous call (then reset)."""
        lag, self.reader_lag_recent = self.reader_lag_recent, 0.0
        return lag

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
        watch = _Watch(self, proc.pid)
        while not self._stop.is_set():
            if proc.poll() is not None:
                break
            verdict = watch.check(time.monotonic())
            if verdict is not None and verdict.hung:
                hung = True
                break
            before = time.monotonic()
            self._stop.wait(self.poll_period)
            watch.woke(time.monotonic() - before - self.poll_period)
        first = self._first_output
        healthy = first is not None and self._last_output - first >= self.healthy_time
        if hung:
            self.hangs += 1
            self._event('hang', pid=proc.pid, silent_for=time.monotonic() - self._last_output,
                        reason=verdict.reason, verdict=verdict.kind, restart_in=self._next_delay(healthy))
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


class _Watch(object):
    """The poll loop's view of one run of the process: the reader's lateness and the process's CPU time since
    its last output and sample, fed to ``hang_verdict``."""

    def __init__(self, sup, pid):
        self.sup = sup
        self.pid = pid
        self.output_seen = sup._last_output
        self.sample_seen = sup._last_sample
        self.late_output = 0.0      # [s] the reader's lateness since the last output
        self.late_sample = 0.0      # ... since the last sample
        self.cpu_at_output = 0.0    # the process's CPU time at its last output (0 at its start)
        self.history = [(sup._last_output, 0.0)]   # (monotonic time, cpu seconds): the last restart_timeout s
        self.reported = None        # the silence last reported as starved (one event per silence)
        self.printing_since = None  # when output came after the last sample (the sample timer runs from there)

    def woke(self, late):
        late = max(0.0, late)
        sup = self.sup
        sup.reader_lag_max = max(sup.reader_lag_max, late)
        sup.reader_lag_recent = max(sup.reader_lag_recent, late)
        self.late_output += late
        self.late_sample += late

    def check(self, now):
        """The verdict on a silence past the timeouts, None while the process prints (and samples) in time."""
        sup = self.sup
        progress = sup.progress(self.pid) if sup.progress is not None else None
        state, cpu = progress if progress is not None else (None, None)
        if sup._last_output != self.output_seen:
            self.output_seen = sup._last_output
            self.late_output = 0.0
            self.reported = None
            if cpu is not None:
                self.cpu_at_output = cpu
        if sup._last_sample != self.sample_seen:
            self.sample_seen = sup._last_sample
            self.late_sample = 0.0
        if sup._last_output <= sup._last_sample:
            self.printing_since = None
        elif self.printing_since is None:    # output after the last sample (or the start): the sample timer runs
            self.printing_since = sup._last_output
            self.late_sample = 0.0
        cpu_recent = None
        if cpu is not None:
            self.history.append((now, cpu))
            while len(self.history) > 1 and self.history[1][0] <= now - sup.restart_timeout:
                self.history.pop(0)
            cpu_recent = cpu - self.history[0][1]
        silent = now - sup._last_output
        first = sup._first_output is None       # nothing printed yet: its source may still be starting
        timeout = sup.start_timeout if first else sup.restart_timeout
        if silent > timeout:
            verdict = hang_verdict(silent, timeout, self.late_output, state, cpu_recent,
                                   None if cpu is None else cpu - self.cpu_at_output, sup.spin_cpu,
                                   sup.patience * sup.restart_timeout / timeout)
            if verdict.hung:
                return verdict
            if verdict.kind != 'quiet' and self.reported != self.output_seen:
                self.reported = self.output_seen
                sup.starved += 1
                sup.last_starved = verdict.reason
                sup._event('starved', pid=self.pid, silent_for=silent, verdict=verdict.kind,
                           reason=verdict.reason)
        if sup.sample_timeout is not None and self.printing_since is not None:   # it prints, but no sample
            silent = now - max(sup._last_sample, self.printing_since)
            if silent - self.late_sample > sup.sample_timeout:
                return Verdict(True, 'no samples', 'output but no sample for %.2f s (%.2f s of the reader\'s time; '
                               'allowed %.2f s)' % (silent, silent - self.late_sample, sup.sample_timeout))
        return None
