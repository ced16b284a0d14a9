"""The fidelity report (docs/fidelity.md): the context of figures the template ``fidelity.md`` is filled with
(pure, no ROS). ``render_report`` computes it from the measured figures (the store written by
anafi_lab/cli/measure_fidelity.py) and renders the template; the template holds every word.
"""
import collections
import math

import numpy as np
import yaml

from anafi_lab.calibration.estimate import FusionProfileRow
from anafi_lab.fidelity import held_out as H
from anafi_lab.engine import replay as R
from anafi_lab.fidelity import scores as S
from anafi_lab.fidelity import variants as V
from anafi_lab.reports import fidelity_tables as T
from anafi_lab import paper
from anafi_lab.reports.render import render
from anafi_lab.engine.engine import DEFAULT_SCHEDULE, mpc_config, simulator_config
from anafi_sim.mission.trajectory import scenario_path
from anafi_sim.numeric import fmt
from anafi_sim.sim.drone_model import EFFECT_GROUPS, EFFECTS_OFF, load_model_params

COMMAND = 'python anafi_lab/cli/measure_fidelity.py'
EXAMPLE_WORKERS = 2      # worker processes of the report's regenerate command (the shared machine's two cores)

Measured = collections.namedtuple('Measured', 'records t3 scen gains selfrep walls meta fitted')
Measured.__doc__ = ('The measured figures of the store: records ({(log, variant): replay record}), t3 ({(variant, '
                    'controller, speed): record}), scen and selfrep ({(variant, controller, scenario): record}), '
                    'gains ([(role, label, ``estimate.FusionProfileRow``, variant name)]), walls ({step: s}), meta '
                    '(provenance), fitted (the effects-on model dict).')


def columns(timing):
    """[(title, PID variant, MPC variant)] of the shared-log tables: the configurations, then the replay methods
    (``variants.METHODS``)."""
    cols = [('shipped defaults', 'shipped', 'shipped'), ('effects off', 'off', 'off'), ('effects on', 'on', 'on'),
            ('fusion only', 'fusion', 'fusion')]
    if timing:
        cols += [('off + paper_timing', 'off', 'off_pt'), ('on + paper_timing', 'on', 'on_pt'),
                 ('fusion + paper_timing', 'fusion', 'fusion_pt')]
    cols.append(('shipped, settled start', 'settled', 'settled'))
    cols.append(('shipped, without the logs\' estimate stalls', 'nostalls', 'nostalls'))
    cols.append(('shipped, unrounded columns', 'unstored', 'unstored'))
    return cols


def configurations(cols):
    """The columns that are configurations of the stand-in (not the replay methods, ``variants.METHODS``)."""
    return [c for c in cols if c[2] not in V.METHODS]


def held_out_configurations(timing):
    """[(title, MPC variant, PID variant)] the held-out section compares (the PID does not depend on the MPC's
    timing: its runs of the same model)."""
    out = [('shipped defaults', 'shipped', 'shipped')]
    if timing:
        out.append(('shipped + paper_timing', 'shipped_pt', 'shipped'))
    out.append(('effects on', 'on', 'on'))
    if timing:
        out.append(('on + paper_timing', 'on_pt', 'on'))
    return out


def _ratios(records, variant, cells):
    """[ratio text (2 digits, '-' when missing)] of the (log, cell) pairs in ``variant``'s records."""
    out = []
    for log, cell in cells:
        rec = records.get((log, variant))
        out.append(fmt(rec['ratio'].get(cell) if rec else None, 2))
    return out


def _counts(records, logs, variant):
    """{within10, within25, mean} of one variant (both controllers): cells within +-10 %, +-25 %, mean |ln ratio|."""
    recs = S.combined(records, logs, variant, variant)
    k10, _, m = S.score(recs, band=S.BANDS[0])
    k25 = S.score(recs, band=S.BANDS[-1])[0]
    return dict(within10=k10, within25=k25, mean=m)


def _score(records, logs, mpc_v, pid_v):
    """{inside, cells, mean} of one configuration: cells within +-10 %, cells with a ratio, mean |ln ratio|."""
    k, n, m = S.score(S.combined(records, logs, mpc_v, pid_v))
    return dict(inside=k, cells=n, mean=m)


def method_context(records, logs):
    """The figures of the reading's initial-state, storage and stall sentences (shipped vs the methods before:
    'settled', 'unstored', 'nostalls')."""
    lines_ = ('x_straight_1_mpc', 'x_straight_3_mpc', 'x_straight_4_mpc')
    stalled = ('x_straight_2_mpc', 'x_straight_3_mpc', 'x_straight_5_mpc')
    counts = dict((v, _counts(records, logs, v)) for v in ('shipped', 'settled', 'unstored', 'nostalls'))

    def both(variant, cells):
        return _ratios(records, variant, cells)
    return dict(counts=counts, initial_lines=lines_, stalled_lines=stalled,
                initial_truth_e_mu=dict((v, both(v, [(n, 'truth_e_mu') for n in lines_]))
                                        for v in ('settled', 'shipped')),
                initial_truth_e_max=dict((v, both(v, [(n, 'truth_e_max') for n in lines_]))
                                         for v in ('settled', 'shipped')),
                storage_e_max=dict((v, both(v, [('x_straight_2_mpc', 'truth_e_max')])[0])
                                   for v in ('unstored', 'shipped')),
                storage_e_mu=dict((v, both(v, [('x_straight_5_mpc', 'truth_e_mu')])[0])
                                  for v in ('unstored', 'shipped')),
                stall_e_max=dict((v, both(v, [(n, 'estimate_e_max') for n in stalled]))
                                 for v in ('nostalls', 'shipped')))


STATIC_STEPS = ('static_waypoint_yaw_0_mpc', 'static_waypoint_yaw_180_mpc', 'static_waypoint_yaw_0_pid',
                'static_waypoint_yaw_180_pid')


def _figure(records, log, variant, group, key, scale=1.0):
    """One stored figure of a replay (``group`` 'ratio' / 'standin' / 'histories'), times ``scale``; None when
    that replay is missing."""
    rec = records.get((log, variant))
    value = rec[group].get(key) if rec else None
    return None if value is None else scale * value


def reading_context(records, logs, fitted):
    """The stored figures the reading's effect sentences quote: ranges over the MPC lines, cells and attitude /
    vertical-speed histories [deg, m/s] of the static steps and x_straight_5_mpc, per variant; ``fitted``: the
    effects-on model (its attitude time constant and attenuation speeds)."""
    lines_ = [n for n in logs if n.startswith('x_straight_') and n.endswith('_mpc')]

    def span(variant, cell):
        values = [v for v in (_figure(records, n, variant, 'ratio', cell) for n in lines_) if v is not None]
        return (min(values), max(values)) if values else (None, None)

    def cells(log, variant):
        return [_figure(records, log, variant, 'ratio', c) for c in ('estimate_e_mu', 'truth_e_mu')]

    def attitude(log, variant):
        return [_figure(records, log, variant, 'histories', h, math.degrees(1.0)) for h in ('roll', 'pitch')]
    x5 = 'x_straight_5_mpc'
    return dict(
        fusion_truth_span=dict((v, span(v, 'truth_e_mu')) for v in ('off', 'only_position_fusion', 'shipped')),
        x5=dict((v, dict((c, _figure(records, x5, v, 'ratio', c)) for c in ('%s_%s' % k for k in R.CELLS)))
                for v in ('fusion', 'shipped', 'unstored')),
        x5_standin_truth_e_max=_figure(records, x5, 'shipped', 'standin', 'truth_e_max'),
        cells=dict((n, dict((v, cells(n, v)) for v in ('shipped', 'on', 'on_pt'))) for n in STATIC_STEPS),
        attitude=dict((n, dict((v, attitude(n, v)) for v in ('off', 'only_tilt_rate_limit', 'shipped', 'on')))
                      for n in STATIC_STEPS),
        vz=[(_figure(records, n, 'off', 'histories', 'vz'),
             _figure(records, n, 'only_vertical_acceleration_limit', 'histories', 'vz')) for n in STATIC_STEPS],
        attitude_time_constant=fitted.get('attitude_time_constant'),
        attenuation_speeds=(fitted.get('tilt_attenuation_speed'), fitted.get('tilt_attenuation_speed_full')))


def _age_spread(scen, mpc_v, pid_v):
    """(fewest, most) held-out middles within the band over the MPC variant's waypoint ages (``variants.AGES``);
    None when those runs are missing."""
    counts = []
    for age in V.AGES:
        inside, outside, _ = H.held_out_score(scen or {}, V.age_name(mpc_v, age), pid_v)
        if inside + outside != H.HELD_OUT_CELLS:
            return None
        counts.append(inside)
    return min(counts), max(counts)


def held_out_context(scen, timing):
    """The held-out scores per configuration whose every cell ran ([{title, inside, mean, spread}]) and the MPC
    cells ``paper_timing`` moves across the band ([{scenario, source, before, after}])."""
    scored = []
    for title, mpc_v, pid_v in held_out_configurations(timing):
        inside, outside, mean = H.held_out_score(scen or {}, mpc_v, pid_v)
        if inside + outside == H.HELD_OUT_CELLS:
            scored.append(dict(title=title, inside=inside, mean=mean, spread=_age_spread(scen, mpc_v, pid_v)))
    moved = []
    for a, b in zip(H.held_out_bounds(scen or {}, 'shipped'), H.held_out_bounds(scen or {}, 'shipped_pt', 'shipped')):
        before, after = a[7][1], b[7][1]
        if a[0] == 'mpc' and math.isfinite(before) and math.isfinite(after) and \
                R.within(before, H.HELD_OUT_BAND) != R.within(after, H.HELD_OUT_BAND):
            moved.append(dict(scenario=a[2], source=a[1], before=before, after=after))
    return dict(scored=scored, moved=moved)


def timing_context(scen):
    """What ``paper_timing`` does to the vertical motions and circles (the shipped model's MPC runs of the
    ``scenarios`` step): {vertical: [(default, paper_timing)], pct: (low, high) change of the vertical e_mu [%],
    circles_pct: (low, high)}, None without those runs."""
    scen = scen or {}

    def change(scenarios, keys):
        out = []
        for s in scenarios:
            a, b = scen.get(('shipped', 'mpc', s)), scen.get(('shipped_pt', 'mpc', s))
            if a and b and a.get('ok') and b.get('ok'):
                out += [(a[k], b[k]) for k in keys if a.get(k) and b.get(k)]
        return out
    vertical = change(paper.VERTICAL_SCENARIOS, ('e_mu',))
    circles = change(paper.CIRCLE_SCENARIOS, ('e_mu', 'e_mu_truth'))
    if not (scen and vertical and circles):
        return None
    pct = [100.0 * (b / a - 1.0) for a, b in vertical]
    cpct = [100.0 * (b / a - 1.0) for a, b in circles]
    return dict(vertical=vertical, pct=(min(pct), max(pct)), circles_pct=(min(cpct), max(cpct)))


def table3_timing_context(scen):
    """Table 3 of the shipped model with each MPC timing and the spread the timer phase alone gives ([{title,
    inside, cells, mean, low, high}], verdict: 'alike' | 'shipped' | 'paper_timing'); None without the runs."""
    t3 = V.table3_from_scenarios(scen or {})
    if not any(k[0] == 'shipped_pt' for k in t3):
        return None
    parts, means, spreads = [], [], []
    for title, v in (('shipped defaults', 'shipped'), ('with paper_timing', 'shipped_pt')):
        k, n, m = S.table3_score(t3, 'shipped', v)
        ages = [S.table3_score(t3, 'shipped', V.age_name(v, a))[2] for a in V.AGES]
        means.append(m)
        spreads.append(max(ages) - min(ages))
        parts.append(dict(title=title, inside=k, cells=n, mean=m, low=min(ages), high=max(ages)))
    verdict = ('alike' if abs(means[0] - means[1]) < 0.25 * min(spreads) else
               'shipped' if means[0] < means[1] else 'paper_timing')
    return dict(parts=parts, verdict=verdict)


def fusion_gain_context(rows):
    """The fusion-gain section's figures (``scores.fusion_gain_rows``): the subsets' gains and their ratio, the
    circles' periods [s], the shipped row, the fits' and the probes' rows (complete: every gain's runs there)."""
    fits = dict((r.role, r.profile.fix_gain) for r in rows if r.role in ('static', 'straight', 'shipped'))
    periods = [2.0 * math.pi * radius / speed for radius, speed in paper.CIRCLES]
    shipped = [r for r in rows if r.role == 'shipped']
    fitted = [r for r in rows if r.role in ('static', 'straight')]
    probes = [r for r in rows if r.role == 'probe']

    def row(r):
        return dict(k=r.profile.fix_gain, fast=T.mids_text(r.fast), truth=T.mids_range(r.truth),
                    held=r.held[0] if r.held else None, shared=r.shared[0], rms_static=r.profile.rms_static)
    return dict(spread=(fits['straight'] / fits['static']) if 'static' in fits and 'straight' in fits else None,
                periods=(min(periods), max(periods)), shipped_k=fits.get('shipped'),
                complete=bool(shipped and fitted and all(r.held for r in rows)),
                shipped=row(shipped[0]) if shipped else None, fits=[row(r) for r in fitted],
                probes=[row(r) for r in probes],
                probes_worse=bool(shipped) and all(r.profile.rms_static > shipped[0].profile.rms_static
                                                   for r in probes))


def self_replay_context(selfrep):
    """The figures of the section on the replay method against the stand-in's own runs: the scores with the
    assumed and the recorded latency, of the lines and of the held-out kinds, the cells outside the band by
    controller and kind, and its table."""
    outside = collections.Counter()               # (controller, scenario kind) of the cells outside the band
    for (v, controller, scenario), r in selfrep.items():
        if v == 'shipped' and r.get('ok'):
            kind = ('lines' if scenario in paper.STRAIGHT else 'periodic motions' if scenario in H.HELD_OUT_SCENARIOS
                    else 'static steps')
            outside[(paper.LABELS[controller], kind)] += sum(
                1 for x in (r.get('ratio') or {}).values() if x is not None and not R.within(x, S.BANDS[0]))
    return dict(before=V.SELF_BEFORE, table=T.self_replay_table(selfrep, 'shipped'),
                default=S.self_replay_score(selfrep, 'shipped'),
                own=S.self_replay_score(selfrep, 'shipped', key='ratio_latency'),
                lines=S.self_replay_score(selfrep, 'shipped', scenarios=paper.STRAIGHT),
                held=S.self_replay_score(selfrep, 'shipped', scenarios=H.HELD_OUT_SCENARIOS),
                outside=[dict(controller=c, kind=k, cells=n) for (c, k), n in sorted(outside.items()) if n])


def ranking(records, t3, logs, cols):
    """The configurations ranked on the shared logs (most cells within +-10 %, then mean |ln ratio|; the shipped
    defaults included) and on Table 3: {best, runner_up, shipped, t3_best} as {title, inside, cells, mean}."""
    confs = configurations(cols)
    scored = [(c, _score(records, logs, c[2], c[1])) for c in confs]
    ranked = sorted(scored, key=lambda cs: (-cs[1]['inside'], cs[1]['mean']))
    out = dict(best=dict(ranked[0][1], title=ranked[0][0][0], name=ranked[0][0][1]),
               runner_up=dict(ranked[1][1], title=ranked[1][0][0]) if len(ranked) > 1 else None,
               shipped=_score(records, logs, 'shipped', 'shipped'), t3_best=None)
    if t3:
        t3ranked = sorted(confs, key=lambda c: (-S.table3_score(t3, c[1], c[2])[0], S.table3_score(t3, c[1], c[2])[2]))
        k, n, _ = S.table3_score(t3, t3ranked[0][1], t3ranked[0][2])
        out['t3_best'] = dict(title=t3ranked[0][0], inside=k, cells=n)
    return out


def ablation_context(records, logs, ablation):
    """The per-effect scores (all off, each effect alone, in the order of ``ablation``) and the ablation /
    timer-phase tables (None when their steps have not run)."""
    per_effect = [dict(label=v.label, **_score(records, logs, v.name, v.name)) for v in ablation
                  if S.combined(records, logs, v.name, v.name)]
    present = []
    for _, v in records:
        if v not in present:
            present.append(v)
    order = dict((v.name, i) for i, v in enumerate(ablation))
    abl = sorted((v for v in present if v.startswith('only_')), key=lambda v: (order.get(v, 99), v))
    ph = sorted((v for v in present if v.startswith('on_age') or v.startswith('on_lat')), key=lambda v: (v[:6], v))
    names = ['off'] + abl + ['on']
    return dict(off=_score(records, logs, 'off', 'off'), per_effect=per_effect,
                matrix=T.ratio_matrix(records, logs, names) if abl else None,
                scores=T.score_table(records, logs, [(n, n, n) for n in names]) if abl else None,
                phases=T.ratio_matrix(records, [l for l in logs if l.endswith('_mpc')], ['on'] + ph) if ph else None)


def scenario_columns(timing):
    """[(title, controller, [variant names])] of the scenario table (several names: their range)."""
    span = '%d-%d ms' % (round(V.AGES[0] * 1e3), round(V.AGES[-1] * 1e3))
    cols = [('PID', 'pid', ['shipped']), ('MPC', 'mpc', ['shipped']),
            ('MPC, waypoint age %s' % span, 'mpc', [V.age_name('shipped', a) for a in V.AGES])]
    if timing:
        cols += [('MPC + paper_timing', 'mpc', ['shipped_pt']),
                 ('MPC + paper_timing, age %s' % span, 'mpc', [V.age_name('shipped_pt', a) for a in V.AGES])]
    cols += [('effects on: PID', 'pid', ['on']), ('effects on: MPC', 'mpc', ['on'])]
    if timing:
        cols.append(('effects on: MPC + paper_timing', 'mpc', ['on_pt']))
    return cols


def schedule_context():
    """The engine's default timer phases: the waypoint's age at the MPC's cycle [ms] and the generator's period
    [ms]; the waypoint ages the phase steps sample [ms]."""
    default_age = (DEFAULT_SCHEDULE['controller_phase'] - DEFAULT_SCHEDULE['generator_phase']) \
        % (1.0 / DEFAULT_SCHEDULE['generator_rate'])
    return dict(default_age_ms=round(default_age * 1e3), period_ms=round(1e3 / DEFAULT_SCHEDULE['generator_rate']),
                ages_ms=[round(a * 1e3) for a in V.AGES])


def half_float_grid(lows=(64, 128)):
    """[{step, low, high}]: the spacing [m] of half floats (the logs' storage) between each of ``lows`` and twice
    it."""
    return [dict(step=float(np.spacing(np.float16(low))), low=low, high=2 * low) for low in lows]


def straight_phases():
    """{phase name: duration [s]} of the paper's straight-line scenarios (their files share the phases)."""
    with open(scenario_path(paper.STRAIGHT[0])) as stream:
        return dict((p['name'], p['duration']) for p in yaml.safe_load(stream)['phases'])


def load_log_facts(path):
    """The facts of the shared logs the report quotes (benchmarks/results/fidelity_log_facts.yaml)."""
    with open(path) as stream:
        return yaml.safe_load(stream)


def load_findings(path):
    """The findings of offline experiments the report's reading quotes, which no step measures
    (benchmarks/results/fidelity_findings.yaml)."""
    with open(path) as stream:
        return yaml.safe_load(stream)


def render_report(measured, logs, ablation, figures_dir, store_path, store_name, facts, findings):
    """The text of docs/fidelity.md from the ``Measured`` figures: ``logs`` (every log name, in order),
    ``ablation`` (the variants of that step, in order), ``figures_dir`` and ``store_path`` (as the report links
    them: relative to the report's directory), ``store_name`` (the store as its commands name it), ``facts``
    and ``findings`` (``load_log_facts``, ``load_findings``)."""
    m = measured
    timing = m.meta['paper_timing_supported']
    cols = columns(timing)
    rows = S.fusion_gain_rows(m.records, m.scen, m.gains, logs) if m.gains and m.scen else None
    return render(
        'fidelity.md', command=COMMAND, meta=m.meta, figures=figures_dir, store=store_path,
        store_from_root=store_name, timing=timing,
        lead=R.DEFAULT_LEAD, initial_ahead=R.INITIAL_AHEAD, late=R.LATE, rate=R.DEFAULT_RATE,
        stall_samples=R.STALL_SAMPLES, facts=facts, grid=half_float_grid(),
        estimate_rate='%g' % load_model_params()['estimate_rate'],
        fitted_model=('`%s`' % m.meta['fitted_model'] if m.meta['fitted_model'].endswith('.yaml')
                      else m.meta['fitted_model']),
        paper_timing=str(mpc_config()[0].get('paper_timing', False)).lower() if timing else 'n/a',
        summary=T.score_table(m.records, logs, cols), summary_late=T.score_table(m.records, logs, cols,
                                                                                 key='ratio_late'),
        rank=ranking(m.records, m.t3, logs, cols), t3_timing=table3_timing_context(m.scen),
        held=held_out_context(m.scen, timing), ablation=ablation_context(m.records, logs, ablation),
        method=method_context(m.records, logs), reading=reading_context(m.records, logs, m.fitted),
        findings=findings, timing_change=timing_context(m.scen),
        replays=T.replay_table(m.records, logs, cols), histories=T.history_table(m.records, logs, cols),
        table3=T.table3_table(m.t3, configurations(cols)) if m.t3 else None,
        scenarios=T.scenario_table(m.scen, scenario_columns(timing)) if m.scen else None,
        schedule=schedule_context(), example_workers=EXAMPLE_WORKERS, straight_phases=straight_phases(),
        engine_seed=simulator_config()[2], band_pct=[int(round(100 * b)) for b in S.BANDS],
        held_out_band=H.HELD_OUT_BAND, held_out_cells=H.HELD_OUT_CELLS,
        inferred=dict(range=H.INFERRED_RANGE, mid=math.sqrt(H.INFERRED_RANGE[0] * H.INFERRED_RANGE[1])),
        compared_batch=H.COMPARED_BATCH,
        held_out=T.held_out_table(m.scen, held_out_configurations(timing)) if m.scen else None,
        fusion=fusion_gain_context(rows) if rows else None, fusion_table=T.fusion_gain_table(rows) if rows else None,
        self_replay=self_replay_context(m.selfrep) if m.selfrep else None,
        fitted=[(k, m.fitted[k]) for k in EFFECTS_OFF if k in m.fitted], logs=logs, walls=sorted(m.walls.items()))


def measured_from_store(store):
    """The ``Measured`` figures of a store (the dict anafi_lab/cli/measure_fidelity.py writes to YAML)."""
    records = collections.OrderedDict(((r['log'], r['variant']), r) for r in store.get('replays', []))
    t3 = collections.OrderedDict(((r['variant'], r['controller'], int(r['scenario'].rsplit('_', 1)[1])), r)
                                 for r in store.get('table3', []))
    gains = [(g['role'], g['label'], FusionProfileRow(*[g[f] for f in FusionProfileRow._fields]), g['name'])
             for g in store.get('fusion_gain', []) if 'role' in g]
    return Measured(records, t3, V.scenario_records(store.get('scenarios', [])), gains,
                    V.scenario_records(store.get('self_replay', [])), dict(store.get('walls') or {}),
                    dict(store.get('meta') or {}), dict(store.get('fitted') or {}))


def store_from_measured(measured):
    """The store (a plain dict for YAML) of ``Measured`` figures: ``measured_from_store``'s inverse."""
    m = measured
    return {'meta': dict(m.meta), 'walls': m.walls, 'fitted': dict(m.fitted),
            'replays': list(m.records.values()), 'table3': list(m.t3.values()), 'scenarios': list(m.scen.values()),
            'fusion_gain': [dict([('role', role), ('label', label), ('name', name)] + list(row._asdict().items()))
                            for role, label, row, name in m.gains],
            'self_replay': list(m.selfrep.values())}


def report_from_store(store, figures_dir, store_path, store_name, facts, findings):
    """docs/fidelity.md from a store alone (nothing measured): the logs, the ablation's effects and the timer
    phases are the ones its replays have. ``figures_dir`` / ``store_path``: as the report links them (relative to
    its directory); ``store_name``: the store as the report's commands name it (relative to the checkout);
    ``facts``: the facts of the logs it quotes (``load_log_facts``); ``findings``: the offline findings it quotes
    (``load_findings``)."""
    measured = measured_from_store(store)
    logs = sorted(set(log for log, _ in measured.records))
    names = set(v for _, v in measured.records)
    ablation = [R.Variant('only_%s' % k, k) for k in EFFECT_GROUPS if 'only_%s' % k in names]
    return render_report(measured, logs, ablation, figures_dir, store_path, store_name, facts, findings)
