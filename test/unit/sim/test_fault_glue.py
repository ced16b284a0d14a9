"""Fault handling without a running graph: master-restart detection (anafi_sim.ros.node), the fault table of
docs/reliability.md (tools/fault_table.py), the sphinx_with_gazebo/Sphinx wire type and gazebo_ros's wording."""
import os
import threading
from xmlrpc.server import SimpleXMLRPCServer

import pytest

from anafi_sim import paths
from anafi_sim.gazebo.kinematic_world import KinematicWorld
from anafi_sim import names
from anafi_sim.ros import node, wire_types
from conftest import load_script

fault_table = load_script('tools', 'fault_table.py')


# ------------------------------------------------------------------ master restart
def test_master_watch_tells_a_restart_from_an_outage():
    w = node.MasterWatch()
    assert w.update((100, 'run-a')) == 'ok'
    assert w.update((100, 'run-a')) == 'ok'
    assert w.update(None) == 'gone'           # master down: nothing to do yet
    assert w.update(None) == 'gone' and w.outages == 2
    assert w.update((100, 'run-a')) == 'ok'   # the same master answers again (a network hiccup)
    assert not w.restarted
    assert w.update((200, 'run-b')) == 'restarted'
    assert w.update(None) == 'restarted'      # latched
    assert w.describe() == 'pid 100 -> 200, run_id run-a -> run-b'


def test_master_watch_sees_a_new_run_id_with_the_same_pid():
    w = node.MasterWatch()
    w.update((1, 'a'))                        # e.g. pid 1 in a container
    assert w.update((1, 'b')) == 'restarted'


def test_master_watch_first_master_seen_late_is_the_reference():
    w = node.MasterWatch()
    assert w.update(None) == 'gone'
    assert w.update((7, None)) == 'ok'
    assert w.update((8, None)) == 'restarted'


class FakeMaster(object):
    def __init__(self, pid, run_id):
        self.server = SimpleXMLRPCServer(('127.0.0.1', 0), logRequests=False, allow_none=True)
        self.server.register_function(lambda caller: [1, 'pid', pid], 'getPid')
        self.server.register_function(
            lambda caller, key: [1, 'ok', run_id] if run_id is not None else [-1, 'no', 0], 'getParam')
        self.uri = 'http://127.0.0.1:%d/' % self.server.server_address[1]
        threading.Thread(target=self.server.serve_forever, daemon=True).start()

    def close(self):
        self.server.shutdown()
        self.server.server_close()


def test_master_identity_reads_pid_and_run_id_and_none_when_nobody_answers():
    m = FakeMaster(4242, 'abc')
    try:
        assert node.master_identity(m.uri, '/x') == (4242, 'abc')
    finally:
        m.close()
    assert node.master_identity(m.uri, '/x', timeout=0.5) is None     # closed port
    m2 = FakeMaster(5, None)
    try:
        assert node.master_identity(m2.uri, '/x') == (5, None)
    finally:
        m2.close()


def test_restore_params_puts_back_only_missing_ones(monkeypatch):
    server = {'/anafi/interface': {'rate': 50.0}}
    monkeypatch.setattr(node.rospy, 'has_param', lambda name: name in server)
    monkeypatch.setattr(node.rospy, 'set_param', lambda name, value: server.__setitem__(name, value))
    saved = {'/anafi/interface': {'rate': 100.0}, '/use_sim_time': True}
    assert node.restore_params(saved) == ['/use_sim_time']
    assert server['/anafi/interface'] == {'rate': 50.0}      # set on the new master meanwhile: kept
    assert server['/use_sim_time'] is True


def test_long_running_nodes_respawn_in_the_launch_files():
    launch = os.path.join(paths.package_dir(), 'anafi_sim', 'launch')
    for name, nodes in (('sim.launch', ('anafi_sim', 'interface')), ('controller.launch', ('$(arg controller)_controller',)),
                        ('spawn_anafi.launch', ('gazebo_mirror',))):
        with open(os.path.join(launch, name)) as f:
            text = f.read()
        for n in nodes:
            tag = text[text.index('name="%s"' % n):]
            tag = tag[:tag.index('>')]
            assert 'respawn="true"' in tag, (name, n)


# ------------------------------------------------------------------ fault table
def test_doc_fault_table_lists_exactly_the_faults_of_the_test():
    want = [name for name, _, _ in fault_table.test_faults()]
    assert len(want) >= 9 and len(set(want)) == len(want)
    with open(fault_table.DOC) as f:
        assert fault_table.doc_faults(f.read()) == want


def test_doc_shared_table_lists_the_fault_matrix_rows_and_how_each_runs():
    rows = fault_table.shared_rows()
    want = [name for name, _, _ in fault_table.test_faults(fault_table.TEST)]
    assert [r[0] for r in rows] == want
    assert set(fault_table._literal(fault_table.TEST, 'SHARED')) <= set(want)
    assert set(kind for _, kind, _ in rows) <= {'runs', 'adapted', 'skipped'}
    with open(fault_table.DOC) as f:
        assert fault_table.doc_faults(f.read(), fault_table.SHARED_BEGIN, fault_table.SHARED_END) == want


def test_shared_table_says_skipped_adapted_and_failed():
    rows = [('a', 'runs', 'x'), ('b', 'adapted', 'the host'), ('c', 'skipped', 'why'), ('d', 'runs', 'x')]
    text = fault_table.shared_table(rows, {'rows': [{'name': 'a', 'observed': 'fine', 'recovery': None},
                                                    {'name': 'b', 'observed': 'ok | then', 'stop': '1 m', 'recovery': 2.04}],
                                           'date': 'D'})
    lines = text.splitlines()
    assert lines[2] == '| `a` | runs | fine | - | - |'
    assert lines[3] == '| `b` | adapted: the host | ok / then | 1 m | 2.0 |'
    assert lines[4] == '| `c` | skipped: why | skipped | - | - |'
    assert lines[5].startswith('| `d` | runs | FAILED')


def test_fault_table_marks_unrecorded_faults_failed():
    faults = [('a', 'inj a', 'exp a'), ('b', 'inj b', 'exp b')]
    text = fault_table.table(faults, {'rows': [{'name': 'a', 'observed': 'x | y', 'stop': None, 'recovery': 1.26}],
                                      'date': 'D'})
    lines = text.splitlines()
    assert lines[2] == '| `a` | inj a | exp a | x / y | - | 1.3 |'
    assert lines[3].startswith('| `b` | inj b | exp b | FAILED')
    assert fault_table.doc_faults(fault_table.BEGIN + '\n' + text + '\n' + fault_table.END) == ['a', 'b']


# ------------------------------------------------------------------ interoperability
def test_sphinx_type_is_the_reference_implementations():
    cls = wire_types.sphinx_class()
    assert cls._type == 'sphinx_with_gazebo/Sphinx'
    assert cls._md5sum == '85390efb41e38eee13815912075e2a5a'
    assert list(cls.__slots__) == list(wire_types.SPHINX_FIELDS)
    assert not cls._has_header
    assert names.SPHINX_DATA == 'sphinx/drone_data' and names.DRONE_DATA != names.SPHINX_DATA


def test_drone_data_has_every_field_of_the_sphinx_type():
    anafi_msg = pytest.importorskip('anafi_sim.msg')
    missing = [f for f in wire_types.SPHINX_FIELDS if f not in anafi_msg.DroneData.__slots__]
    assert missing == []


def test_kinematic_world_uses_gazebo_ros_status_messages():
    world = KinematicWorld()
    urdf = '<robot name="box"><link name="base_link"/></robot>'
    assert world.spawn('box', urdf).status_message == 'SpawnModel: Successfully spawned entity'
    assert world.spawn('box', urdf) == (False, 'SpawnModel: Failure - entity already exists.')
    assert world.set_state('nobody', (0, 0, 0), (0, 0, 0, 1)) == (False, 'SetModelState: model does not exist')
    assert world.set_state('box', (0, 0, 0), (0, 0, 0, 1), reference_frame='nowhere') == (
        False, 'SetModelState: specified reference frame entity does not exist')
    assert world.set_state('box', (0, 0, 0), (0, 0, 0, 1)).status_message == 'SetModelState: set model state done'
    assert world.delete('box').status_message == 'DeleteModel: successfully deleted model'
    assert world.delete('box') == (False, 'DeleteModel: model does not exist')


def test_refreshing_some_rows_keeps_the_others_and_says_where_the_new_ones_come_from():
    faults = [('a', 'inject a', 'expect a'), ('b', 'inject b', 'expect b')]
    old = fault_table.table(faults, {'rows': [{'name': 'a', 'observed': 'old a', 'stop': None},
                                              {'name': 'b', 'observed': 'old b', 'stop': None}],
                                     'source': 'the run of 2026-01-01'})
    fresh = fault_table.table(faults, {'rows': [{'name': 'b', 'observed': 'new b', 'stop': 'x'}]})
    out = fault_table.replace_rows('\n' + old + '\n', fresh, ['b'], '`b` from the run of 2026-02-02.')
    assert '| `a` | inject a | expect a | old a | - | - |' in out
    assert '| `b` | inject b | expect b | new b | x | - |' in out and 'old b' not in out
    assert 'Generated by `tools/fault_table.py` from the run of 2026-01-01. Refreshed since: `b` from the run of ' \
           '2026-02-02.' in out
    again = fault_table.replace_rows(out, fresh, ['b'], '`b` from the run of 2026-03-03.')
    assert again.count('Refreshed since') == 1 and '2026-03-03' in again
    with pytest.raises(ValueError):
        fault_table.replace_rows(out, fresh, ['c'], '')
