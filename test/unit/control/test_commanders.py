"""One drone, one commander: the rule a commanding node applies to a second commander."""
import pytest

from anafi_control.commanders import CLEAR, DOWN, LISTEN, RESUMED, CommanderGuard


def test_alone_the_node_commands_after_listening_first():
    guard = CommanderGuard(2.0, listen_time=1.0)
    assert [guard.check(t) for t in (0.0, 0.5, 1.0, 100.0)] == [LISTEN, LISTEN, CLEAR, CLEAR] and guard.episodes == 0


def test_a_newcomer_that_hears_commands_while_listening_never_commands():
    guard = CommanderGuard(2.0, listen_time=1.0)
    assert guard.check(0.0) == LISTEN
    for t in (0.1, 0.2, 0.3):
        guard.on_command('/anafi/mpc_controller', t)
    assert [guard.check(t) for t in (0.35, 1.5)] == [DOWN, DOWN]
    assert guard.check(60.0) == DOWN and guard.episodes == 1    # present (it runs and publishes): still down


def test_a_second_commander_stands_the_node_down_until_it_is_quiet_and_gone_then_one_reset():
    guard = CommanderGuard(2.0, listen_time=0.0)
    guard.on_command('/anafi/rogue', 10.0)
    assert guard.check(10.1) == DOWN and guard.others(10.1) == ['/anafi/rogue'] and guard.episodes == 1
    guard.set_present('/anafi/rogue', True)       # still runs and publishes, even if quiet (it stood down too)
    assert guard.check(30.0) == DOWN and guard.episodes == 1
    guard.set_present('/anafi/rogue', False)      # gone: quiet for 20 s already
    assert guard.check(30.1) == RESUMED and guard.check(30.2) == CLEAR
    assert guard.foreign_commands == 1 and guard.others(30.2) == []


def test_a_node_that_stopped_publishing_releases_after_the_quiet_time():
    guard = CommanderGuard(2.0, listen_time=0.0)
    for t in (5.0, 5.1, 5.2):
        guard.on_command('/teleop', t)
    guard.set_present('/teleop', False)           # e.g. unregistered, or killed without unregistering
    assert guard.check(6.0) == DOWN and guard.check(7.1) == DOWN
    assert guard.check(7.3) == RESUMED and guard.foreign_commands == 3


def test_every_new_episode_is_counted():
    guard = CommanderGuard(1.0, listen_time=0.0)
    for start in (0.0, 10.0):
        guard.on_command('/x', start)
        guard.set_present('/x', False)
        assert guard.check(start + 0.5) == DOWN and guard.check(start + 1.5) == RESUMED
    assert guard.episodes == 2


def test_presence_of_an_unknown_node_is_ignored_and_the_quiet_time_is_checked():
    guard = CommanderGuard(listen_time=0.0)
    guard.set_present('/never_heard', True)
    assert guard.check(0.0) == CLEAR
    with pytest.raises(ValueError):
        CommanderGuard(0.0)
