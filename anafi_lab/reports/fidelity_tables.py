"""The tables of the fidelity report as rows of short cells (pure, no ROS): each function returns a ``Table``
(head cells, rows of cells: numbers already written with their digits, '-' when missing, ratios outside the band
in bold) that the template ``fidelity/table.md`` lays out as a Markdown table.
"""
import collections
import math

from anafi_lab.fidelity.held_out import FAST_CIRCLES, HELD_OUT_BAND, HELD_OUT_CELLS, held_out_bounds, held_out_score
from anafi_lab.engine.replay import CELLS, DEFAULT_RATE, SOURCES, parse_name, within
from anafi_lab.fidelity.scores import BANDS, cell_key, combined, record_ratios, score
from anafi_lab import paper
from anafi_sim.numeric import fmt

Table = collections.namedtuple('Table', 'head rows')
Table.__doc__ = 'A table of the report: head ([cell]) and rows ([[cell]]), every cell a short text.'

CELL_LABELS = {('estimate', 'e_mu'): 'e_mu est', ('estimate', 'e_max'): 'e_max est',
               ('truth', 'e_mu'): 'e_mu truth', ('truth', 'e_max'): 'e_max truth'}


def ratio_text(ratio, band=BANDS[0]):
    """'0.97' inside the band, '**1.35**' outside, '-' when missing."""
    if ratio is None or not math.isfinite(ratio):
        return '-'
    return ('%.2f' if within(ratio, band) else '**%.2f**') % ratio


def replay_table(records, logs, columns):
    """One row per log and cell, Sphinx's value then per column (title, variant name of the PID logs, variant
    name of the MPC logs) the stand-in's value and its ratio to Sphinx."""
    head = ['log', 'cell', 'Sphinx [m]']
    for title, _, _ in columns:
        head += ['%s [m]' % title, 'ratio']
    rows = []
    for log in logs:
        for cell in CELLS:
            ref = None
            parts = []
            horizontal = False
            for _, pid_v, mpc_v in columns:
                rec = records.get((log, mpc_v if parse_name(log)[1] == 'mpc' else pid_v))
                if rec is None:
                    parts += ['-', '-']
                    continue
                ref = rec['reference'].get(cell_key(cell))
                horizontal = horizontal or cell[0] in rec.get('horizontal', ())
                if not rec['ok']:
                    parts += ['failed', '-']
                    continue
                parts += [fmt(rec['standin'].get(cell_key(cell)), 3), ratio_text(rec['ratio'].get(cell_key(cell)))]
            label = CELL_LABELS[cell] + (' (horizontal)' if horizontal else '')
            rows.append([log, label, fmt(ref, 3)] + parts)
    return Table(head, rows)


def score_table(records, logs, columns, bands=BANDS, key='ratio'):
    """Per configuration the cells within each band (all, PID, MPC, estimate, truth) and the mean |ln ratio|
    (``key``: see ``scores.record_ratios``)."""
    head = (['configuration'] + ['within +-%d %%' % round(100 * b) for b in bands]
            + ['PID +-10 %', 'MPC +-10 %', 'estimate +-10 %', 'truth +-10 %', 'mean abs ln(ratio)'])
    rows = []
    for title, pid_v, mpc_v in columns:
        recs = combined(records, logs, mpc_v, pid_v)
        parts = []
        for b in bands:
            k, n, _ = score(recs, b, key)
            parts.append('%d / %d' % (k, n))
        for subset in (('pid',), ('mpc',)):
            k, n, _ = score([r for r in recs if r['controller'] in subset], key=key)
            parts.append('%d / %d' % (k, n))
        for source in SOURCES:
            ratios = [r for rec in recs for _, cell, r in record_ratios(rec, key) if cell[0] == source and r]
            parts.append('%d / %d' % (sum(1 for r in ratios if within(r, BANDS[0])), len(ratios)))
        parts.append(fmt(score(recs, key=key)[2], 3))
        rows.append([title] + parts)
    return Table(head, rows)


def history_table(records, logs, columns):
    """rms difference of the truth roll, pitch [deg] and vertical speed [m/s] vs Sphinx."""
    head = ['log'] + ['%s roll / pitch [deg], vz [m/s]' % t for t, _, _ in columns]
    rows = []
    for log in logs:
        parts = []
        for _, pid_v, mpc_v in columns:
            rec = records.get((log, mpc_v if parse_name(log)[1] == 'mpc' else pid_v))
            h = (rec or {}).get('histories') or {}
            deg = [None if h.get(k) is None else math.degrees(h[k]) for k in ('roll', 'pitch')]
            parts.append('%s / %s, %s' % (fmt(deg[0], 2), fmt(deg[1], 2), fmt(h.get('vz'), 3)))
        rows.append([log] + parts)
    return Table(head, rows)


def table3_table(t3, columns):
    """Table 3 (e_mu vs estimate, straight lines) of the paper and of each configuration."""
    head = ['controller', 'speed [m/s]', 'paper [m]']
    for t, _, _ in columns:
        head += ['%s [m]' % t, 'ratio']
    rows = []
    for c in paper.CONTROLLERS:
        for k, published in enumerate(paper.PAPER_TABLE3[c]):
            parts = []
            for _, pid_v, mpc_v in columns:
                r = t3.get((mpc_v if c == 'mpc' else pid_v, c, k + 1))
                v = r.get('e_mu') if r and r.get('ok') else None
                parts += [fmt(v, 3), ratio_text(v / published if v is not None else None)]
            rows.append([paper.LABELS[c], '%d' % (k + 1), '%.2f' % published] + parts)
    return Table(head, rows)


def _pair(record):
    """'est / truth' e_mu of a scenario record ('-' when missing or failed)."""
    if not record or not record.get('ok'):
        return '-'
    return '%s / %s' % (fmt(record.get('e_mu'), 3), fmt(record.get('e_mu_truth'), 3))


def _span(records, names, controller, scenario):
    """'lo-hi / lo-hi' e_mu (est / truth) over the variants ``names`` ('-' when none ran)."""
    rows = [records.get((n, controller, scenario)) for n in names]
    rows = [r for r in rows if r and r.get('ok') and r.get('e_mu') is not None]
    if not rows:
        return '-'
    parts = []
    for key in ('e_mu', 'e_mu_truth'):
        v = [r[key] for r in rows if r.get(key) is not None]
        parts.append('%s-%s' % (fmt(min(v), 3), fmt(max(v), 3)) if v else '-')
    return ' / '.join(parts)


def scenario_table(records, columns, scenarios=paper.ALL_SCENARIOS):
    """e_mu vs estimate / vs ground truth [m] of every scenario, one column per (title, controller, variant
    names): one name -> its run, several -> their range (min-max)."""
    rows = []
    for s in scenarios:
        rows.append([s] + [(_pair(records.get((names[0], c, s))) if len(names) == 1 else _span(records, names, c, s))
                           for _, c, names in columns])
    return Table(['scenario'] + [t for t, _, _ in columns], rows)


def held_out_table(records, configurations, band=HELD_OUT_BAND):
    """``held_out_bounds`` for each (title, MPC variant, PID variant) configuration: the stand-in's e_mu now and
    now / Sphinx as 'low-high (mid)', the mid in bold outside +-``band``; a last row with ``held_out_score`` per
    configuration."""
    bounds = [held_out_bounds(records, v, p) for _, v, p in configurations]
    head = ['controller', 'vs', 'scenario', 'compared [m]', 'compared / Sphinx', 'Sphinx implied [m]']
    for t, _, _ in configurations:
        head += ['%s [m]' % t, '/ Sphinx']
    rows = []
    for i, row in enumerate(bounds[0]):
        controller, source, scenario, first, (lo, hi), sphinx = row[:6]
        parts = []
        for b in bounds:
            now, ratio = b[i][6], b[i][7]
            if now is None or not all(math.isfinite(x) for x in ratio):
                parts += ['-', '-']
                continue
            parts += [fmt(now, 3), ('%.2f-%.2f (%.2f)' if within(ratio[1], band) else '%.2f-%.2f (**%.2f**)')
                      % (ratio[0], ratio[2], ratio[1])]
        rows.append([paper.LABELS[controller], 'est' if source == 'estimate' else 'truth', scenario,
                     '%.3f' % first, '%.2f-%.2f' % (lo, hi), '%.3f-%.3f' % sphinx] + parts)
    tally = []
    for _, v, p in configurations:
        inside, outside, mean = held_out_score(records, v, p, band)
        tally += ['', '%d / %d, %s' % (inside, outside, fmt(mean, 3))]
    rows.append(['**cells**', '', 'mid inside / outside +-%d %%, mean abs ln(mid)' % round(band * 100), '', '', '']
                + tally)
    return Table(head, rows)


def mids_text(mids):
    """The middles of a {scenario: middle} mapping as 'a / b' ('-' when none is finite)."""
    if not any(math.isfinite(m) for m in mids.values()):
        return '-'
    return ' / '.join('%.2f' % m if math.isfinite(m) else '-' for m in mids.values())


def mids_range(mids):
    """The range of the finite middles of a {scenario: middle} mapping as 'low-high' ('-' when none)."""
    finite = [m for m in mids.values() if math.isfinite(m)]
    return '%.2f-%.2f' % (min(finite), max(finite)) if finite else '-'


def fusion_gain_table(rows, band=HELD_OUT_BAND):
    """``scores.fusion_gain_rows``: k, D, the fit's rms (all, static, straight), the shared-log cells within
    +-10 % and mean abs ln, the held-out middles inside +-``band`` and mean abs ln, the fast circles' middles (vs
    the estimate) and the range of the circles' middles vs ground truth."""
    head = ['k [1/s]', 'from', 'D [s]', 'fit rms all / static / straight [m]',
            'shared-log cells within +-10 %, mean abs ln',
            'held-out middles inside +-%d %%, mean abs ln' % round(band * 100),
            'MPC %s vs the estimate (middle)' % ' / '.join(FAST_CIRCLES), 'MPC circles vs ground truth (middles)']
    out = []
    for r in rows:
        p, shared, held = r.profile, r.shared, r.held
        out.append(['%.3f' % p.fix_gain, r.label, '%.3f' % p.fix_delay,
                    '%.4f / %.4f / %.4f' % (p.rms, p.rms_static, p.rms_straight),
                    '%d / %d, %s' % (shared[0], shared[1], fmt(shared[2], 3)),
                    '%d / %d, %s' % (held[0], HELD_OUT_CELLS, fmt(held[2], 3)) if held else '-',
                    mids_text(r.fast), mids_range(r.truth)])
    return Table(head, out)


def ratio_matrix(records, logs, names):
    """Ratios only: one row per log and cell, one column per variant name."""
    rows = []
    for log in logs:
        for cell in CELLS:
            parts = []
            for v in names:
                rec = records.get((log, v))
                parts.append('-' if rec is None or not rec['ok'] else ratio_text(rec['ratio'].get(cell_key(cell))))
            if all(p == '-' for p in parts):
                continue
            rows.append([log, CELL_LABELS[cell]] + parts)
    return Table(['log', 'cell'] + list(names), rows)


def self_replay_table(records, variant, scenarios=paper.ALL_SCENARIOS, band=None):
    """``variants.self_replay_runs`` records of ``variant``: per scenario and controller the lead-in (period [s],
    'straight' or none for a log that starts in a hover) and the four ratios replay / log with the default
    latency, then with the recording's own (bold outside +-``band``, default BANDS[0])."""
    band = BANDS[0] if band is None else band
    names = ['%s %s' % cell for cell in CELLS]
    head = ['scenario', 'controller', 'lead-in'] + names + ['latency [ms]'] + names
    rows = []
    for scenario in scenarios:
        for controller in paper.CONTROLLERS:
            r = records.get((variant, controller, scenario))
            if r is None:
                continue
            if not r.get('ok'):
                rows.append([scenario, paper.LABELS[controller], 'failed: %s' % r.get('error')]
                            + ['-'] * (2 * len(CELLS) + 1))
                continue
            lead = ('%.1f s period' % (r['period'] / DEFAULT_RATE) if r.get('period') else
                    'straight' if r.get('moving', True) else 'none (hover)')
            parts = []
            for key in ('ratio', 'ratio_latency'):
                parts += [ratio_text(x if x is not None else float('nan'), band)
                          for x in [(r.get(key) or {}).get(cell_key(cell)) for cell in CELLS]]
            parts.insert(len(CELLS), '%.0f' % (1e3 * r['latency']) if r.get('latency') is not None else '-')
            rows.append([scenario, paper.LABELS[controller], lead] + parts)
    return Table(head, rows)
