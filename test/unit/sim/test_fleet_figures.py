"""The fleet benchmark's figures where they are quoted: benchmarks/results/fleet.md and the generated block of
docs/fleet.md are what benchmarks/fleet_report.py renders from benchmarks/results/fleet.json; the fleet cap's
CPU per drone (anafi_sim.launch_check.CPU_PER_DRONE) is the one measured there; every quote of the cap in the
docs, the launch files and the code is the cap's. And the rules behind them: *holds real time* (one definition,
every run, the mirror included), the spread over the runs, the roles of a shared layout's host processes, the
older one-run-per-size format. No ROS, no benchmark run."""
import copy
import importlib.util
import functools
import os
import re

import pytest

from anafi_sim import launch_check
from conftest import ROOT

FLEET_JSON = os.path.join(ROOT, 'benchmarks', 'results', 'fleet.json')
FLEET_MD = os.path.join(ROOT, 'benchmarks', 'results', 'fleet.md')
DOCS = os.path.join(ROOT, 'docs', 'fleet.md')
#: where the fleet cap or the benchmark's figures are quoted
QUOTE_FILES = ['README.md', 'anafi_sim/launch/fleet.launch', 'anafi_sim/launch_check.py',
               'anafi_sim/nodes/fleet_launcher.py', 'test/ros/test_fault_matrix.py'] + \
    sorted(os.path.relpath(os.path.join(ROOT, 'docs', f), ROOT) for f in os.listdir(os.path.join(ROOT, 'docs'))
           if f.endswith('.md'))


def _report():
    spec = importlib.util.spec_from_file_location('fleet_report', os.path.join(ROOT, 'benchmarks', 'fleet_report.py'))
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


report = _report()


def _read(path):
    with open(path) as f:
        return f.read()


def _drone(rtf=1.0, truth=100.0, mirror=100.0):
    return {'rtf': rtf, 'truth_hz': truth, 'mirror_hz': mirror, 'mirror_in_hz': mirror, 'mirror_decimated_hz': 0.0,
            'lag_p99_ms': 1.0, 'overruns': 0.0}


def _run(n, repeat=0, layout='per_drone', cpu=20.0, **drone):
    return {'layout': layout, 'n': n, 'repeat': repeat, 'drones': dict(('anafi%d' % (i + 1), _drone(**drone))
                                                                       for i in range(n)),
            'roles': {'mirror': [cpu * n * 0.5, n], 'world': [cpu * n * 0.5, 1]}, 'busy': 10.0, 'other_jobs': 0.0,
            'bench_cpu': 0.5, 'load_before': [0.5, 0, 0], 'load_after': [0.6, 0, 0], 'startup_s': 4.0, 'wall': 10.0}


def _data(runs, layouts=('per_drone',), repeats=2):
    return {'format': 2, 'fleet': 'circles', 'settle': 5.0, 'duration': 10.0, 'repeats': repeats,
            'sizes': sorted(set(r['n'] for r in runs)), 'layouts': list(layouts), 'runs': runs, 'core_cost': None,
            'machine': {'date': '2026-01-01 00:00', 'python': '3.11.2', 'cores': 2, 'cpu_model': 'test'}}


# ----------------------------------------------------------------------------- the rules
def test_holding_real_time_needs_rtf_ground_truth_and_mirror_of_every_drone():
    assert report.run_holds(_run(2))
    assert report.run_holds(_run(2, rtf=0.98, truth=97.0, mirror=97.0))
    assert not report.run_holds(_run(2, mirror=96.9))       # the mirror counts
    assert not report.run_holds(_run(2, truth=96.9))
    assert not report.run_holds(_run(2, rtf=0.979))
    assert not report.run_holds(_run(2, rtf=float('nan')))
    missing = _run(2)
    missing['drones']['anafi2'] = {}                          # a drone without figures: not measured
    assert not report.run_holds(missing)
    assert not report.run_holds({'layout': 'per_drone', 'n': 2, 'repeat': 0, 'error': 'never flew'})
    assert report.HOLD == {'rtf': 0.98, 'truth_hz': 97.0, 'mirror_hz': 97.0}
    assert report.HOLD_TEXT == "every drone's RTF >= 0.98, ground truth >= 97 Hz and mirror sent >= 97 Hz"


def test_a_size_holds_only_when_every_run_holds_and_the_spread_is_over_the_runs():
    data = _data([_run(1, 0), _run(1, 1), _run(2, 0, cpu=18.0), _run(2, 1, cpu=19.0, mirror=90.0),
                  _run(4, 0, cpu=16.0), _run(4, 1, cpu=17.0)])
    rows = dict((r['n'], r) for r in report.summary(data))
    assert rows[1]['holds'] and not rows[2]['holds'] and rows[2]['held'] == 1 and rows[4]['holds']
    assert rows[2]['spread']['mirror_min'] == (90.0, 95.0, 100.0)
    assert rows[4]['spread']['cpu_per_drone'] == pytest.approx((16.0, 16.5, 17.0))
    [head] = report.headline(data)
    assert head['n'] == 4 and head['failing_above'] == []
    assert report.cap_cpu_per_drone(data, 'per_drone') == 0.165
    data['runs'][-1]['drones']['anafi3']['rtf'] = 0.9        # one run of 4 below: 1 is the largest holding
    [head] = report.headline(data)
    assert head['n'] == 1 and head['failing_above'] == [2, 4]
    assert report.cap_cpu_per_drone(data, 'per_drone') == 0.2
    assert report.fmt_spread((1.0, 1.0, 1.0), 3) == '1.000' and report.fmt_spread(None) == '-'


def test_layouts_are_summed_apart_and_a_shared_host_is_a_role_of_its_own():
    data = _data([_run(2, 0), _run(2, 1), _run(2, 0, 'shared', cpu=10.0), _run(2, 1, 'shared', cpu=11.0)],
                 layouts=('per_drone', 'shared'))
    heads = dict((h['layout'], h) for h in report.headline(data))
    assert heads['per_drone']['cpu_per_drone'] == 0.2 and heads['shared']['cpu_per_drone'] == 0.105
    role = report.role_of_cmdline
    host = ['/usr/bin/python3', '/ws/fleet_host.py', '__name:=fleet_drones', '__log:=/x.log']
    assert role(host) == 'host fleet_drones'
    assert role(['python3', 'fleet_host.py', '__name:=fleet_ground_truth']) == 'host fleet_ground_truth'
    assert role(['python3', '/x/interface_node.py', '__name:=interface']) == 'interface'
    assert role(['python3', '/x/kinematic_world_node.py']) == 'world'
    assert role(['/usr/bin/python3', '/usr/bin/rosmaster', '--core']) == 'master + rosout'
    assert role(['sleep', '1']) == 'other'
    rows = [{'roles': {'host fleet_drones': 1.0, 'world': 1.0, 'mirror': 1.0, 'other': 0.1}}]
    assert report.role_order(rows) == ['mirror', 'host fleet_drones', 'world', 'other']
    text = report.markdown(data)
    assert 'Layout shared:' in text and '`layout:=shared`' in text


def test_the_older_format_reads_as_one_run_per_size():
    old = {'results': [dict(_run(2), **{'n': 2}), _run(4)], 'fleet': 'circles', 'settle': 10.0,
           'duration': 30.0, 'core_cost': [{'numpy (before)': 30.0, 'plain Python (shipped)': 15.0}, 1e-17]}
    for r in old['results']:
        for key in ('layout', 'repeat', 'other_jobs'):
            del r[key]
    data = report.normalize(old)
    assert data['repeats'] == 1 and data['layouts'] == ['per_drone'] and len(data['runs']) == 2
    text = report.markdown(data)
    assert '| per_drone | 4 | 1 run | yes (1/1) |' in text and 'older format' in text


# ----------------------------------------------------------------------------- the committed figures
def test_fleet_md_and_the_docs_block_are_rendered_from_fleet_json():
    data = report.load(FLEET_JSON)
    assert _read(FLEET_MD) == report.markdown(data), 'rerun: python benchmarks/bench_fleet.py --from-json'
    block = report.current_docs_block(_read(DOCS))
    assert block == report.docs_block(data), 'rerun: python benchmarks/bench_fleet.py --from-json'


def test_the_docs_block_check_fails_on_a_figure_that_is_not_fleet_json_s():
    data = report.load(FLEET_JSON)
    changed = copy.deepcopy(data)
    for run in changed['runs']:
        for fig in run.get('drones', {}).values():
            if fig:
                fig['mirror_hz'] = 50.0
    assert report.docs_block(changed) != report.current_docs_block(_read(DOCS))
    assert report.current_docs_block('no markers') is None
    with pytest.raises(ValueError):
        report.replace_docs_block('no markers', data)


def test_the_fleet_cap_is_the_cpu_per_drone_measured_in_fleet_json():
    data = report.load(FLEET_JSON)
    machine = data['machine']       # the reference the conservative default scales names the machine measured
    assert launch_check.REFERENCE_MACHINE == dict((k, machine[k]) for k in ('cpu_model', 'cores', 'date'))
    assert sorted(launch_check.CPU_PER_DRONE) == sorted(report.LAYOUTS)
    for layout in report.LAYOUTS:
        if layout in data['layouts']:
            measured = report.cap_cpu_per_drone(data, layout)
            assert measured is not None, '%s: no size holds real time in fleet.json' % layout
            assert launch_check.CPU_PER_DRONE[layout] == pytest.approx(measured, abs=5e-4), \
                'set launch_check.CPU_PER_DRONE[%r] = %.3f (fleet.json)' % (layout, measured)
        else:   # not measured yet: the per-drone layout's figure stands in
            assert launch_check.CPU_PER_DRONE[layout] == launch_check.CPU_PER_DRONE['per_drone']


def test_the_fleet_cap_stays_below_the_smallest_size_fleet_json_saw_fail():
    data = report.load(FLEET_JSON)
    for layout in report.LAYOUTS:
        if layout in data['layouts']:
            measured = report.cap_failing_per_core(data, layout)
            assert launch_check.FAILING_PER_CORE[layout] == (None if measured is None else pytest.approx(measured)), \
                'set launch_check.FAILING_PER_CORE[%r] = %r (fleet.json)' % (layout, measured)
            head = [h for h in report.headline(data) if h['layout'] == layout][0]
            if head['failing_above']:
                assert launch_check.fleet_cap(data['machine']['cores'], layout) < min(head['failing_above'])


def test_the_failing_size_per_core_is_the_smallest_failing_above_the_largest_holding():
    runs = [_run(4), _run(4, 1), _run(8, mirror=90.0), _run(8, 1), _run(12), _run(12, 1), _run(16, rtf=0.5)]
    data = _data(runs)
    assert report.cap_failing_per_core(data, 'per_drone') == 8.0      # 8 failed once, 12 held: 16 fails above it
    data = _data([_run(4), _run(8, truth=90.0), _run(12, mirror=80.0)])
    assert report.cap_failing_per_core(data, 'per_drone') == 4.0
    assert report.cap_failing_per_core(_data([_run(4), _run(8)]), 'per_drone') is None
    assert report.fleet_cap(2, 0.06, 12.5) == 24 and report.fleet_cap(2, 0.271, None) == 7


def stale_quotes(text, cpu_per_drone, cap):
    """The quotes of the fleet cap in ``text`` that are not ``cpu_per_drone`` [core] or ``cap(cores)`` (or, given
    lists of each, not one of them: one per layout)."""
    cpus = cpu_per_drone if isinstance(cpu_per_drone, (list, tuple)) else [cpu_per_drone]
    caps = cap if isinstance(cap, (list, tuple)) else [cap]
    wrong = []
    for m in re.finditer(r'(\d+\.\d+)\s+core\s+per\s+drone|cores\s+/\s+(\d+\.\d+)', text):
        value = m.group(1) or m.group(2)
        if value not in ['%.3f' % c for c in cpus]:
            wrong.append(m.group(0))
    for m in re.finditer(r'fleet\s+cap\s+of\s+(\d+)\s+\((\d+)\s+cores|(?:\(|:\s)(\d+)\s+on\s+(\d+)\s+cores', text):
        got, cores = (m.group(1), m.group(2)) if m.group(1) else (m.group(3), m.group(4))
        if int(got) not in [c(int(cores)) for c in caps]:
            wrong.append(m.group(0))
    return wrong


def test_every_quote_of_the_fleet_cap_is_the_cap_s():
    layouts = sorted(launch_check.CPU_PER_DRONE)
    cpus = [launch_check.CPU_PER_DRONE[layout] for layout in layouts]
    caps = [functools.partial(launch_check.fleet_cap, layout=layout) for layout in layouts]
    found = 0
    for name in QUOTE_FILES:
        text = _read(os.path.join(ROOT, name))
        assert stale_quotes(text, cpus, caps) == [], name
        found += len(re.findall(r'core\s+per\s+drone|cores\s+/\s+\d|(?:\(|:\s)\d+\s+on\s+\d+\s+cores', text))
    assert found >= 3    # the docs block, docs/reliability.md, the fault table


def test_the_quote_check_finds_a_stale_figure():
    cap = lambda cores: int(cores / 0.165)    # noqa: E731
    good = ('the fleet cap of 12 (2 cores / 0.165 core per drone (...)); cores / 0.165 (12 on 2 cores); '
            'load 1-5 on 2 cores')
    assert stale_quotes(good, 0.165, cap) == []
    bad = 'the fleet cap of 12 (2 cores / 0.190 core per\n  drone (...)); cores / 0.2: 14 on 2 cores'
    assert len(stale_quotes(bad, 0.165, cap)) == 3
    assert stale_quotes('the fleet cap of 10 (2 cores / 0.165 core per drone', 0.165, cap) == \
        ['fleet cap of 10 (2 cores']


def test_the_page_shows_the_largest_single_process_and_the_machine():
    runs = [_run(20, 0, 'shared'), _run(20, 1, 'shared')]
    runs[0]['largest_processes'] = [['host fleet_ground_truth_1', 41.0], ['host fleet_drones_1', 30.0]]
    runs[1]['largest_processes'] = [['host fleet_ground_truth_1', 45.0]]
    data = _data(runs, layouts=('shared',))
    [row] = report.summary(data)
    assert row['spread']['largest_process'] == (41.0, 43.0, 45.0)
    assert row['largest_roles'] == ['host fleet_ground_truth_1']
    text = report.markdown(data)
    assert '| 41.0 / 43.0 / 45.0 (host fleet_ground_truth_1) |' in text
    assert '| 41.0 (host fleet_ground_truth_1) |' in text and '2 CPU cores, test' in text
    assert 'not recorded' not in text
    block = report.docs_block(data)
    assert 'test, 2 cores' in block and 'the largest process 41.0 / 43.0 / 45.0 % of a core' in block
    del runs[0]['largest_processes'], runs[1]['largest_processes']
    assert 'not recorded by the runs of this file' in report.markdown(data)


def test_the_hosts_cpu_per_drone_adds_the_hosts_of_a_kind_at_the_largest_size_holding():
    assert report.host_kind('host fleet_ground_truth_2') == 'fleet_ground_truth'
    assert report.host_kind('host fleet_drones') == 'fleet_drones' and report.host_kind('mirror') is None

    def shared(n, repeat, gt, drones, **kw):
        run = _run(n, repeat, 'shared', **kw)
        run['roles'] = {'host fleet_ground_truth_1': [gt / 2.0, 1], 'host fleet_ground_truth_2': [gt / 2.0, 1],
                        'host fleet_drones': [drones, 1], 'telemetry CLI': [4.0, n]}
        return run
    runs = [shared(10, 0, 60.0, 50.0), shared(10, 1, 70.0, 40.0), shared(20, 0, 200.0, 200.0, rtf=0.5),
            shared(20, 1, 200.0, 200.0)]
    data = _data(runs, layouts=('shared',))
    assert report.host_cpu_per_drone(data) == {'fleet_ground_truth': 0.065, 'fleet_drones': 0.045}  # N = 10
    assert report.host_cpu_per_drone(_data([shared(4, 0, 10.0, 10.0, rtf=0.5)], layouts=('shared',))) is None


def test_the_processes_page_names_the_machine_the_load_the_split_and_each_host_against_the_budget():
    run = _run(20, 0, 'shared')
    run.update(processes=[['host fleet_ground_truth_1', 55.0], ['host fleet_drones_1', 40.0], ['telemetry CLI', 0.4],
                          ['roslaunch', 2.0]], drones_per_host={'fleet_drones': 7, 'fleet_ground_truth': 8})
    data = _data([run, {'layout': 'shared', 'n': 30, 'repeat': 0, 'error': 'timed out | never flew'}],
                 layouts=('shared',))
    data['machine']['load_start'] = [1.5, 2.0, 3.0]
    text = report.processes_markdown(data, budget=0.5)
    assert 'on test, 2 cores' in text and 'load average at the start 1.5 / 2.0 / 3.0' in text
    assert '| 20 | 1 | yes | fleet_drones 7, fleet_ground_truth 8 | 0.5 / 0.6 | 0 | fleet_ground_truth_1 55.0 | no |' \
        in text
    assert '| 30 | 1 | no: timed out / never flew |' in text
    assert '| host fleet_drones_1 | 40.0 |' in text and '| 1 other processes under 1 % each | 0.4 together |' in text
