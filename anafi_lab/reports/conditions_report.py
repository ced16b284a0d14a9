"""The predicted real-flight table: e_max / e_mu / e_sigma per cell under flight conditions, with the seed spread.

Stage: experiments (a section of a sweep's summary.md, ``anafi_lab.engine.sweep``). One row per
conditions x scenario x controller over the runs (the gust seeds): mean +- std [min, max] of each metric
against the drone's estimate (the paper's e). Under ``real_flights`` these are the stand-in's prediction of
the paper's real-flight columns of Tables 4 and 5 (anafi_lab/sweeps/real_flights.yaml), made from the
four real static logs, the Sphinx logs and physics (docs/calibration.md, "Real flights").
"""
import collections
import math

import numpy as np
import yaml

from anafi_lab.calibration import conditions as cond
from anafi_lab.reports.render import na, render
from anafi_sim.numeric import summary_stats

METRICS = ('e_max', 'e_mu', 'e_sigma')


def _stats(values):
    """(mean, std, min, max, n) of the finite values, None when there are none; std is the sample standard deviation
    of the seeds (ddof 1, ``anafi_sim.numeric.summary_stats``)."""
    s = summary_stats([x for x in values if x != ''], sample=True)
    return (s['mean'], s['std'], s['min'], s['max'], s['n']) if s else None


def cells(table):
    """OrderedDict (conditions, scenario, controller) -> {metric: (mean, std, min, max, n) or None} of the tidy
    rows (``sweep.rows``; failed runs left out)."""
    groups = collections.OrderedDict()
    for row in table:
        if not row.get('ok'):
            continue
        key = (row.get('conditions', 'none'), row['scenario'], row['controller'])
        groups.setdefault(key, []).append(row)
    return collections.OrderedDict((key, collections.OrderedDict((m, _stats([r.get(m) for r in rows]))
                                                                 for m in METRICS))
                                   for key, rows in groups.items())


def _cell(s):
    if s is None:
        return '-'
    return '%.2f +- %.2f [%.2f, %.2f]' % s[:4]


def predicted_section(table):
    """Markdown lines of the section."""
    out = ['## Predicted flight figures per cell (seed spread)', '',
           'Per conditions x scenario x controller over the seeds (the gusts): mean +- std [min, max] of e_max, '
           'e_mu, e_sigma [m] against the drone\'s estimate (the paper\'s e). Under `real_flights` this is the '
           'stand-in\'s prediction of the paper\'s real-flight cells (Tables 4 and 5), from the four real static '
           'logs, the Sphinx logs and physics; the real figures of these cells are held out of the repository.',
           '', '| conditions | scenario | controller | seeds | e_max | e_mu | e_sigma |',
           '|---|---|---|---|---|---|---|']
    for (conditions, scenario, controller), stats in cells(table).items():
        n = max((s[4] for s in stats.values() if s is not None), default=0)
        out.append('| %s | %s | %s | %d | %s | %s | %s |' % (conditions, scenario, controller, n,
                                                           _cell(stats['e_max']), _cell(stats['e_mu']),
                                                           _cell(stats['e_sigma'])))
    return out


def _turn_text(turns):
    """'log: W against B m/s^2; ...': the change of the firmware contribution through each yaw turn, in the world
    and in the body frame."""
    parts = []
    for check in turns:
        b, a = check['before'], check['after']
        world = math.hypot(a['world'][0] - b['world'][0], a['world'][1] - b['world'][1])
        body = math.hypot(a['body'][0] - b['body'][0], a['body'][1] - b['body'][1])
        parts.append('%s: %s against %s m/s^2' % (check['name'], na(world, 2), na(body, 2)))
    return '; '.join(parts) or 'no log with a yaw turn'


def _replay_cells(means, ref):
    return ['%s [%s, %s] vs %s (%s)' % (na(means[s][0]), na(means[s][1]), na(means[s][2]), na(ref[s]),
                                         na(means[s][0] / ref[s], 2)) for s in cond.REPLAY_STATS]


def _grid_rows(grid, settings_list, chosen, references, off_index):
    rows = []
    for i, settings in enumerate(settings_list):
        s, inside, total = cond.score(grid, i, references)
        tau = na(settings['wind_compensation_time_constant'], 2)
        label = [tau, na(settings['gust_std_horizontal'], 2)]
        if i == off_index:
            label[0] = 'no wind handling (K = 0)'
        if i == chosen:
            label = ['**' + label[0], label[1] + '**']
        rows.append(label + [na(s), '%d / %d' % (inside, total)])
    return rows


def calibration_section(logs, handling, conds, combined, grid, settings_list, chosen, references, seeds, off_index,
                        command, findings):
    """The "Real flights" section of docs/calibration.md (between ``cond.SECTION_BEGIN`` and ``SECTION_END``):
    the identified wind handling, each log's conditions and the closed-loop replays; ``findings``: the figures of
    the earlier checks it quotes (benchmarks/results/conditions_findings.yaml)."""
    per_log = [[name, na(v['held'], 2), na(v['commanded'], 2), '(%s, %s)' % (na(v['firmware'][0], 2),
                na(v['firmware'][1], 2)), '(%s, %s)' % (na(v['wind_force'][0], 2), na(v['wind_force'][1], 2)),
                na(v['gain'], 2), '%d' % v['samples']] for name, v in handling.per_log.items()]
    per_log_conditions = [[c.name, '(%s, %s)' % (na(c.wind[0], 2), na(c.wind[1], 2)), na(c.wind_speed, 2),
                           na(c.gust_std, 2), na(c.gust_time_constant, 2), na(c.position_noise, 4),
                           na(c.velocity_noise, 4), '%s / %s' % (na(c.tilt_mean), na(c.tilt_std))] for c in conds]
    chosen_settings = settings_list[chosen]
    edge = chosen_settings['gust_std_horizontal'] in (cond.GUST_GRID[0], cond.GUST_GRID[-1]) or \
        chosen_settings['wind_compensation_time_constant'] in (cond.TAU_W_GRID[0], cond.TAU_W_GRID[-1])
    chosen_rows, all_inside = [], True
    for log in logs:
        means, ref = cond.seed_means(grid[(chosen, log.name)]), references[log.name]
        for stat in cond.REPLAY_STATS:
            if stat != 'e_hold':
                all_inside &= abs(means[stat][0] / ref[stat] - 1.0) <= cond.BAND
        chosen_rows.append([log.name] + _replay_cells(means, ref))
    off = [cond.seed_means(grid[(off_index, log.name)]) for log in logs]
    return render('conditions/calibration.md', begin=cond.SECTION_BEGIN, end=cond.SECTION_END, command=command,
                  logs=logs, settle=cond.SETTLE, per_log=per_log,
                  commanded_mean=float(np.mean([v['commanded'] for v in handling.per_log.values()])),
                  held_mean=float(np.mean([v['held'] for v in handling.per_log.values()])),
                  gain=handling.gain, gain_stderr=handling.gain_stderr, samples=handling.samples,
                  candidates=[[name, na(rms), verdict] for name, rms, verdict in handling.candidates],
                  turns=_turn_text(handling.turns), f=findings, gust_smoothing=cond.GUST_SMOOTHING,
                  noise_window=cond.NOISE_WINDOW, per_log_conditions=per_log_conditions, combined=combined,
                  seeds=seeds, hold_window=cond.HOLD_WINDOW, band_text='+-%d %%' % round(100 * cond.BAND),
                  grid_rows=_grid_rows(grid, settings_list, chosen, references, off_index), edge=edge,
                  chosen_rows=chosen_rows, all_inside=all_inside,
                  off_hold=', '.join(na(o['e_hold'][0], 2) if o else 'failed' for o in off),
                  log_hold=', '.join(na(references[log.name]['e_hold'], 2) for log in logs))


def fidelity_section(logs, grid, chosen, references, seeds, command):
    """The "real flights" section of docs/fidelity.md (between ``cond.FIDELITY_BEGIN`` and ``FIDELITY_END``): the
    real logs' closed-loop replays under the chosen conditions (the same method as the Sphinx logs')."""
    rows = [[log.name] + _replay_cells(cond.seed_means(grid[(chosen, log.name)]), references[log.name])
            for log in logs]
    return render('conditions/fidelity.md', begin=cond.FIDELITY_BEGIN, end=cond.FIDELITY_END, seeds=seeds,
                  command=command, rows=rows, hold_window=cond.HOLD_WINDOW)


def load_findings(path):
    """The figures of the earlier checks the calibration section quotes (a YAML mapping)."""
    with open(path) as stream:
        return yaml.safe_load(stream)
