"""Experiment batch report (pure Python, no ROS): the paper's Tables 3-5 from run summaries, as Markdown.

Stage: evaluation output -> report (anafi_lab/engine/ros_batch.py writes
benchmarks/results/experiments.md with it). Units: errors [m] (e = |waypoint - position|, ENU),
times [s], speeds [m/s].

A run record is a dict: ``scenario`` (name), ``controller`` ('mpc' | 'pid'), ``ok`` (bool),
``error`` (text), ``summary`` (the evaluator's summary dict: ``estimate`` / ``truth`` with e_max,
e_mu, e_sigma, ...), ``info`` (the experiment monitor's run_info dict: achieved_rtf, sim_overruns,
hover_commands, disturbed, ...), ``attempts`` (runs needed, >= 1), ``step`` (``step_response.as_dict`` for static waypoints, else None), ``wall_s`` (wall time of
the whole run incl. start-up and shut-down), ``plot`` (PNG path relative to the report, or '').

``render`` lays the records out like the paper: Table 3 (mean e per straight-line speed, ours next
to the paper's), Table 4 (circles) and Table 5 (vertical periodic motion) with e_max, e_mu, e_sigma
per scenario and controller against the drone's estimate (the paper's metric) and against ground
truth, the static waypoints' overshoot and settling, MPC-vs-PID per scenario, timing and the
simulator's keeping up, and the plots.
"""
import math

from anafi_lab.paper import (ALL_SCENARIOS, BEYOND, CIRCLE_SCENARIOS, CIRCLES, CONTROLLERS, KNOWN_CONTROLLERS,  # noqa: F401
                              PAPER_TABLE3, STATIC, STRAIGHT, STRAIGHT_SPEEDS, VERTICAL, VERTICAL_SCENARIOS)
from anafi_sim.numeric import fmt

SOURCES = (('estimate', 'vs the drone\'s estimate (the paper\'s metric)'), ('truth', 'vs ground truth'))
LABELS = {'mpc': 'MPC', 'pid': 'PID', 'preview_mpc': 'preview MPC'}


def present(records):
    """The controllers to tabulate: the paper's two, then those of ``BEYOND`` some record has."""
    have = set(r.get('controller') for r in records)
    return CONTROLLERS + tuple(c for c in BEYOND if c in have)


def index(records):
    """{(scenario, controller): record} (the last record wins)."""
    return dict(((r.get('scenario'), r.get('controller')), r) for r in records)


def stat(record, source, key):
    """Statistic ``key`` (e_max, e_mu, e_sigma, ...) of ``source`` ('estimate' | 'truth') of a record,
    None when the run failed or the value is absent."""
    if not record or not record.get('ok'):
        return None
    res = (record.get('summary') or {}).get(source)
    if not isinstance(res, dict):
        return None
    v = res.get(key)
    return v if isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) else None


def disturbed(record):
    """The run's 'disturbed' reason ('' when the controller ran undisturbed or it is unknown)."""
    return str(((record or {}).get('info') or {}).get('disturbed') or '')


def cell(record, source, key, digits=2):
    """``fmt`` of a statistic, with a dagger when the run was disturbed (see ``DAGGER_NOTE``)."""
    text = fmt(stat(record, source, key), digits)
    return text + ' †' if text != '-' and disturbed(record) else text


DAGGER_NOTE = ('† the controller was interrupted during this run (hover commands or a gap in its commands, '
               'i.e. a node starved of CPU) even after the retry: the number is not a clean controller result.')


def mpc_beats_pid(records, scenario, source='estimate', key='e_mu'):
    """True / False when both runs have the statistic (MPC strictly lower), None otherwise."""
    idx = index(records) if isinstance(records, list) else records
    a, b = stat(idx.get((scenario, 'mpc')), source, key), stat(idx.get((scenario, 'pid')), source, key)
    if a is None or b is None:
        return None
    return a < b


def _yes_no(v):
    return '-' if v is None else ('yes' if v else '**no**')


def table3(records):
    """Markdown lines of Table 3 (straight line: mean e per speed), ours next to the paper's."""
    idx = index(records)
    head = '| Controller / speed | ' + ' | '.join('%d m/s' % v for v in STRAIGHT_SPEEDS) + ' |'
    lines = [head, '|---|' + '---|' * len(STRAIGHT_SPEEDS)]
    for c in present(records):
        lines.append('| %s ours, vs estimate | ' % LABELS[c] + ' | '.join(
            '**%s**' % cell(idx.get((s, c)), 'estimate', 'e_mu') for s in STRAIGHT) + ' |')
        if c in PAPER_TABLE3:
            lines.append('| %s paper | ' % LABELS[c] + ' | '.join(fmt(v) for v in PAPER_TABLE3[c]) + ' |')
        lines.append('| %s ours, vs ground truth | ' % LABELS[c] + ' | '.join(
            cell(idx.get((s, c)), 'truth', 'e_mu') for s in STRAIGHT) + ' |')
        if c not in PAPER_TABLE3:
            continue
        ratios = []
        for s, p in zip(STRAIGHT, PAPER_TABLE3[c]):
            v = stat(idx.get((s, c)), 'estimate', 'e_mu')
            ratios.append(fmt(v / p) if v is not None else '-')
        lines.append('| %s ours / paper | ' % LABELS[c] + ' | '.join(ratios) + ' |')
    return lines


def stats_table(records, scenarios, params, source):
    """Markdown lines of a Table-4/5 style table: (r, v) rows, e_max e_mu e_sigma per controller."""
    idx = index(records)
    cols = []
    controllers = present(records)
    for c in controllers:
        cols += ['%s e_max' % LABELS[c], '%s e_mu' % LABELS[c], '%s e_sigma' % LABELS[c]]
    lines = ['| r [m] | v [m/s] | ' + ' | '.join(cols) + ' | MPC e_mu < PID e_mu |',
             '|---|---|' + '---|' * (len(cols) + 1)]
    for s, (r, v) in zip(scenarios, params):
        cells = []
        for c in controllers:
            rec = idx.get((s, c))
            cells += [cell(rec, source, k) for k in ('e_max', 'e_mu', 'e_sigma')]
        lines.append('| %g | %g | %s | %s |' % (r, v, ' | '.join(cells), _yes_no(mpc_beats_pid(idx, s, source))))
    return lines


def static_table(records):
    """Markdown lines: static waypoints' overshoot and settling per controller."""
    idx = index(records)
    lines = ['| waypoint | controller | overshoot x / y / z [m] | overshoot [m] | settling (e < band) [s] | '
             'yaw settling [s] | e_mu [m] | e_mu ground truth [m] |',
             '|---|---|---|---|---|---|---|---|']
    for s in STATIC:
        for c in present(records):
            rec = idx.get((s, c))
            st = (rec or {}).get('step') or {}
            if not rec or not rec.get('ok'):
                lines.append('| %s | %s | failed | | | | | |' % (s, LABELS[c]))
                continue
            lines.append('| %s | %s | %s / %s / %s | %s | %s | %s | %s | %s |' % (
                s, LABELS[c], fmt(st.get('overshoot_x')), fmt(st.get('overshoot_y')), fmt(st.get('overshoot_z')),
                fmt(st.get('overshoot')), fmt(st.get('settling_time'), 1), fmt(st.get('yaw_settling_time'), 1),
                fmt(stat(rec, 'estimate', 'e_mu')), fmt(stat(rec, 'truth', 'e_mu'))))
    return lines


def beats_summary(records, scenarios=ALL_SCENARIOS):
    """(lines, wins, compared): per scenario whether MPC's e_mu (vs estimate) is below PID's."""
    idx = index(records)
    lines = ['| scenario | MPC e_mu [m] | PID e_mu [m] | PID / MPC | MPC better |', '|---|---|---|---|---|']
    wins = compared = 0
    for s in scenarios:
        a, b = stat(idx.get((s, 'mpc')), 'estimate', 'e_mu'), stat(idx.get((s, 'pid')), 'estimate', 'e_mu')
        if a is None and b is None and (s, 'mpc') not in idx and (s, 'pid') not in idx:
            continue
        better = mpc_beats_pid(idx, s)
        if better is not None:
            compared += 1
            wins += int(better)
        lines.append('| %s | %s | %s | %s | %s |' % (s, fmt(a), fmt(b), fmt(b / a, 1) if a and b else '-',
                                                     _yes_no(better)))
    return lines, wins, compared


def timing_table(records):
    """Markdown lines: per run wall time, simulated time, achieved real-time factor, simulator lateness."""
    lines = ['| run | status | attempts | wall total [s] | start-up [s] | scenario sim [s] | scenario wall [s] | '
             'achieved RTF | sim min RTF | sim overruns | re-anchors | hover cmds | max cmd gap [s] | '
             'MPC solve mean / max [ms] | controller CPU [s per sim s] |',
             '|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|']
    for r in records:
        info = r.get('info') or {}
        solve = '-'
        if info.get('mpc_solve_time_mean_ms') is not None:
            solve = '%s / %s' % (fmt(info.get('mpc_solve_time_mean_ms')), fmt(info.get('mpc_solve_time_max_ms'), 1))
        status = 'ok' if r.get('ok') else 'FAILED: %s' % r.get('error', '')
        if r.get('ok') and disturbed(r):
            status = 'ok, disturbed: %s' % disturbed(r)
        lines.append('| %s_%s | %s | %s | %s | %s | %s | %s | %s | %s | %s | %s | %s | %s | %s | %s |' % (
            r.get('scenario'), r.get('controller'), status, r.get('attempts', 1),
            fmt(r.get('wall_s'), 1), fmt(info.get('startup_wall_s'), 1), fmt(info.get('scenario_sim_s'), 1),
            fmt(info.get('scenario_wall_s'), 1), fmt(info.get('achieved_rtf')), fmt(info.get('sim_reported_rtf_min')),
            info.get('sim_overruns', '-'), info.get('sim_reanchors', '-'), info.get('hover_commands', '-'),
            fmt(info.get('max_command_gap_s')), solve, fmt(info.get('controller_cpu_per_sim_s'), 3)))
    return lines


def cpu_ratio(records):
    """{controller: CPU s per simulated s over all its runs} and PID / MPC ratio (None when unknown)."""
    per = {}
    for c in present(records):
        cpu = sim = 0.0
        for r in records:
            info = r.get('info') or {}
            if r.get('controller') == c and r.get('ok') and info.get('controller_cpu_s') is not None \
                    and info.get('scenario_sim_s'):
                cpu += info['controller_cpu_s']
                sim += info['scenario_sim_s']
        per[c] = cpu / sim if sim > 0 else None
    ratio = per['pid'] / per['mpc'] if per.get('pid') and per.get('mpc') else None
    return per, ratio


def keeping_up(records, wanted_rtf):
    """(min achieved RTF over the runs, total simulator overruns, total re-anchors, runs measured)."""
    rtfs, overruns, reanchors = [], 0, 0
    for r in records:
        info = r.get('info') or {}
        if info.get('achieved_rtf') is not None:
            rtfs.append(info['achieved_rtf'])
        overruns += info.get('sim_overruns') or 0
        reanchors += info.get('sim_reanchors') or 0
    return (min(rtfs) if rtfs else None), overruns, reanchors, len(rtfs)


def paper_comparison(records):
    """Markdown lines comparing Table 3 with the paper: ours / paper per controller (mean, range) and the
    PID / MPC ratio of e_mu in each table's scenarios (ours; the paper's Table 3 for the straight line)."""
    idx = index(records)
    lines = []
    for c in CONTROLLERS:
        ratios = []
        for s, p in zip(STRAIGHT, PAPER_TABLE3[c]):
            v = stat(idx.get((s, c)), 'estimate', 'e_mu')
            if v is not None:
                ratios.append((v / p, s))
        if ratios:
            lo, hi = min(ratios), max(ratios)
            lines.append('- Table 3, %s: ours / paper = %s on average (%s at %s m/s .. %s at %s m/s).' % (
                LABELS[c], fmt(sum(r for r, _ in ratios) / len(ratios)), fmt(lo[0]), lo[1].split('_')[1],
                fmt(hi[0]), hi[1].split('_')[1]))
    for title, scenarios in (('Table 3 (straight line)', STRAIGHT), ('Table 4 (circles)', CIRCLE_SCENARIOS),
                             ('Table 5 (vertical)', VERTICAL_SCENARIOS)):
        pairs = []
        for s in scenarios:
            a, b = stat(idx.get((s, 'mpc')), 'estimate', 'e_mu'), stat(idx.get((s, 'pid')), 'estimate', 'e_mu')
            if a and b:
                pairs.append(b / a)
        if pairs:
            paper = ''
            if scenarios == STRAIGHT:
                pr = [p / m for p, m in zip(PAPER_TABLE3['pid'], PAPER_TABLE3['mpc'])]
                paper = ' (the paper: %s .. %s)' % (fmt(min(pr), 1), fmt(max(pr), 1))
            lines.append('- %s: PID e_mu / MPC e_mu = %s .. %s%s.' % (title, fmt(min(pairs), 1), fmt(max(pairs), 1),
                                                                       paper))
    return lines


def render(records, meta, plots=(), comparison_plots=()):
    """The whole Markdown report. ``meta``: dict with 'command', 'date', 'machine', 'rtf', 'wall_s',
    'mirror', 'pid_mode', 'notes' (list of lines, optional); ``plots``: [(run label, relative PNG path)];
    ``comparison_plots``: [(title, relative PNG path)]."""
    ok = sum(1 for r in records if r.get('ok'))
    lines = ['# Experiments: the paper\'s evaluation (Sec. V.B, Tables 3-5, Figs. 2 and 6) reproduced', '',
             'Generated by `%s` on %s (%s). Do not edit by hand: rerun `make bench`.' % (
                 meta.get('command', 'anafi_lab/engine/ros_batch.py'), meta.get('date', '?'),
                 meta.get('machine', '?')), '',
             '- Runs: %d (%d ok, %d failed), one at a time, each on its own ROS master; simulation time at '
             'a requested real-time factor of %s; kinematic world + Gazebo mirror: %s; PID framework mode: %s.' % (
                 len(records), ok, len(records) - ok, meta.get('rtf'), meta.get('mirror'), meta.get('pid_mode')),
             '- **Wall time of the whole batch: %s s (%s min)**; per run below.' % (
                 fmt(meta.get('wall_s'), 0), fmt((meta.get('wall_s') or 0) / 60.0, 1)),
             '- Tracking error e = |waypoint - drone position| per drone-estimate sample over the scenario\'s '
             'measured window (anafi_sim/config/scenarios/README.md): against the drone\'s own estimate (the '
             'paper\'s metric) and against ground truth. e_mu = mean, e_max = maximum, e_sigma = standard '
             'deviation, in metres.', '']
    min_rtf, overruns, reanchors, n = keeping_up(records, meta.get('rtf'))
    retried = [r for r in records if (r.get('attempts') or 1) > 1]
    still = [r for r in records if r.get('ok') and disturbed(r)]
    lines += ['## Did the simulator keep up?', '',
              'Achieved real-time factor (simulated seconds of the scenario / wall seconds) over the runs: '
              'min %s (requested %s); simulator steps late by more than one period: %d in total, schedule '
              're-anchors (> 0.25 s behind; the simulation clock then slows down instead of jumping): %d. '
              'Every node runs on the simulation clock, so a slower clock only slows the batch down; what '
              'spoils a run is a controller node starved of CPU, which shows as hover (all-zero) commands or '
              'a gap in the commands while the scenario runs (columns "hover cmds" and "max cmd gap" below). '
              'Such runs are repeated once; %d run(s) needed a repeat, %d remain disturbed (marked †).' % (
                  fmt(min_rtf), meta.get('rtf'), overruns, reanchors, len(retried), len(still)), '']
    if still:
        lines += [DAGGER_NOTE, '']
    lines += ['## Table 3: straight line, mean tracking error e_mu [m]', ''] + table3(records) + ['']
    comparison = paper_comparison(records)
    if comparison:
        lines += ['Compared with the paper (its Tables 4 and 5 are withheld here, so only Table 3 has reference '
                  'numbers):', ''] + comparison + ['']
    for title, scenarios, params in (('Table 4: circles in the xy-plane', CIRCLE_SCENARIOS, CIRCLES),
                                     ('Table 5: vertical rectilinear periodic motion', VERTICAL_SCENARIOS,
                                      VERTICAL)):
        for source, text in SOURCES:
            lines += ['## %s, %s [m]' % (title, text), ''] + stats_table(records, scenarios, params, source) + ['']
    lines += ['## Static waypoints WP0 / WP1 (Fig. 6): overshoot and settling', '',
              'Step from hover at (0, 0, 1) to (3, 2, 5) with yaw 0 (WP0) / 180 deg (WP1). Overshoot: per '
              'axis the largest excursion beyond the waypoint in the approach direction (drone estimate); '
              'settling: time after the step from which e stays below %s m (yaw: %s deg).' % (
                  meta.get('band', 0.2), meta.get('yaw_band', 5.0)), ''] + static_table(records) + ['']
    beat_lines, wins, compared = beats_summary(records)
    lines += ['## MPC vs PID per scenario (e_mu vs estimate)', '',
              '**MPC better than PID in %d of %d scenarios.**' % (wins, compared), ''] + beat_lines + ['']
    per, ratio = cpu_ratio(records)
    lines += ['## Computational workload', '',
              'Controller CPU time per simulated second (all controller processes; PID mode %s): MPC %s s, '
              'PID %s s; PID / MPC = %s (the paper: 2.59).' % (meta.get('pid_mode'), fmt(per.get('mpc'), 3),
                                                              fmt(per.get('pid'), 3), fmt(ratio))]
    for c in present(records)[len(CONTROLLERS):]:
        lines.append('%s (beyond the paper): %s s, %s x the MPC\'s.' % (
            LABELS[c], fmt(per.get(c), 3), fmt(per[c] / per['mpc'] if per.get(c) and per.get('mpc') else None)))
    lines.append('')
    lines += ['## Runs: wall time and the simulator', ''] + timing_table(records) + ['']
    notes = meta.get('notes') or []
    if notes:
        lines += ['## Notes', ''] + list(notes) + ['']
    if comparison_plots or plots:
        lines += ['## Plots', '']
        for title, path in comparison_plots:
            lines += ['%s:' % title, '', '![%s](%s)' % (title, path), '']
        if plots:
            lines += ['Per run (position vs waypoint, xy path or yaw, error over time; measured window shaded):', '']
            lines += ['- [%s](%s)' % (label, path) for label, path in plots]
            lines.append('')
    return '\n'.join(lines)
