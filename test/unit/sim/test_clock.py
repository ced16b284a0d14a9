"""anafi_sim.sim.clock: decimation, real-time pacing, overruns / re-anchors and achieved rates on a fake wall clock."""
import threading

import pytest

from anafi_sim.mission import monitor
from anafi_sim.sim.clock import (MAX_LAG, TIMER_PHASES, Lockstep, Pacer, Periodic, ScaledSteps, SimClock, StartHold, aligned_start, lockstep_values,
                                 report_values)


def run(clock, wall, steps, cost=lambda k: 0.0):
    """The node's loop on a fake wall clock: each step takes ``cost(k)`` s, then sleeps what pace() says."""
    ticks = []
    for _ in range(steps):
        tick = clock.tick()
        ticks.append(tick)
        wall += cost(tick.k)
        wall += clock.pace(wall)
    return wall, ticks


# --- Periodic ----------------------------------------------------------------------------------

def test_periodic_keeps_phase_and_catches_up_at_most_one_period():
    p = Periodic(0.01)
    due = [k for k in range(1, 201) if p.due(k * 0.005)]     # 200 Hz -> 100 Hz: every other step
    assert due == [1] + list(range(2, 201, 2))                # first at the first step (t = 0 was due)
    p = Periodic(1.0)
    assert p.due(0.0) and not p.due(0.5) and p.due(1.0)
    assert p.due(5.0)                      # a gap: due once, then one period after it
    assert not p.due(5.5) and p.due(6.0)


def test_periodic_without_phase_counts_from_now():
    p = Periodic(1.0, first=10.0, keep_phase=False)
    assert not p.due(9.0) and p.due(10.3) and not p.due(11.2) and p.due(11.3)
    with pytest.raises(ValueError):
        Periodic(0.0)


# --- Pacer -------------------------------------------------------------------------------------

def test_pacer_sleeps_to_the_schedule():
    p = Pacer(0.01)
    p.start(100.0)
    assert p.wait(100.004) == pytest.approx(0.006)
    assert p.wait(100.02) == 0.0          # on time to the microsecond: no sleep, not late
    assert p.overruns == 0 and p.reanchors == 0


def test_pacer_counts_overruns_and_catches_up_below_max_lag():
    p = Pacer(0.01, max_lag=0.25)
    p.start(0.0)
    assert p.wait(0.05) == 0.0            # cycle 1 due at 0.01: 40 ms late, an overrun
    assert p.overruns == 1 and p.reanchors == 0
    for wall in (0.051, 0.052, 0.053):    # cycles 2..4 due at 0.02..0.04: catching up, still > 1 period late
        assert p.wait(wall) == 0.0
    assert p.overruns == 4
    assert p.wait(0.054) == 0.0 and p.overruns == 4         # cycle 5 due at 0.05: 4 ms late, not an overrun
    assert p.wait(0.055) == pytest.approx(0.005)            # back on the schedule
    assert p.reanchors == 0


def test_pacer_reanchors_after_a_stall_longer_than_max_lag():
    p = Pacer(0.01, max_lag=0.25)
    p.start(0.0)
    assert p.wait(0.5) == 0.0             # stalled half a second
    assert p.overruns == 1 and p.reanchors == 1
    assert p.wait(0.505) == pytest.approx(0.005)    # the schedule restarts from the stall, no burst


def test_pacer_without_lag_never_catches_up():
    """max_lag 0 (the kinematic world): a late cycle moves the schedule; the next one is a period later."""
    p = Pacer(0.01, max_lag=0.0)
    p.start(0.0)
    assert p.wait(0.015) == 0.0 and p.reanchors == 1 and p.overruns == 0
    assert p.wait(0.016) == pytest.approx(0.009)
    with pytest.raises(ValueError):
        Pacer(0.0)


# --- SimClock ----------------------------------------------------------------------------------

def test_sim_clock_steps_decimates_and_publishes_clock():
    c = SimClock(200.0, rtf=1.0, telemetry_rate=100.0, estimate_rate=30.0, publish_clock=True)
    c.start(0.0)
    _, ticks = run(c, 0.0, 400)                       # 2 s of simulation
    assert ticks[-1].t == pytest.approx(2.0) and ticks[-1].k == 400
    assert [t.k for t in ticks] == list(range(1, 401))
    assert sum(t.telemetry for t in ticks) == 201     # 100 Hz (and at the first step)
    assert sum(t.estimate for t in ticks) == pytest.approx(61, abs=1)   # 30 Hz of a 200 Hz step
    assert all(t.clock for t in ticks)
    quiet = SimClock(200.0)
    quiet.start(0.0)
    assert not any(t.clock for t in run(quiet, 0.0, 3)[1])


@pytest.mark.parametrize('rate, rtf', [(200.0, 1.0), (200.0, 2.0), (500.0, 0.5)])
def test_sim_clock_paces_at_rate_times_rtf(rate, rtf):
    c = SimClock(rate, rtf=rtf)
    c.start(10.0)
    wall, _ = run(c, 10.0, 1000, cost=lambda k: 0.2 / (rate * rtf))   # a step takes a fifth of its period
    report = c.report(wall)
    assert wall - 10.0 == pytest.approx(1000 / (rate * rtf))
    assert report.achieved_rate == pytest.approx(rate * rtf) and report.wanted_rate == rate * rtf
    assert report.achieved_rtf == pytest.approx(rtf)
    assert report.overruns == 0 and report.reanchors == 0
    assert report.sim_time == pytest.approx(1000 / rate)


def test_sim_clock_too_slow_overruns_and_reports_the_achieved_rtf():
    c = SimClock(200.0, rtf=1.0)
    c.start(0.0)
    wall, _ = run(c, 0.0, 200, cost=lambda k: 0.01)    # each step takes 10 ms: half real time
    report = c.report(wall)
    assert report.achieved_rtf == pytest.approx(0.5)
    assert report.achieved_rate == pytest.approx(100.0)
    assert report.overruns > 150                      # steps more than 5 ms late
    assert 3 <= report.reanchors <= 4                 # 2 s wall for 1 s sim: 1 s behind, re-anchored per 0.25 s


def test_sim_clock_reanchors_once_after_a_stall_and_keeps_real_time():
    c = SimClock(200.0)
    c.start(0.0)
    wall, _ = run(c, 0.0, 400, cost=lambda k: 1.0 if k == 100 else 0.0)   # one 1 s stall
    report = c.report(wall)
    assert report.reanchors == 1 and report.overruns == 1
    assert wall == pytest.approx(2.995)              # 2 s of steps + the stall (less its step's period), no burst


def test_sim_clock_reports_since_the_previous_report():
    c = SimClock(200.0)
    c.start(0.0)
    wall, _ = run(c, 0.0, 200)
    assert c.report(wall).achieved_rate == pytest.approx(200.0)
    wall, _ = run(c, wall, 100, cost=lambda k: 0.01)    # now a step takes two periods: 100 Hz
    assert c.report(wall).achieved_rate == pytest.approx(100.0)
    assert c.report(wall).achieved_rate == 0.0         # nothing since (zero span)


def test_sim_clock_refuses_bad_rates():
    for kwargs in ({'rate': 0.0}, {'rate': 200.0, 'rtf': 0.0}, {'rate': 200.0, 'telemetry_rate': -1.0}):
        with pytest.raises(ValueError):
            SimClock(**kwargs)


def test_report_values_keep_the_keys_the_monitor_reads():
    c = SimClock(200.0, rtf=2.0)
    c.start(0.0)
    wall, _ = run(c, 0.0, 10)
    values = dict(report_values(c.report(wall)))
    assert values[monitor.SIM_RTF_KEY] == '2.000'
    assert values[monitor.SIM_OVERRUNS_KEY] == '0'
    assert [k for k in values if k.startswith(monitor.SIM_REANCHOR_PREFIX)] == \
        ['schedule re-anchors (> %.2f s behind)' % MAX_LAG]
    assert values['physics rate wanted [Hz wall]'] == '400.0' and values['sim time [s]'] == '0.050'


# --- ScaledSteps -------------------------------------------------------------------------------

def test_scaled_steps_scale_cap_and_count():
    s = ScaledSteps(rtf=2.0, max_step=0.1)
    assert s.step(0.01) == pytest.approx(0.02)
    assert s.step(0.0) == 0.0 and s.step(-0.01) < 0.0
    assert s.step(1.0) == 0.1 and s.overruns == 1
    with pytest.raises(ValueError):
        ScaledSteps(0.0, 0.1)


# ------------------------------------------------------------------ lockstep
def test_pacer_resume_continues_without_catching_up_or_counting():
    p = Pacer(0.01, max_lag=0.25)
    p.start(0.0)
    assert p.wait(0.0) == pytest.approx(0.01)
    p.resume(5.0)                       # a 5 s lockstep wait
    assert p.wait(5.0) == pytest.approx(0.01)
    assert (p.overruns, p.reanchors) == (0, 0)


def test_lockstep_waits_only_once_armed_and_at_the_period_tick():
    lock = Lockstep(0.1, 0.005, timeout=0.05)
    assert not lock.due(10.0)                        # no command yet: free-running
    lock.on_command(0.2)                             # arms; the next command is due 0.1 s later
    assert not lock.due(0.295)
    assert lock.due(0.3)
    assert not lock.wait()                           # nothing newer than 0.2 came: time-out
    assert (lock.timeouts, lock.missed) == (1, 1)
    assert not lock.due(0.395) and lock.due(0.4)     # the period went on without the command
    lock.on_command(0.4)
    assert lock.wait()                               # already there: no wait
    assert lock.last == pytest.approx(0.4) and lock.missed == 0
    assert lock.report().state == 'lockstep' and lock.report().waits == 2


def test_lockstep_takes_the_period_of_the_stamps_not_of_arrival():
    lock = Lockstep(0.1, 0.005, timeout=0.05)
    lock.on_command(0.105)                           # a timer that fired one tick late once
    lock.on_command(0.2)                             # then back in phase, before the sim got to 0.205
    assert lock.due(0.205) and lock.wait()
    assert lock.last == pytest.approx(0.2)
    assert lock.due(0.3) and not lock.due(0.295)


def test_lockstep_wait_ends_when_the_command_arrives_from_another_thread():
    lock = Lockstep(0.1, 0.005, timeout=30.0)
    lock.on_command(1.0)
    pokes = []
    sender = threading.Timer(0.05, lock.on_command, args=(1.1,))
    sender.start()
    assert lock.wait(poke=lambda: pokes.append(1))   # well before the 30 s time-out
    sender.join()
    assert lock.timeouts == 0 and lock.report().wait_wall_max < 30.0
    assert pokes                                     # /clock repeated while waiting


def test_lockstep_disarms_after_max_missed_and_rearms_on_the_next_command():
    lock = Lockstep(0.1, 0.005, timeout=0.01, max_missed=3)
    lock.on_command(1.0)
    t = 1.1
    for _ in range(3):
        assert lock.due(t) and not lock.wait()
        t += 0.1
    assert not lock.due(t) and not lock.due(t + 10.0)   # silent controller: the world goes on
    report = lock.report()
    assert (report.timeouts, report.disarms, report.state) == (3, 1, 'free-running: controller silent')
    lock.on_command(5.0)
    assert lock.due(5.1) and lock.report().state == 'lockstep'


def test_lockstep_close_ends_a_wait_without_counting_a_timeout():
    lock = Lockstep(0.1, 0.005, timeout=30.0)
    lock.on_command(1.0)
    closer = threading.Timer(0.05, lock.close)
    closer.start()
    assert not lock.wait()
    closer.join()
    assert lock.timeouts == 0 and not lock.due(1.1)


def test_lockstep_refuses_bad_settings():
    for args in ((0.0, 0.005), (0.1, 0.0), (0.1, 0.005, 0.0), (0.1, 0.005, 1.0, 0)):
        with pytest.raises(ValueError):
            Lockstep(*args)


def test_lockstep_values_name_every_figure():
    lock = Lockstep(0.1, 0.005, timeout=0.01)
    values = dict(lockstep_values(lock.report()))
    assert values['lockstep'] == 'waiting for the first command'
    assert values['lockstep timeouts (period went on without a command)'] == '0'


def test_start_hold_waits_for_the_subscribers_to_settle():
    hold = StartHold(settle=2.0, timeout=60.0)
    assert not hold.ready(0.0, 0)
    assert not hold.ready(5.0, 0)          # nobody listens yet
    assert not hold.ready(5.5, 3)
    assert not hold.ready(7.0, 4)          # still coming up
    assert not hold.ready(8.9, 4)
    assert hold.ready(9.0, 4) and not hold.timed_out


def test_start_hold_gives_up_after_its_timeout():
    hold = StartHold(settle=2.0, timeout=10.0)
    assert not hold.ready(0.0, 0)
    assert hold.ready(10.0, 0) and hold.timed_out


def test_aligned_start_is_the_next_instant_of_the_phase_grid():
    assert aligned_start(0.0, 0.1, 0.03) == pytest.approx(0.03)
    assert aligned_start(12.345, 0.1, 0.03) == pytest.approx(12.43)
    assert aligned_start(12.43, 0.1, 0.03) == pytest.approx(12.43)          # on the grid: now
    assert aligned_start(12.4300001, 0.1, 0.03) == pytest.approx(12.53)
    assert aligned_start(7.0, 0.1, 0.08) == pytest.approx(7.08)
    assert aligned_start(7.25, 0.1, -1.0) == 7.25                          # < 0: no grid
    for now in (0.0, 0.017, 3.999, 1234.56789):
        t = aligned_start(now, 0.1, 0.08)
        assert now - 1e-9 <= t < now + 0.1 and abs(((t - 0.08) / 0.1) - round((t - 0.08) / 0.1)) < 1e-6


def test_timer_phases_put_the_waypoint_half_a_period_old_at_the_controllers_cycle():
    """The generator ticks 50 ms before each controller cycle (10 Hz both): the mean age over a random phase;
    the engine's schedule uses the same two (one source)."""
    from anafi_lab.engine.engine import DEFAULT_SCHEDULE
    age = (TIMER_PHASES['controller'] - TIMER_PHASES['generator']) % 0.1
    assert age == pytest.approx(0.05)
    assert DEFAULT_SCHEDULE['controller_phase'] == TIMER_PHASES['controller']
    assert DEFAULT_SCHEDULE['generator_phase'] == TIMER_PHASES['generator']
