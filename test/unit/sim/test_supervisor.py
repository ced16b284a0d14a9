"""ProcessSupervisor with small sh / python commands: lines, exits, hangs, back-off, missing executables."""
import os
import threading
import time

import psutil
import pytest

from anafi_sim.interface.supervisor import ProcessSupervisor

PY = '/usr/bin/python3'


class Recorder(object):
    def __init__(self):
        self.lines = []
        self.events = []
        self.cond = threading.Condition()

    def on_line(self, line, wall_time):
        with self.cond:
            self.lines.append((line, wall_time))
            self.cond.notify_all()

    def on_event(self, kind, info):
        with self.cond:
            self.events.append((kind, dict(info), time.monotonic()))
            self.cond.notify_all()

    def kinds(self, kind):
        with self.cond:
            return [e for e in self.events if e[0] == kind]

    def wait_for(self, predicate, timeout=4.0):
        deadline = time.monotonic() + timeout
        with self.cond:
            while not predicate():
                left = deadline - time.monotonic()
                if left <= 0:
                    return False
                self.cond.wait(min(left, 0.05))
        return True


@pytest.fixture
def rec():
    return Recorder()


def make(rec, command, **kwargs):
    kwargs.setdefault('restart_timeout', 2.0)
    sup = ProcessSupervisor(command, rec.on_line, on_event=rec.on_event, **kwargs)
    sup.start()
    return sup


def gone(pid):
    try:
        return psutil.Process(pid).status() == psutil.STATUS_ZOMBIE
    except psutil.NoSuchProcess:
        return True


def test_lines_are_delivered_in_order_with_wall_time(rec):
    t0 = time.time()
    sup = make(rec, [PY, '-c', 'import sys, time\nfor i in range(5): print("k%d : %d" % (i, i), flush=True)\n'
                                 'sys.stdout.write("cut"); sys.stdout.flush(); time.sleep(30)'],
               restart_timeout=0.5, backoff_initial=2.0)
    # the unterminated "cut" comes out when the silent process is killed (hang) and its pipe closes
    try:
        assert rec.wait_for(lambda: len(rec.lines) >= 6)
        assert [l for l, _ in rec.lines[:6]] == ['k%d : %d\n' % (i, i) for i in range(5)] + ['cut']
        assert all(t0 <= t <= time.time() for _, t in rec.lines)
        assert sup.starts == 1 and sup.lines == 6 and sup.hangs == 1
    finally:
        pid = sup.pid
        sup.stop()
    assert gone(pid)
    assert not sup.running


def test_command_string_is_shlex_split(rec):
    sup = make(rec, "sh -c 'echo \"a b : 1\"; sleep 30'")
    try:
        assert rec.wait_for(lambda: rec.lines)
        assert rec.lines[0][0] == 'a b : 1\n'
        assert sup.argv == ['sh', '-c', 'echo "a b : 1"; sleep 30']
    finally:
        sup.stop()


def test_exiting_process_is_restarted_with_growing_backoff(rec):
    sup = make(rec, ['sh', '-c', 'echo out; echo oops >&2; exit 3'], backoff_initial=0.05, backoff_max=0.4)
    try:
        assert rec.wait_for(lambda: len(rec.kinds('start')) >= 5, timeout=4.0)
    finally:
        sup.stop()
    snap = sup.snapshot()
    assert snap['exits'] >= 4 and snap['restarts'] >= 4 and snap['hangs'] == 0
    assert snap['last_stderr'] == 'oops'
    assert [e[1]['code'] for e in rec.kinds('exit')] == [3] * snap['exits']
    starts = [t for _, _, t in rec.kinds('start')]
    # restart k waits at least backoff_initial * 2**k (capped): lower bounds only, no timing upper bounds
    for k in range(4):
        assert starts[k + 1] - starts[k] >= min(0.05 * 2 ** k, 0.4) * 0.95, (k, starts)
    assert snap['backoff'] == 0.4


def test_backoff_resets_after_healthy_output(rec):
    script = 'import time\nfor i in range(6):\n    print(i, flush=True)\n    time.sleep(0.05)\n'
    sup = make(rec, [PY, '-c', script], backoff_initial=0.05, backoff_max=2.0, healthy_time=0.15)
    try:
        assert rec.wait_for(lambda: len(rec.kinds('start')) >= 4, timeout=4.5)
    finally:
        sup.stop()
    # every run printed for >= healthy_time, so the back-off never grew past its first doubling
    assert sup.backoff == pytest.approx(0.1)
    assert sup.exits >= 3 and all(e[1]['code'] == 0 for e in rec.kinds('exit'))


def test_hanging_process_is_killed_and_restarted(rec):
    sup = make(rec, ['sh', '-c', 'echo hello; exec sleep 30'], restart_timeout=0.3, backoff_initial=0.05)
    try:
        assert rec.wait_for(lambda: [l for l, _ in rec.lines].count('hello\n') >= 2)
        first_pid = rec.kinds('start')[0][1]['pid']
        assert rec.wait_for(lambda: gone(first_pid))
    finally:
        sup.stop()
    assert sup.hangs >= 1
    assert rec.kinds('hang')[0][1]['pid'] == first_pid
    assert sup.exits == 0  # killed for hanging, not counted as exiting by itself


def test_process_that_never_prints_is_detected_as_hung(rec):
    sup = make(rec, ['sleep', '30'], restart_timeout=0.2, backoff_initial=0.05)
    try:
        assert rec.wait_for(lambda: len(rec.kinds('hang')) >= 2)
    finally:
        sup.stop()
    assert sup.lines == 0 and sup.starts >= 2


def test_whole_process_group_is_killed(rec):
    sup = make(rec, ['sh', '-c', 'sleep 30 & echo $!; sleep 30'], restart_timeout=0.3, backoff_initial=1.0)
    try:
        assert rec.wait_for(lambda: rec.lines)
        child = int(rec.lines[0][0])
        assert not gone(child)
        assert rec.wait_for(lambda: rec.kinds('hang'))
        assert rec.wait_for(lambda: gone(child))
    finally:
        sup.stop()


def test_missing_executable_is_counted_and_retried(rec):
    sup = make(rec, ['/nonexistent/tlm-data-logger', '-r', '0'], backoff_initial=0.05, backoff_max=0.2)
    try:
        assert rec.wait_for(lambda: len(rec.kinds('spawn_failed')) >= 3)
    finally:
        sup.stop()
    assert sup.starts == 0 and sup.spawn_failures >= 3 and sup.restarts >= 2
    assert 'FileNotFoundError' in sup.last_error
    assert not sup.running


def test_callback_errors_are_counted_not_raised(rec):
    calls = []

    def bad_on_line(line, wall_time):
        calls.append(line)
        raise RuntimeError('boom')

    sup = ProcessSupervisor(['sh', '-c', 'echo 1; echo 2; sleep 30'], bad_on_line, on_event=rec.on_event)
    sup.start()
    try:
        assert rec.wait_for(lambda: len(calls) >= 2)
    finally:
        sup.stop()
    assert calls == ['1\n', '2\n']
    assert sup.callback_errors == 2 and 'boom' in sup.last_error


def test_stop_during_backoff_returns_quickly(rec):
    sup = make(rec, ['sh', '-c', 'exit 1'], backoff_initial=5.0, backoff_max=5.0)
    assert rec.wait_for(lambda: rec.kinds('exit'))
    assert sup.stop(timeout=2.0)  # the 5 s back-off wait is interrupted
    assert sup.starts == 1


def test_bad_arguments_raise_at_construction():
    for kwargs in (dict(restart_timeout=0.0), dict(backoff_initial=-1.0), dict(backoff_initial=2.0, backoff_max=1.0)):
        with pytest.raises(ValueError):
            ProcessSupervisor(['true'], lambda l, t: None, **kwargs)
    with pytest.raises(ValueError):
        ProcessSupervisor('', lambda l, t: None)
    assert os.path.exists(PY)


def test_a_line_without_end_is_capped_dropped_and_counted(rec):
    # 64 kB per chunk, no newline, then a normal line: memory stays bounded, the normal line comes through
    script = ('import sys, time\n'
              'for i in range(40):\n    sys.stdout.write("x" * 65536); sys.stdout.flush()\n'
              'sys.stdout.write("\\nshort\\n"); sys.stdout.flush(); time.sleep(30)\n')
    sup = make(rec, [PY, '-c', script], restart_timeout=5.0, max_line=1024)
    try:
        assert rec.wait_for(lambda: 'short\n' in [l for l, _ in rec.lines], timeout=10.0)
    finally:
        sup.stop()
    assert sup.oversize_lines == 1 and sup.snapshot()['oversize_lines'] == 1
    assert all(len(l) <= 1024 for l, _ in rec.lines) and sup.hangs == 0


def test_stderr_is_read_with_the_same_cap_and_only_its_last_line_start_kept(rec):
    # 2.5 MB on stderr without a newline, then a short line; stdout keeps flowing
    script = ('import sys, time\n'
              'for i in range(40):\n    sys.stderr.write("e" * 65536); sys.stderr.flush()\n'
              'sys.stderr.write("\\nlast words\\n"); sys.stderr.flush()\n'
              'while True:\n    print("k : 1", flush=True); time.sleep(0.05)\n')
    sup = make(rec, [PY, '-c', script], restart_timeout=5.0, max_line=1024)
    try:
        assert rec.wait_for(lambda: sup.last_stderr == 'last words' and len(rec.lines) >= 3, timeout=10.0)
    finally:
        sup.stop()
    snap = sup.snapshot()
    assert snap['stderr_bytes'] == 40 * 65536 + len('\nlast words\n') and snap['stderr_oversize_lines'] == 1
    assert sup.hangs == 0 and sup.oversize_lines == 0


def test_endless_bytes_without_samples_count_as_a_hang_with_a_sample_timeout(rec):
    script = 'import sys\nwhile True:\n    sys.stdout.write("y" * 4096); sys.stdout.flush()\n'
    sup = make(rec, [PY, '-c', script], restart_timeout=5.0, sample_timeout=0.5, max_line=1024,
               backoff_initial=0.05)
    try:
        assert rec.wait_for(lambda: len(rec.kinds('hang')) >= 1, timeout=10.0)
    finally:
        sup.stop()
    assert sup.oversize_lines >= 1 and sup.lines == 0


def test_a_clean_exit_restarts_without_growing_back_off(rec):
    # the telemetry tool exits with code 0 when the simulator stops: retry at once, do not back off
    sup = make(rec, ['sh', '-c', 'exit 0'], backoff_initial=0.05, backoff_max=2.0)
    try:
        assert rec.wait_for(lambda: len(rec.kinds('start')) >= 5, timeout=4.0)
    finally:
        sup.stop()
    assert sup.backoff == pytest.approx(0.1)
    assert all(e[1]['restart_in'] == pytest.approx(0.05) for e in rec.kinds('exit'))


@pytest.mark.parametrize('kw', [dict(max_line=0), dict(max_line=8), dict(max_line=1.5), dict(sample_timeout=0.0)])
def test_bad_line_cap_or_sample_timeout_raise(kw):
    with pytest.raises(ValueError):
        ProcessSupervisor(['true'], lambda line, t: None, **kw)


# -- hung or starved: the pure verdict ------------------------------------------------------------------

from anafi_sim.interface.supervisor import hang_verdict, parse_proc_stat   # noqa: E402


def test_a_silence_within_the_timeout_is_quiet():
    v = hang_verdict(1.0, 2.0, state='S', cpu_recent=0.0, cpu_silent=0.0)
    assert not v.hung and v.kind == 'quiet'


def test_a_late_reader_does_not_count_its_own_absence_as_the_tools_silence():
    # starved reader: 5 s silent, but the reader itself woke up 3.5 s late in that time
    v = hang_verdict(5.0, 2.0, reader_late=3.5, state='S', cpu_recent=0.0, cpu_silent=0.0)
    assert not v.hung and v.kind == 'reader late' and '3.50 s late' in v.reason


def test_a_tool_that_made_cpu_progress_is_starved_not_hung():
    v = hang_verdict(3.0, 2.0, reader_late=0.01, state='S', cpu_recent=0.02, cpu_silent=0.3)
    assert not v.hung and v.kind == 'working' and '0.020 s of CPU' in v.reason


@pytest.mark.parametrize('state', ['R', 'D'])
def test_a_tool_waiting_for_a_cpu_or_a_disk_is_starved_not_hung(state):
    v = hang_verdict(3.0, 2.0, state=state, cpu_recent=0.0, cpu_silent=0.0)
    assert not v.hung and v.kind == 'working'


def test_a_blocked_tool_without_progress_while_the_reader_is_on_time_is_hung():
    v = hang_verdict(2.5, 2.0, reader_late=0.05, state='S', cpu_recent=0.0, cpu_silent=0.0)
    assert v.hung and v.kind == 'blocked' and 'on time' in v.reason


@pytest.mark.parametrize('state', ['T', 't', 'Z'])
def test_a_stopped_tool_is_hung_even_with_cpu_progress(state):
    v = hang_verdict(2.5, 2.0, state=state, cpu_recent=0.5, cpu_silent=0.5)
    assert v.hung and v.kind == 'stopped'


def test_a_busy_loop_without_output_is_hung():
    v = hang_verdict(6.0, 2.0, state='R', cpu_recent=1.9, cpu_silent=5.5, spin_cpu=5.0)
    assert v.hung and v.kind == 'spinning'


def test_patience_ends_at_a_multiple_of_the_timeout_of_the_readers_own_time():
    assert not hang_verdict(19.0, 2.0, state='R', cpu_recent=0.1, cpu_silent=1.0, patience=10).hung
    v = hang_verdict(21.0, 2.0, state='R', cpu_recent=0.1, cpu_silent=1.0, patience=10)
    assert v.hung and v.kind == 'silent'
    # ... and the reader's own lateness still does not count
    assert not hang_verdict(30.0, 2.0, reader_late=12.0, state='R', cpu_recent=0.1, cpu_silent=1.0).hung


def test_without_progress_figures_the_timeout_alone_decides():
    assert hang_verdict(2.5, 2.0).hung
    assert not hang_verdict(1.5, 2.0).hung


def test_proc_stat_is_parsed_with_spaces_and_parentheses_in_the_name():
    fields = ['S'] + ['0'] * 10 + ['250', '50'] + ['0'] * 30
    text = '1234 (tlm (data) logger) ' + ' '.join(fields) + '\n'
    assert parse_proc_stat(text, 100) == ('S', pytest.approx(3.0))
    assert parse_proc_stat('garbage', 100) is None
    assert parse_proc_stat('1 (x) S 1 2', 100) is None


# -- hung or starved: the supervisor ----------------------------------------------------------------------

def test_a_silent_process_using_cpu_is_not_killed(rec):
    # computes without printing for longer than the timeout (a start-up on a loaded machine), then prints
    script = 'import time\nt = time.process_time()\nwhile time.process_time() - t < 1.0: pass\n' \
             'print("done", flush=True)\n' \
             'time.sleep(30)\n'
    sup = make(rec, [PY, '-c', script], restart_timeout=0.3, spin_cpu=20.0, patience=1000.0,
               backoff_initial=0.05)
    try:
        assert rec.wait_for(lambda: rec.lines, timeout=60.0)
    finally:
        sup.stop()
    assert rec.lines[0][0] == 'done\n' and sup.starts == 1
    assert sup.hangs == 0
    assert sup.starved >= 1 and rec.kinds('starved')[0][1]['verdict'] == 'working'


def test_a_stopped_process_is_killed_and_restarted(rec):
    sup = make(rec, ['sh', '-c', 'echo hello; kill -STOP $$; echo never'], restart_timeout=0.3,
               backoff_initial=0.05)
    try:
        assert rec.wait_for(lambda: rec.kinds('hang'), timeout=30.0)
    finally:
        sup.stop()
    hang = rec.kinds('hang')[0][1]
    assert hang['verdict'] == 'stopped' and 'state T' in hang['reason']
    assert 'never\n' not in [l for l, _ in rec.lines]


def test_a_starved_reader_or_tool_as_measured_is_waited_for(rec):
    # the process's progress as /proc would show a starved one: runnable, waiting for a CPU
    sup = make(rec, ['sleep', '30'], restart_timeout=0.2, backoff_initial=0.05, patience=1e6,
               progress=lambda pid: ('R', 0.0))
    try:
        assert rec.wait_for(lambda: rec.kinds('starved'), timeout=10.0)
        assert sup.hangs == 0
    finally:
        sup.stop()
    assert sup.snapshot()['starved'] >= 1 and 'waiting for a CPU' in sup.last_starved


def test_a_process_blocked_before_its_first_byte_is_given_the_start_timeout(rec):
    sup = make(rec, ['sh', '-c', 'sleep 1.5; echo first; exec sleep 30'], restart_timeout=0.3, start_timeout=20.0,
               backoff_initial=0.05)
    try:
        assert rec.wait_for(lambda: rec.lines, timeout=30.0)
        assert rec.wait_for(lambda: rec.kinds('hang'), timeout=30.0)    # after it: restart_timeout again
    finally:
        sup.stop()
    assert rec.lines[0][0] == 'first\n' and rec.kinds('hang')[0][1]['pid'] == rec.kinds('start')[0][1]['pid']


def test_no_sample_timer_while_nothing_is_printed(rec):
    # silent (no byte): the output timer and its verdict decide, not the sample timer
    sup = make(rec, ['sleep', '30'], restart_timeout=0.3, sample_timeout=0.3, start_timeout=20.0,
               backoff_initial=0.05)
    try:
        time.sleep(1.5)
        assert not rec.kinds('hang') and sup.starts == 1
    finally:
        sup.stop()


def test_the_sample_timer_runs_from_the_first_byte_after_a_silence(rec):
    # silent (blocked, before its first byte) longer than the sample timeout, then samples: nothing killed
    script = 'import time\ntime.sleep(1.5)\nwhile True:\n    print("k : 1", flush=True); time.sleep(0.05)\n'
    seen = []

    def on_line(line, wall_time):
        rec.on_line(line, wall_time)
        seen.append(line)
        return len(seen) % 2 == 0     # every other line completes a sample

    sup = ProcessSupervisor([PY, '-c', script], on_line, on_event=rec.on_event, restart_timeout=0.5,
                            sample_timeout=0.5, start_timeout=20.0, backoff_initial=0.05)
    sup.start()
    try:
        assert rec.wait_for(lambda: len(rec.lines) >= 10, timeout=30.0)
    finally:
        sup.stop()
    assert not rec.kinds('hang') and sup.starts == 1
