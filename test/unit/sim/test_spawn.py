"""anafi_sim.gazebo.spawn: SpawnTracker bookkeeping and the SpawnDriver's world-loss rule (fake worlds, fake clock)."""
import time

import pytest

from anafi_sim.gazebo import spawn


# --- SpawnTracker ------------------------------------------------------------------------------

def test_spawn_failure_retries_after_the_retry_period():
    t = spawn.SpawnTracker(('a', 'b'), retry_period=1.0)
    t.on_world(True, 'w1', 0.0)
    assert t.due_actions(0.0) == [('spawn', 'a'), ('spawn', 'b')]
    t.on_spawn_result('a', False, 'timeout', 0.0)
    t.on_spawn_result('b', True, 'ok', 0.0)
    assert t.due_actions(0.5) == []
    assert t.due_actions(1.0) == [('spawn', 'a')]
    assert t.spawn_failures == 1 and 'timeout' in t.last_error


def test_existing_model_is_deleted_then_spawned():
    t = spawn.SpawnTracker(('a',))
    t.on_world(True, 'w1', 0.0)
    t.on_spawn_result('a', False, 'SpawnModel: Failure - entity already exists.', 0.0)
    assert t.due_actions(0.0) == [('delete', 'a')]
    t.on_delete_result('a', True, 'ok', 0.1)
    assert t.due_actions(0.1) == [('spawn', 'a')]


def test_world_gone_then_back_triggers_respawn():
    t = spawn.SpawnTracker(('a',))
    t.on_world(True, 'w1', 0.0)
    t.on_spawn_result('a', True, '', 0.0)
    t.on_world(False, None, 1.0)
    assert not t.is_spawned('a') and t.world_losses == 1
    assert t.due_actions(1.5) == []
    t.on_world(True, 'w2', 2.0)
    assert t.due_actions(2.0) == [('spawn', 'a')]


def test_model_missing_from_model_states_after_grace_triggers_respawn():
    t = spawn.SpawnTracker(('a', 'b'), missing_grace=1.0)
    t.on_world(True, 'w1', 0.0)
    t.on_spawn_result('a', True, '', 0.0)
    t.on_spawn_result('b', True, '', 0.0)
    t.on_model_states(['b'], 0.5)  # too early to tell: model_states may lag the spawn
    assert t.is_spawned('a')
    t.on_model_states(['a', 'b', 'other'], 1.5)
    assert t.all_spawned
    t.on_model_states(['b'], 2.0)
    assert not t.is_spawned('a') and t.is_spawned('b')
    assert t.models_missing == 1
    assert t.due_actions(2.0) == [('spawn', 'a')]


def test_tracker_refuses_bad_periods():
    with pytest.raises(ValueError):
        spawn.SpawnTracker(('a',), retry_period=0.0)
    with pytest.raises(ValueError):
        spawn.SpawnTracker(('a',), missing_grace=-1.0)


# --- call_with_timeout -------------------------------------------------------------------------

def test_call_with_timeout_result_error_and_timeout():
    assert spawn.call_with_timeout(lambda: 42, 1.0) == (True, 42)
    ok, text = spawn.call_with_timeout(lambda: 1 / 0, 1.0)
    assert not ok and text.startswith('ZeroDivisionError')
    ok, text = spawn.call_with_timeout(lambda: time.sleep(1.0), 0.05)
    assert (ok, text) == (False, 'no answer within 0.1 s')


# --- SpawnDriver against a fake world ----------------------------------------------------------

class FakeWorld(object):
    """A world's spawn service as the master and rospy see it.

    ``uri``: the URI registered with the master (None: not registered); ``up``: the service answers.
    A world killed with SIGKILL stays registered (uri kept) but does not answer. ``during_contact``: run
    once inside the next contact (a successor registering while the caller waits for the service).
    """

    def __init__(self, uri='rosrpc://world:1'):
        self.uri = uri
        self.up = True
        self.models = set()
        self.spawned = []     # names of the successful spawn calls, in order
        self.calls = []       # 'contact' / 'lookup', in order
        self.during_contact = None

    def contact(self, timeout):
        self.calls.append('contact')
        hook, self.during_contact = self.during_contact, None
        if hook is not None:
            hook()
        if not self.up:
            raise RuntimeError('timeout exceeded while waiting for service')

    def lookup(self):
        self.calls.append('lookup')
        if self.uri is None:
            raise RuntimeError('no provider')
        return self.uri

    def spawn(self, name):
        if not self.up:
            raise RuntimeError('unable to connect')
        if name in self.models:
            return False, 'SpawnModel: Failure - entity already exists.'
        self.models.add(name)
        self.spawned.append(name)
        return True, 'SpawnModel: Successfully spawned entity'

    def delete(self, name):
        if name not in self.models:
            return False, 'DeleteModel: model does not exist'
        self.models.discard(name)
        return True, 'DeleteModel: successfully deleted model'

    def kill(self):
        """SIGKILL: the models are gone, the registration stays."""
        self.up = False
        self.models = set()

    def restart(self, uri):
        """A new world registers the same service at a new URI."""
        self.uri = uri
        self.up = True
        self.models = set()


class Clock(object):
    def __init__(self):
        self.t = 0.0

    def __call__(self):
        return self.t


def driver(world, names=('anafi', 'anafi_camera'), **kwargs):
    clock = Clock()
    d = spawn.SpawnDriver(spawn.SpawnTracker(names, retry_period=1.0), world.contact, world.lookup,
                          world.spawn, world.delete, clock=clock, **kwargs)
    return d, clock


def check(d, clock, dt=0.5):
    """One world check and the due calls, ``dt`` s after the previous one."""
    clock.t += dt
    return d.check_world() + d.do_actions()


def spawned_driver(world, **kwargs):
    d, clock = driver(world, **kwargs)
    logs = check(d, clock, 0.0)
    assert d.tracker.all_spawned, logs
    assert ('info', 'mirror: Gazebo available at rosrpc://world:1') in logs
    assert world.spawned == ['anafi', 'anafi_camera']
    return d, clock


def test_contacts_the_service_before_looking_up_its_uri():
    world = FakeWorld()
    d, clock = spawned_driver(world)
    assert world.calls[:2] == ['contact', 'lookup']


def test_a_world_lost_once_is_not_a_loss():
    world = FakeWorld()
    d, clock = spawned_driver(world)
    world.up = False                      # one check of a busy world times out
    assert check(d, clock) == []
    assert d.tracker.all_spawned and d.tracker.world_available and d.missed_checks == 1
    world.up = True
    assert check(d, clock) == []
    assert world.spawned == ['anafi', 'anafi_camera']        # no respawn
    assert d.tracker.world_losses == 0 and d.tracker.respawns == 0


def test_a_world_lost_twice_is_lost_and_the_models_respawn_once():
    world = FakeWorld()
    d, clock = spawned_driver(world)
    world.kill()
    world.uri = None                      # and it unregistered
    assert check(d, clock) == []
    logs = check(d, clock)
    assert logs == [('error', 'mirror: Gazebo went away (/gazebo/spawn_urdf_model no longer reachable); will '
                              'respawn the models when it is back')]
    assert not d.tracker.world_available and d.tracker.world_losses == 1
    assert check(d, clock, 1.0) == []     # still gone: the error is not repeated at once
    world.restart('rosrpc://world:2')
    logs = check(d, clock, 1.0)
    assert ('warn', 'mirror: Gazebo restarted (/gazebo/spawn_urdf_model now at rosrpc://world:2); '
                    'respawning') in logs
    assert ('info', 'mirror: respawned anafi (SpawnModel: Successfully spawned entity)') in logs
    for _ in range(5):
        assert check(d, clock) == []
    assert world.spawned == ['anafi', 'anafi_camera'] * 2
    assert d.tracker.respawns == 2 and d.tracker.all_spawned


def test_a_killed_world_replaced_during_a_contact_is_respawned_once():
    """The double-respawn defect: the dead world's URI is still registered while its successor starts."""
    world = FakeWorld()
    d, clock = spawned_driver(world)
    world.kill()                          # SIGKILL: rosrpc://world:1 stays registered, nothing answers
    assert check(d, clock) == [] and check(d, clock)[0][0] == 'error'
    assert not d.tracker.world_available
    # the successor registers while the next check waits for the service
    world.during_contact = lambda: world.restart('rosrpc://world:2')
    check(d, clock, 1.0)
    assert d.tracker.world_id == 'rosrpc://world:2'
    for _ in range(6):
        assert check(d, clock) == []
    assert world.spawned == ['anafi', 'anafi_camera'] * 2          # one respawn each, not two
    assert d.tracker.respawns == 2 and d.tracker.world_restarts == 1


def test_a_world_that_never_comes_logs_a_clear_error_not_too_often():
    world = FakeWorld(uri=None)
    world.up = False
    d, clock = driver(world, absent_log_period=5.0)
    logs = check(d, clock, 0.0)
    assert len(logs) == 1 and logs[0][0] == 'error'
    assert 'Gazebo not available' in logs[0][1] and '/gazebo/spawn_urdf_model' in logs[0][1]
    assert check(d, clock, 1.0) == []
    for _ in range(3):
        check(d, clock, 1.0)
    assert len(check(d, clock, 1.0)) == 1  # again after 5 s
    assert d.tracker.spawns == 0


def test_left_over_model_is_deleted_then_spawned():
    world = FakeWorld()
    world.models.add('anafi')             # from an earlier run
    d, clock = driver(world, names=('anafi',))
    logs = check(d, clock, 0.0)
    assert ('warn', 'mirror: spawning anafi failed: SpawnModel: Failure - entity already exists.; retrying') in logs
    logs = d.do_actions()
    assert logs[0][0] == 'info' and 'deleted the existing model anafi' in logs[0][1]
    assert d.do_actions() == [('info', 'mirror: spawned anafi (SpawnModel: Successfully spawned entity)')]
    assert d.tracker.all_spawned


def test_a_hanging_spawn_call_times_out_and_is_retried():
    world = FakeWorld()
    world.spawn = lambda name: time.sleep(1.0)
    d, clock = driver(world, names=('anafi',), spawn_timeout=0.05, label='airship')
    logs = check(d, clock, 0.0)
    assert ('warn', 'airship: spawning anafi failed: no answer within 0.1 s; retrying') in logs
    assert d.tracker.spawn_failures == 1 and not d.tracker.all_spawned
    assert d.do_actions() == []           # retry after retry_period
    clock.t += 1.0
    assert len(d.do_actions()) == 1


def test_poll_checks_every_check_period_while_available_else_every_retry_period():
    world = FakeWorld()
    d, clock = driver(world, check_period=0.5)
    assert d.poll(0.0)                    # checked (and spawned) at once
    contacts = world.calls.count('contact')
    clock.t = 0.4
    assert d.poll() == [] and world.calls.count('contact') == contacts
    clock.t = 0.5
    d.poll()
    assert world.calls.count('contact') == contacts + 1
    world.up = False
    world.uri = None
    for t in (1.0, 1.5):                  # two misses: gone
        clock.t = t
        d.poll()
    assert not d.tracker.world_available
    contacts = world.calls.count('contact')
    clock.t = 2.0
    d.poll()
    assert world.calls.count('contact') == contacts          # retry_period 1 s now
    clock.t = 2.5
    d.poll()
    assert world.calls.count('contact') == contacts + 1


def test_delete_all_deletes_the_spawned_models():
    world = FakeWorld()
    d, clock = spawned_driver(world)
    logs = d.delete_all(timeout=1.0)
    assert logs == [('info', 'mirror: deleted anafi'), ('info', 'mirror: deleted anafi_camera')]
    assert world.models == set()
    logs = d.delete_all(timeout=1.0)      # already gone from the world: a warning each, no exception
    assert logs[0] == ('warn', 'mirror: could not delete anafi on shutdown: DeleteModel: model does not exist')
    assert len(logs) == 2


def test_model_states_feed_the_tracker_under_the_lock():
    world = FakeWorld()
    d, clock = spawned_driver(world)
    d.on_model_states(['anafi'], 5.0)
    assert d.tracker.is_spawned('anafi') and not d.tracker.is_spawned('anafi_camera')
    assert d.tracker.models_missing == 1


def test_driver_refuses_non_positive_periods():
    world = FakeWorld()
    with pytest.raises(ValueError, match='periods and timeouts must be > 0'):
        driver(world, spawn_timeout=0.0)


def test_a_shared_check_asks_the_world_once_per_max_age_for_every_driver():
    world = FakeWorld()
    clock = Clock()
    drivers = [spawn.SpawnDriver(spawn.SpawnTracker(('anafi%d' % i,), retry_period=1.0), world.contact,
                                 world.lookup, world.spawn, world.delete, clock=clock, label='mirror%d' % i)
               for i in range(20)]
    shared = spawn.SharedCheck(drivers[0].probe, 0.25, clock=clock)
    for d in drivers:
        d.shared_check = shared
    for step in range(4):                 # every driver checks every 0.5 s (their default check period)
        for d in drivers:
            d.check_world()
            d.do_actions()
        clock.t += 0.5
    assert shared.checks == 4 and world.calls == ['contact', 'lookup'] * 4
    assert all(d.tracker.all_spawned for d in drivers)
    world.kill()
    world.uri = None                      # the world is lost: each driver confirms it on its next check
    for d in drivers:
        assert d.check_world() == []
    clock.t += 0.5
    for d in drivers:
        logs = d.check_world()
        assert logs and logs[0][0] == 'error' and not d.tracker.world_available


def test_a_shared_check_answers_callers_in_between_and_refuses_a_bad_age():
    clock = Clock()
    answers = iter(['rosrpc://a:1', None])
    shared = spawn.SharedCheck(lambda: next(answers), 0.25, clock=clock)
    assert shared() == shared() == 'rosrpc://a:1'
    clock.t = 0.24
    assert shared() == 'rosrpc://a:1'
    clock.t = 0.25
    assert shared() is None and shared.checks == 2
    with pytest.raises(ValueError):
        spawn.SharedCheck(lambda: None, 0.0)
