"""Experiment batch report (pure Python, no ROS): the paper's Tables 3-5 from run summaries, as Markdown.

Stage: evaluation output -> report (anafi_lab/cli/ros_batch.py writes
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
import collections
import math
import os

import yaml

from anafi_lab.paper import (ALL_SCENARIOS, BEYOND, CIRCLE_SCENARIOS, CIRCLES, CONTROLLERS, LABELS, PAPER_TABLE3, STATIC,
                             STRAIGHT, STRAIGHT_SPEEDS, VERTICAL, VERTICAL_SCENARIOS)
from anafi_lab.reports.batch_facts import batch_facts
from anafi_lab.reports.render import markdown_table, render as render_template
from anafi_sim.mission import step_response
from anafi_sim.numeric import fmt

SOURCES = (('estimate', 'vs the drone\'s estimate (the paper\'s metric)'), ('truth', 'vs ground truth'))


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
    """Rows of Table 3 (straight line: mean e per speed), ours next to the paper's: [label, cell per speed]."""
    idx = index(records)
    rows = []
    for c in present(records):
        rows.append(['%s ours, vs estimate' % LABELS[c]] +
                    ['**%s**' % cell(idx.get((s, c)), 'estimate', 'e_mu') for s in STRAIGHT])
        if c in PAPER_TABLE3:
            rows.append(['%s paper' % LABELS[c]] + [fmt(v) for v in PAPER_TABLE3[c]])
        rows.append(['%s ours, vs ground truth' % LABELS[c]] + [cell(idx.get((s, c)), 'truth', 'e_mu') for s in STRAIGHT])
        if c not in PAPER_TABLE3:
            continue
        ratios = []
        for s, p in zip(STRAIGHT, PAPER_TABLE3[c]):
            v = stat(idx.get((s, c)), 'estimate', 'e_mu')
            ratios.append(fmt(v / p) if v is not None else '-')
        rows.append(['%s ours / paper' % LABELS[c]] + ratios)
    return rows


def stats_table(records, scenarios, params, source):
    """(header, rows) of a Table-4/5 style table: (r, v) rows, e_max e_mu e_sigma per controller."""
    idx = index(records)
    cols = []
    controllers = present(records)
    for c in controllers:
        cols += ['%s e_max' % LABELS[c], '%s e_mu' % LABELS[c], '%s e_sigma' % LABELS[c]]
    rows = []
    for s, (r, v) in zip(scenarios, params):
        cells = []
        for c in controllers:
            rec = idx.get((s, c))
            cells += [cell(rec, source, k) for k in ('e_max', 'e_mu', 'e_sigma')]
        rows.append(['%g' % r, '%g' % v] + cells + [_yes_no(mpc_beats_pid(idx, s, source))])
    return ['r [m]', 'v [m/s]'] + cols + ['MPC e_mu < PID e_mu'], rows


def static_table(records):
    """Rows: static waypoints' overshoot and settling per controller (None for a failed run)."""
    idx = index(records)
    rows = []
    for s in STATIC:
        for c in present(records):
            rec = idx.get((s, c))
            st = (rec or {}).get('step') or {}
            if not rec or not rec.get('ok'):
                rows.append([s, LABELS[c], 'failed', '', '', '', '', ''])
                continue
            rows.append([s, LABELS[c], '%s / %s / %s' % (fmt(st.get('overshoot_x')), fmt(st.get('overshoot_y')),
                                                         fmt(st.get('overshoot_z'))),
                         fmt(st.get('overshoot')), fmt(st.get('settling_time'), 1), fmt(st.get('yaw_settling_time'), 1),
                         fmt(stat(rec, 'estimate', 'e_mu')), fmt(stat(rec, 'truth', 'e_mu'))])
    return rows


def beats_rows(records, scenarios=ALL_SCENARIOS):
    """(rows, wins, compared): per scenario whether MPC's e_mu (vs estimate) is below PID's."""
    idx = index(records)
    rows = []
    wins = compared = 0
    for s in scenarios:
        a, b = stat(idx.get((s, 'mpc')), 'estimate', 'e_mu'), stat(idx.get((s, 'pid')), 'estimate', 'e_mu')
        if a is None and b is None and (s, 'mpc') not in idx and (s, 'pid') not in idx:
            continue
        better = mpc_beats_pid(idx, s)
        if better is not None:
            compared += 1
            wins += int(better)
        rows.append([s, fmt(a), fmt(b), fmt(b / a, 1) if a and b else '-', _yes_no(better)])
    return rows, wins, compared


BEATS_HEADER = ('scenario', 'MPC e_mu [m]', 'PID e_mu [m]', 'PID / MPC', 'MPC better')


def beats_summary(records, scenarios=ALL_SCENARIOS):
    """(Markdown lines, wins, compared) of ``beats_rows`` (the batch's and the sweep's terminal summary)."""
    rows, wins, compared = beats_rows(records, scenarios)
    return markdown_table(BEATS_HEADER, rows), wins, compared


def _status(r):
    status = 'ok' if r.get('ok') else 'FAILED: %s' % r.get('error', '')
    if r.get('ok') and disturbed(r):
        status = 'ok, disturbed: %s' % disturbed(r)
    return status


def timing_table(records):
    """Rows: per run wall time, simulated time, achieved real-time factor, simulator lateness."""
    rows = []
    for r in records:
        info = r.get('info') or {}
        solve = '-'
        if info.get('mpc_solve_time_mean_ms') is not None:
            solve = '%s / %s' % (fmt(info.get('mpc_solve_time_mean_ms')), fmt(info.get('mpc_solve_time_max_ms'), 1))
        rows.append(['%s_%s' % (r.get('scenario'), r.get('controller')), _status(r), r.get('attempts', 1),
                     fmt(r.get('wall_s'), 1), fmt(info.get('startup_wall_s'), 1), fmt(info.get('scenario_sim_s'), 1),
                     fmt(info.get('scenario_wall_s'), 1), fmt(info.get('achieved_rtf')),
                     fmt(info.get('sim_reported_rtf_min')), info.get('sim_overruns', '-'),
                     info.get('sim_reanchors', '-'), info.get('hover_commands', '-'), fmt(info.get('max_command_gap_s')),
                     solve, fmt(info.get('controller_cpu_per_sim_s'), 3)])
    return rows


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


def keeping_up(records):
    """(min achieved RTF over the runs, total simulator overruns, total re-anchors, runs measured, sorted RTFs)."""
    rtfs, overruns, reanchors = [], 0, 0
    for r in records:
        info = r.get('info') or {}
        if info.get('achieved_rtf') is not None:
            rtfs.append(info['achieved_rtf'])
        overruns += info.get('sim_overruns') or 0
        reanchors += info.get('sim_reanchors') or 0
    return (min(rtfs) if rtfs else None), overruns, reanchors, len(rtfs), sorted(v for v in rtfs if v)


def paper_comparison(records):
    """Table 3 against the paper: {'ours_vs_paper': [(label, mean, lo, lo speed, hi, hi speed)], 'pid_vs_mpc':
    [(title, min, max, paper min or None, paper max)]} (ours / paper per controller; PID / MPC e_mu per table)."""
    idx = index(records)
    ours = []
    for c in CONTROLLERS:
        ratios = []
        for s, p in zip(STRAIGHT, PAPER_TABLE3[c]):
            v = stat(idx.get((s, c)), 'estimate', 'e_mu')
            if v is not None:
                ratios.append((v / p, s))
        if ratios:
            lo, hi = min(ratios), max(ratios)
            ours.append((LABELS[c], sum(r for r, _ in ratios) / len(ratios), lo[0], lo[1].split('_')[1],
                         hi[0], hi[1].split('_')[1]))
    pid_vs_mpc = []
    for title, scenarios in (('Table 3 (straight line)', STRAIGHT), ('Table 4 (circles)', CIRCLE_SCENARIOS),
                             ('Table 5 (vertical)', VERTICAL_SCENARIOS)):
        pairs = []
        for s in scenarios:
            a, b = stat(idx.get((s, 'mpc')), 'estimate', 'e_mu'), stat(idx.get((s, 'pid')), 'estimate', 'e_mu')
            if a and b:
                pairs.append(b / a)
        if pairs:
            paper = [p / m for p, m in zip(PAPER_TABLE3['pid'], PAPER_TABLE3['mpc'])] if scenarios == STRAIGHT else None
            pid_vs_mpc.append((title, min(pairs), max(pairs), min(paper) if paper else None,
                               max(paper) if paper else None))
    return {'ours_vs_paper': ours, 'pid_vs_mpc': pid_vs_mpc}


def context(records, meta, plots=(), comparison_plots=()):
    """The figures of the batch report (``templates/batch.md``)."""
    min_rtf, overruns, reanchors, _, rtfs = keeping_up(records)
    beats, wins, compared = beats_rows(records)
    per, ratio = cpu_ratio(records)
    stats = []
    for title, scenarios, params in (('Table 4: circles in the xy-plane', CIRCLE_SCENARIOS, CIRCLES),
                                     ('Table 5: vertical rectilinear periodic motion', VERTICAL_SCENARIOS, VERTICAL)):
        for source, text in SOURCES:
            header, rows = stats_table(records, scenarios, params, source)
            stats.append({'title': title, 'source': text, 'header': header, 'rows': rows})
    beyond = [(LABELS[c], per.get(c), per[c] / per['mpc'] if per.get(c) and per.get('mpc') else None)
              for c in present(records)[len(CONTROLLERS):]]
    return {
        'meta': collections.defaultdict(lambda: None, meta), 'inprocess': meta.get('engine') == 'inprocess', 'runs': len(records),
        'ok': sum(1 for r in records if r.get('ok')), 'rtfs': rtfs, 'min_rtf': min_rtf, 'overruns': overruns,
        'reanchors': reanchors, 'retried': sum(1 for r in records if (r.get('attempts') or 1) > 1),
        'disturbed': sum(1 for r in records if r.get('ok') and disturbed(r)),
        'table3_header': ['Controller / speed'] + ['%d m/s' % v for v in STRAIGHT_SPEEDS], 'table3': table3(records), 'comparison': paper_comparison(records),
        'stats': stats, 'static': static_table(records), 'beats_header': BEATS_HEADER, 'beats': beats,
        'wins': wins, 'compared': compared, 'cpu': per, 'cpu_ratio': ratio, 'beyond': beyond,
        'timing': timing_table(records), 'band': meta.get('band', step_response.BAND),
        'yaw_band': meta.get('yaw_band', step_response.YAW_BAND), 'plots': list(plots), 'comparison_plots': list(comparison_plots),
    }


def render(records, meta, plots=(), comparison_plots=()):
    """The whole Markdown report. ``meta``: dict with 'command', 'date', 'machine', 'rtf', 'wall_s',
    'mirror', 'pid_mode' (a ROS batch), or 'engine': 'inprocess' with 'workers', 'sim_s' (an in-process batch);
    ``plots``: [(run label, relative PNG path)]; ``comparison_plots``: [(title, relative PNG path)]."""
    return render_template('batch.md', **dict(context(records, meta, plots, comparison_plots), **batch_facts()))


STATIC_COMPARISON = 'Static waypoints WP0 / WP1, PID and MPC (cf. the paper\'s Fig. 6)'
"""Title of the static waypoints' comparison figure (plots/static_waypoints.png beside the report)."""


def rerender(records_path):
    """The report of a stored batch (its ``experiments.yaml``: meta and records) with the plots that stand
    beside it, without rerunning or redrawing anything."""
    import os
    import yaml
    with open(records_path) as stream:
        data = yaml.safe_load(stream)
    directory = os.path.dirname(os.path.abspath(records_path))
    records = data['records']
    plots = [('%s_%s' % (r['scenario'], r['controller']), r['plot']) for r in records
             if r.get('plot') and os.path.exists(os.path.join(directory, r['plot']))]
    figure = os.path.join('plots', 'static_waypoints.png')
    comparisons = [(STATIC_COMPARISON, figure)] if os.path.exists(os.path.join(directory, figure)) else []
    return render(records, data.get('meta') or {}, plots, comparisons)
