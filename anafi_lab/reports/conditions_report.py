"""The predicted real-flight table: e_max / e_mu / e_sigma per cell under flight conditions, with the seed spread.

Stage: experiments (a section of a sweep's summary.md, ``anafi_lab.engine.sweep``). One row per
conditions x scenario x controller over the runs (the gust seeds): mean +- std [min, max] of each metric
against the drone's estimate (the paper's e). Under ``real_flights`` these are the stand-in's prediction of
the paper's real-flight columns of Tables 4 and 5 (anafi_sim/config/sweeps/real_flights.yaml), made from the
four real static logs, the Sphinx logs and physics (docs/calibration.md, "Real flights").
"""
import collections
import math

METRICS = ('e_max', 'e_mu', 'e_sigma')


def _stats(values):
    v = [float(x) for x in values if x is not None and x != '' and math.isfinite(float(x))]
    if not v:
        return None
    mean = sum(v) / len(v)
    std = math.sqrt(sum((x - mean) ** 2 for x in v) / (len(v) - 1)) if len(v) > 1 else 0.0
    return mean, std, min(v), max(v), len(v)


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
