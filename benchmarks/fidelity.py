#!/usr/bin/env python3
"""Fidelity of the stand-in against the shared Sphinx logs: closed-loop replays -> docs/fidelity.md and
docs/fidelity/*.png (the core is anafi_sim/experiments/fidelity.py; this script only wires it to files).

Stage: benchmark (not a test; the regression guard is test/unit/test_fidelity.py). Steps (``--steps``,
default all; measured figures are kept in docs/fidelity/fidelity.yaml so that a step can be rerun alone and
the report re-rendered):

- ``replay``: every shared log replayed in closed loop by its controller on the in-process engine with the
  model effects OFF (anafi_sim/config/anafi_model.yaml with every effect key off) and ON
  (anafi_sim/config/anafi_model_fitted.yaml, or the calibration's fitted dict when that file is missing),
  and for the MPC logs with the MPC's ``paper_timing`` true as well (when mpc.yaml knows the key); one
  figure per log;
- ``ablation``: each fidelity effect on its own (effects-off model + that effect's fitted keys);
- ``phases``: the MPC logs with the waypoint 5 / 30 / 55 / 80 ms old at the MPC's cycle (engine schedule
  ``generator_phase``; the ROS graph's phase is random per start-up) and with the replay's waypoint latency
  at its extremes (0 and 50 ms before the logger's first sample of a new waypoint);
- ``table3``: the paper's straight-line scenarios (Table 3) on the engine for each configuration;
- ``scenarios``: every paper scenario (static waypoints, Tables 3-5) on the engine with the shipped model and
  the fitted one, the MPC with both timings (``paper_timing`` false / true) and, for the shipped model, with
  the waypoint 5 / 30 / 55 / 80 ms old at its cycle; with what the issue's comparison implies for the
  held-out cells of Tables 4 and 5 (``fidelity.held_out_bounds``);
- ``fusion_gain``: the shipped model with the position fusion's gain k (and its delay refitted) at the fits of
  the static-waypoint logs alone and of the straight-line logs alone, and at ``fidelity.FUSION_GAIN_PROBES``
  beyond them: how well the logs allow each k (``fit.fusion_profile``), the shared-log replays and the
  held-out scenarios with it;
- ``self_replay``: the replay method on the stand-in's own runs of every paper scenario (``F.self_replay_runs``):
  recorded as the paper's logger recorded Sphinx, replayed, compared (ratio 1 = the method adds nothing).

Logs of other scenarios (e.g. Sphinx's runs of Tables 4 and 5, in the shared logs' format, named
``<scenario>_<pid|mpc>.csv``) are replayed alike: ``--logs DIR --steps replay`` (with ``--out`` / ``--figures``
elsewhere); the models are calibrated on ``--calibration-logs`` (default the shared logs) whatever ``--logs`` is.

    python benchmarks/fidelity.py [--steps replay,...,self_replay] [--workers 2]
"""
import argparse
import collections
import datetime
import math
import os
import platform
import sys
import time

import yaml

from anafi_sim.calibration import conditions
from anafi_sim import paths
from anafi_sim.calibration import fit
from anafi_sim.experiments import fidelity as F
from anafi_sim.experiments import report
from anafi_sim.experiments.engine import DEFAULT_SCHEDULE, mpc_config
from anafi_sim.experiments.reference_log import read_log
from anafi_sim.sim.drone_model import EFFECTS_OFF, load_model_params

STEPS = ('replay', 'ablation', 'phases', 'table3', 'scenarios', 'fusion_gain', 'self_replay')
METHODS = ('settled', 'nostalls', 'unstored')    # variants that are replay methods, not configurations
PLOTTED = ('off', 'settled', 'shipped')       # the variants in each log's figure: before (settled start) / after
AGES = (0.005, 0.030, 0.055, 0.080)          # s, waypoint age at the MPC's cycle
AGES_TEXT = ' / '.join(str(round(a * 1e3)) for a in AGES)     # '5 / 30 / 55 / 80' [ms]
COMMAND = 'python benchmarks/fidelity.py'


def parse_args(argv):
    root = paths.checkout()
    parser = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    parser.add_argument('--logs', default=paths.reference_logs_dir(),
                        help='directory with the reference-log CSVs (default: <checkout>/../shared/reference_logs)')
    parser.add_argument('--calibration-logs', default=paths.reference_logs_dir(),
                        help='directory of the logs the models are calibrated on (default: the shared logs)')
    parser.add_argument('--out', default=os.path.join(root, 'docs', 'fidelity.md'), help='Markdown report')
    parser.add_argument('--figures', default=os.path.join(root, 'docs', 'fidelity'),
                        help='directory of the figures and of fidelity.yaml (the measured figures)')
    parser.add_argument('--fitted', default=paths.config_path('anafi_model_fitted.yaml'),
                        help='model YAML with every effect on (missing: calibrate the logs)')
    parser.add_argument('--steps', default=','.join(STEPS), help='comma-separated subset of %s' % ', '.join(STEPS))
    parser.add_argument('--workers', type=int, default=os.cpu_count() or 1, help='worker processes')
    parser.add_argument('--only', default='', help='comma-separated log names (default: every log)')
    parser.add_argument('--variants', default='',
                        help='replay / table3 / scenarios: comma-separated configurations (replay, table3: off, on, '
                             'off_pt, on_pt, ...; scenarios: shipped, shipped_pt, on, on_pt, shipped_age05, ...; '
                             'default all; a subset draws no figures)')
    parser.add_argument('--effects', default='', help='ablation: comma-separated effects (default: every one)')
    parser.add_argument('--ages', default=','.join(str(round(a * 1e3)) for a in AGES),
                        help='phases: waypoint ages at the MPC cycle [ms], comma-separated')
    parser.add_argument('--latencies', default='0,50', help='phases: replay latencies [ms], comma-separated')
    args = parser.parse_args(argv)
    args.steps = [s for s in args.steps.split(',') if s]
    unknown = [s for s in args.steps if s not in STEPS]
    if unknown:
        parser.error('unknown step(s) %s' % ', '.join(unknown))
    return args


def models(args, paths_):
    """(off, on, shipped name, how the fitted dict was found, shipped dict, the calibration's position fusion fit
    ``fit.PositionFusionFit``)."""
    shipped = load_model_params()
    cal = fit.calibrate([read_log(p) for p in paths_])    # ~15 s: the baseline (every effect off)
    # (paths_: the calibration logs, the shared ones by default: a --logs directory of other scenarios is only
    # replayed)
    off = dict(cal.baseline)          # an effect's refitted keys (e.g. the vertical time constant) at their off values
    if os.path.isfile(args.fitted):
        on, how = load_model_params(args.fitted), os.path.relpath(os.path.realpath(args.fitted), paths.checkout())
    else:
        on = dict(cal.fitted)
        how = 'anafi_sim.calibration.fit.calibrate(logs).fitted (%s missing)' % args.fitted
    groups = [g for g, keys in F.effect_groups(on).items()           # on: an effect key off its off value
              if any(shipped.get(k, v) != v for k, v in EFFECTS_OFF.items() if k in keys)]
    name = 'with %s on' % ', '.join(groups) if groups else 'with every effect off'
    return off, dict(on), name, how, dict(shipped), cal.effects.fusion


def fusion_gain_entries(fusion, shipped, logs):
    """[(role, label, ``fit.FusionProfileRow``, variant name)] of the ``fusion_gain`` step (roles
    ``F.FUSION_GAIN_ROLES``): the fix gain k fitted on the static-waypoint logs alone, the shipped model's (its
    own delay: the ``shipped`` runs of the other steps), the one fitted on the straight-line logs alone, and
    ``F.FUSION_GAIN_PROBES``; the others with the delay refitted for their k on every clean log
    (``fit.fusion_profile``). ``fusion``: the calibration's ``PositionFusionFit`` (a subset without static or
    straight logs has no fit of its own: left out)."""
    rate = shipped['estimate_rate']
    gains = [('static', 'static-waypoint logs alone', (fusion.groups.get('static') or (None,))[0], None),
             ('shipped', 'shipped model', shipped['estimate_position_fix_gain'],
              shipped['estimate_position_fix_delay'] + 0.5 / rate),
             ('straight', 'straight-line logs alone', (fusion.groups.get('straight') or (None,))[0], None)]
    gains += [('probe', 'probe beyond the fits', g, None) for g in F.FUSION_GAIN_PROBES]
    gains = [g for g in gains if g[2] is not None]
    rows = fit.fusion_profile(logs, [g[2] for g in gains], rate, [g[3] for g in gains])
    return [(role, label, row, 'shipped' if role == 'shipped' else F.gain_name('shipped', row.fix_gain))
            for (role, label, _, _), row in zip(gains, rows)]


def supports_paper_timing():
    """True when mpc.yaml / the engine know the MPC's ``paper_timing`` key."""
    try:
        mpc_config({'paper_timing': True})
        return True
    except ValueError:
        return False


def main_variants(off, on, timing, shipped=None):
    fusion = F.effect_variants(off, on).get('position_fusion', on)
    shipped = shipped if shipped is not None else load_model_params()
    out = [F.Variant('shipped', 'shipped defaults', shipped)]
    out += [F.Variant('off', 'effects off', off), F.Variant('on', 'effects on', on),
           F.Variant('fusion', 'fusion only', fusion)]
    if timing:
        out += [F.Variant('off_pt', 'effects off, paper_timing', off, {'mpc': {'paper_timing': True}},
                          controllers=('mpc',)),
                F.Variant('on_pt', 'effects on, paper_timing', on, {'mpc': {'paper_timing': True}},
                          controllers=('mpc',)),
                F.Variant('fusion_pt', 'fusion only, paper_timing', fusion, {'mpc': {'paper_timing': True}},
                          controllers=('mpc',))]
        for v in out[1:4]:     # the default runs state the timing explicitly (mpc.yaml may change its default)
            out[out.index(v)] = v._replace(controller_params={'mpc': {'paper_timing': False}})
    # the replay method before the initial state (the same model): every log starts settled on its line
    out.append(F.Variant('settled', 'shipped, settled start', shipped, plan={'initial_state': False}))
    # the same model, the replay not holding the estimate where the log's estimate stream stalled (before)
    out.append(F.Variant('nostalls', 'shipped, without the logs\' estimate stalls', shipped, plan={'stalls': False}))
    # the measurement before the storage (the same runs): the stand-in's columns unrounded
    out.append(F.Variant('unstored', 'shipped, unrounded columns', shipped, plan={'stored': False}))
    return out


def phase_variants(model, name, ages=AGES, latencies=(0.0, 0.05)):
    out = F.age_variants(F.Variant(name, name, model), ages)
    for latency in latencies:
        out.append(F.Variant('%s_lat%02d' % (name, round(latency * 1e3)), 'latency %d ms' % round(latency * 1e3),
                             model, plan={'latency': latency}, controllers=('mpc',)))
    return out


def scenario_variants(shipped, on, timing, ages=AGES):
    """The configurations of the ``scenarios`` step: shipped defaults and effects on, each with the MPC's
    timing explicit (false / true), and the shipped ones at the ``ages`` [s] (MPC)."""
    def mpc(pt):
        return {'mpc': {'paper_timing': pt}} if timing else None
    out = [F.Variant('shipped', 'shipped defaults', shipped, mpc(False)),
           F.Variant('on', 'effects on', on, mpc(False))]
    if timing:
        out += [F.Variant('shipped_pt', 'shipped, paper_timing', shipped, mpc(True), controllers=('mpc',)),
                F.Variant('on_pt', 'effects on, paper_timing', on, mpc(True), controllers=('mpc',))]
    for v in [v for v in out if v.name in ('shipped', 'shipped_pt')]:
        out += F.age_variants(v, ages)
    return out


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


def strip(rec):
    return dict((k, v) for k, v in rec.items() if k != 'series')


def load_store(path):
    if os.path.isfile(path):
        with open(path) as stream:
            return yaml.safe_load(stream) or {}
    return {}


def main(argv=None):
    args = parse_args(argv if argv is not None else sys.argv[1:])
    all_paths = F.find_logs(args.logs)
    if not all_paths:
        sys.exit('no reference logs in %s' % args.logs)
    only = [s for s in args.only.split(',') if s]
    log_paths = [p for p in all_paths if not only or os.path.splitext(os.path.basename(p))[0] in only]
    all_logs = [os.path.splitext(os.path.basename(p))[0] for p in all_paths]
    calibration_paths = F.find_logs(args.calibration_logs)
    if not calibration_paths:
        sys.exit('no calibration logs in %s' % args.calibration_logs)
    off, on, shipped, how, shipped_model, fusion = models(args, calibration_paths)
    timing = supports_paper_timing()
    os.makedirs(args.figures, exist_ok=True)
    store_path = os.path.join(args.figures, 'fidelity.yaml')
    store = load_store(store_path)
    records = collections.OrderedDict(((r['log'], r['variant']), r) for r in store.get('replays', []))
    t3 = collections.OrderedDict(((r['variant'], r['controller'], int(r['scenario'].rsplit('_', 1)[1])), r)
                                 for r in store.get('table3', []))
    scen = F.scenario_records(store.get('scenarios', []))
    gains = [(g['role'], g['label'], fit.FusionProfileRow(*[g[f] for f in fit.FusionProfileRow._fields]), g['name'])
             for g in store.get('fusion_gain', []) if 'role' in g]
    if 'fusion_gain' in args.steps:
        gains = fusion_gain_entries(fusion, shipped_model, [read_log(p) for p in calibration_paths])
    selfrep = F.scenario_records(store.get('self_replay', []))
    walls = dict((k, v) for k, v in (store.get('walls') or {}).items() if k in STEPS)   # steps it still has
    variants = main_variants(off, on, timing, shipped_model)
    scen_variants = scenario_variants(shipped_model, on, timing)
    chosen = [v for v in args.variants.split(',') if v]
    run_variants = [v for v in variants if not chosen or v.name in chosen]
    effects = [e for e in args.effects.split(',') if e]
    ablation = [F.Variant('only_%s' % k, k, m, {'mpc': {'paper_timing': False}} if timing else None)
                for k, m in F.effect_variants(off, on).items() if not effects or k in effects]   # vs 'off'
    phases = phase_variants(on, 'on', [float(a) * 1e-3 for a in args.ages.split(',') if a],
                            [float(a) * 1e-3 for a in args.latencies.split(',') if a])
    # records of variants the script no longer has are dropped (a subset run keeps the others)
    known = set(v.name for v in variants + phases + phase_variants(on, 'on'))
    known.update('only_%s' % k for k in F.effect_variants(off, on))
    known.update(name for _, _, _, name in gains)
    for key in [k for k in records if k[1] not in known]:
        del records[key]
    known_scen = set(v.name for v in scen_variants) | set(name for _, _, _, name in gains)
    for key in [k for k in scen if k[0] not in known_scen]:
        del scen[key]
    t0 = time.perf_counter()
    measured_meta = dict(store.get('meta') or {})

    def save():
        """Write the measured figures and the report (after every step: a later step may be cut short)."""
        meta = collections.OrderedDict([
            ('command', COMMAND + (' ' + ' '.join(argv if argv is not None else sys.argv[1:])).rstrip()),
            ('date', datetime.datetime.now().strftime('%Y-%m-%d %H:%M')),
            ('machine', '%s, %d CPUs, Python %s' % (platform.machine(), os.cpu_count() or 0,
                                                    platform.python_version())),
            ('shipped_model', shipped), ('fitted_model', how), ('paper_timing_supported', timing),
            ('wall_s', round(time.perf_counter() - t0, 1)),
        ])
        if not args.steps and measured_meta:
            # a re-render measures nothing: the figures keep the provenance of the run that measured them
            for key in ('command', 'date', 'machine', 'wall_s'):
                meta[key] = measured_meta.get(key, meta[key])
        store = {'meta': dict(meta), 'walls': walls, 'fitted': dict(on),
                 'replays': list(records.values()), 'table3': list(t3.values()),
                 'scenarios': list(scen.values()),
                 'fusion_gain': [dict([('role', role), ('label', label), ('name', name)] + list(row._asdict().items()))
                                 for role, label, row, name in gains],
                 'self_replay': list(selfrep.values())}
        with open(store_path, 'w') as stream:
            yaml.safe_dump(store, stream, default_flow_style=False, sort_keys=False)
        text = render(records, t3, all_logs, variants, ablation, phases, on, meta, walls, args, scen, gains,
                      selfrep)
        # the real flights' replay section (anafi_sim/scripts/calibrate_conditions.py) is kept as it is
        kept = conditions.existing_section(open(args.out).read(), conditions.FIDELITY_BEGIN,
                                           conditions.FIDELITY_END) if os.path.exists(args.out) else ''
        if kept:
            text = conditions.replace_section(text, kept, conditions.FIDELITY_BEGIN, conditions.FIDELITY_END)
        with open(args.out, 'w') as stream:
            stream.write(text)

    for step in args.steps:
        t = time.perf_counter()
        if step == 'replay':
            new = F.replay_all(log_paths, run_variants, workers=args.workers)
            for p in (log_paths if not chosen else []):
                name = os.path.splitext(os.path.basename(p))[0]
                series = [(v.label, new[(name, v.name)]['series']) for v in variants
                          if (name, v.name) in new and new[(name, v.name)].get('series')
                          and v.name in PLOTTED]
                F.plot_replay(os.path.join(args.figures, name + '.png'), read_log(p), series,
                              title='%s: Sphinx (black) vs the stand-in' % name)
        elif step == 'ablation':
            new = F.replay_all(log_paths, ablation, workers=args.workers)
        elif step == 'phases':
            new = F.replay_all(log_paths, phases, workers=args.workers)
        elif step == 'table3':
            new = {}
            t3.update(F.table3_runs([v for v in run_variants if v.name not in METHODS],
                                    workers=args.workers))
        elif step == 'scenarios':
            new = {}
            scen.update(F.scenario_runs([v for v in scen_variants if not chosen or v.name in chosen],
                                        workers=args.workers))
        elif step == 'self_replay':
            new = {}
            selfrep.clear()
            selfrep.update(F.self_replay_runs([v for v in scen_variants if v.name == 'shipped'], workers=args.workers))
        else:
            # each step's own 'shipped' variant with the other gains (the same MPC timing as the runs they join)
            rows = [row for role, _, row, _ in gains if role != 'shipped']
            new = F.replay_all(log_paths, F.fusion_gain_variants(
                [v for v in variants if v.name == 'shipped'][0], rows), workers=args.workers)
            scen.update(F.scenario_runs(F.fusion_gain_variants([v for v in scen_variants if v.name == 'shipped'][0],
                                                               rows),
                                        F.HELD_OUT_SCENARIOS, workers=args.workers, label='fusion_gain'))
        records.update((k, strip(r)) for k, r in new.items())
        walls[step] = round(time.perf_counter() - t, 1)
        save()
    save()
    print('wrote %s and %s (%.0f s)' % (args.out, store_path, time.perf_counter() - t0))


def _columns(variants, timing):
    cols = [('shipped defaults', 'shipped', 'shipped'), ('effects off', 'off', 'off'), ('effects on', 'on', 'on'),
            ('fusion only', 'fusion', 'fusion')]
    if timing:
        cols += [('off + paper_timing', 'off', 'off_pt'), ('on + paper_timing', 'on', 'on_pt'),
                 ('fusion + paper_timing', 'fusion', 'fusion_pt')]
    cols.append(('shipped, settled start', 'settled', 'settled'))   # not a configuration: the method before
    cols.append(('shipped, without the logs\' estimate stalls', 'nostalls', 'nostalls'))   # nor this
    cols.append(('shipped, unrounded columns', 'unstored', 'unstored'))   # nor this: the measurement before
    return cols


def configurations(cols):
    """The columns that are configurations of the stand-in (not the replay methods, ``METHODS``)."""
    return [c for c in cols if c[2] not in METHODS]


def _ratios(records, variant, cells):
    """' / '-joined ratios (2 digits) of the (log, cell) pairs in ``variant``'s records ('-' when missing)."""
    out = []
    for log, cell in cells:
        rec = records.get((log, variant))
        out.append(F.fmt(rec['ratio'].get(cell) if rec else None, 2))
    return ' / '.join(out)


def _counts(records, logs, variant):
    """(cells within +-10 %, within +-25 %, mean |ln ratio|) of one variant (both controllers)."""
    recs = F.combined(records, logs, variant, variant)
    k10, _, m = F.score(recs, band=F.BANDS[0])
    k25 = F.score(recs, band=F.BANDS[-1])[0]
    return k10, k25, m


def _initial_text(records, logs):
    """The initial state's sentence of the reading, its figures from ``records`` (shipped vs 'settled')."""
    shipped, settled = _counts(records, logs, 'shipped'), _counts(records, logs, 'settled')
    lines_ = ('x_straight_1_mpc', 'x_straight_3_mpc', 'x_straight_4_mpc')
    return ('**The initial state** (shipped defaults against "shipped, settled start", the same model replayed '
            'from a start settled on the line, the method before): %d -> %d cells within +-10 %%, mean |ln ratio| '
            '%s -> %s; it moves the ground-truth cells of the MPC lines, x_straight_1/3/4_mpc e_mu %s -> %s and '
            'e_max %s -> %s.' % (
                settled[0], shipped[0], F.fmt(settled[2]), F.fmt(shipped[2]),
                _ratios(records, 'settled', [(n, 'truth_e_mu') for n in lines_]),
                _ratios(records, 'shipped', [(n, 'truth_e_mu') for n in lines_]),
                _ratios(records, 'settled', [(n, 'truth_e_max') for n in lines_]),
                _ratios(records, 'shipped', [(n, 'truth_e_max') for n in lines_])))


def _method_text(records, logs):
    """The storage and the stall paragraphs of the reading, their figures from ``records`` (shipped vs the
    methods before: 'unstored', 'nostalls'); the facts about the logs are the logs' and fixed."""
    shipped, unstored, nostalls = (_counts(records, logs, v) for v in ('shipped', 'unstored', 'nostalls'))
    lines_ = ('x_straight_2_mpc', 'x_straight_3_mpc', 'x_straight_5_mpc')
    return (
        '**The storage** (shipped defaults against "shipped, unrounded columns", the same runs): the logger '
        'stored every value as a half float written as its shortest repr, a 0.0625 m grid at 64-128 m and '
        '0.125 m at 128-256 m plus up to 0.025 m of the repr, and a maximum over a log picks that rounding up: '
        'stored like Sphinx\'s, x_straight_2_mpc\'s truth e_max goes %s -> %s (Sphinx\'s is one sample at '
        '11.35 s stored as "81.4" for the half float 81.375, 0.2 m ahead of the waypoint; the 2 m/s line moves '
        '0.1 m a sample against a waypoint that steps 0.2 m every 0.1 s), and x_straight_5_mpc\'s truth e_mu '
        '%s -> %s (its x lies at 153-234 m, on the 0.125 m grid): %d -> %d cells within +-10 %%, mean |ln ratio| '
        '%s -> %s. The honest figure is the stored one: Sphinx\'s values went through that storage. **The '
        'estimate stalls** (shipped defaults against "shipped, without the logs\' estimate stalls"): in '
        'x_straight_2/3/5_mpc Sphinx\'s estimate stream holds for 4 rows (at 8.4, 7.5 and 8.7 s) and catches up '
        'after 5, 5 and 4 rows (0.25, 0.25, 0.2 s; in the first two a fifth row has moved by 0.06 and 0.13 m '
        'only, a sixth and a fifth of the truth\'s move since the stall began), and the MPC reacts to it: within '
        '0.8 s of the stall\'s start Sphinx\'s pitch rises by 1.1 / 2.4 / 1.9 deg and its vx by 0.05 / 0.08 / '
        '0.05 m/s. Replaying the stalls (the stand-in\'s published estimate held over the same log times) the '
        'stand-in\'s MPC reacts alike (at the time of writing: pitch +1.7 / +1.9 / +1.5 deg, vx +0.06 / +0.06 / '
        '+0.05 m/s; without the stall at most +0.25 deg) and the estimate e_max cells of those three lines go '
        '%s -> %s: %d -> %d cells within +-10 %%, %d -> %d within +-25 %%. The stall is a condition of the run '
        '(what the controller received), not of the drone: Sphinx\'s PID and static runs show none.' % (
            _ratios(records, 'unstored', [('x_straight_2_mpc', 'truth_e_max')]),
            _ratios(records, 'shipped', [('x_straight_2_mpc', 'truth_e_max')]),
            _ratios(records, 'unstored', [('x_straight_5_mpc', 'truth_e_mu')]),
            _ratios(records, 'shipped', [('x_straight_5_mpc', 'truth_e_mu')]),
            unstored[0], shipped[0], F.fmt(unstored[2]), F.fmt(shipped[2]),
            _ratios(records, 'nostalls', [(n, 'estimate_e_max') for n in lines_]),
            _ratios(records, 'shipped', [(n, 'estimate_e_max') for n in lines_]),
            nostalls[0], shipped[0], nostalls[1], shipped[1]))


def _held_out_text(scen, timing):
    """What the issue's comparison implies for the held-out cells, per configuration, in words, with the MPC
    cells ``paper_timing`` moves across the band (measured figures; a note when the step has not run). Only
    configurations whose every held-out cell ran are scored."""
    band = F.HELD_OUT_BAND
    parts = []
    for title, mpc_v, pid_v in held_out_configurations(timing):
        inside, outside, mean = F.held_out_score(scen or {}, mpc_v, pid_v)
        if inside + outside == F.HELD_OUT_CELLS:
            text = '%s %d / %d, %s' % (title, inside, F.HELD_OUT_CELLS, F.fmt(mean))
            spread = _age_spread(scen, mpc_v, pid_v)
            if spread:
                text += ' (%d-%d with the waypoint %s ms old)' % (spread + (AGES_TEXT,))
            parts.append(text)
    if not parts:
        return 'The held-out cells: the `scenarios` step has not run for every configuration. '
    moved = []
    for a, b in zip(F.held_out_bounds(scen, 'shipped'), F.held_out_bounds(scen, 'shipped_pt', 'shipped')):
        before, after = a[7][1], b[7][1]
        if a[0] == 'mpc' and math.isfinite(before) and math.isfinite(after) and \
                F.within(before, band) != F.within(after, band):
            moved.append('%s vs the %s %.2f -> %.2f' % (a[2], a[1], before, after))
    text = ('On the held-out cells of Tables 4 and 5, by what the issue\'s comparison implies (section "The '
            'held-out cells": middles of now / Sphinx within +-%d %%, mean abs ln): %s.'
            % (round(band * 100), '; '.join(parts)))
    if moved:
        text += ' `paper_timing` moves across that band: %s.' % ', '.join(moved)
    return text + ' These counts are as uncertain as the middles, several of which lie within a few per cent ' \
                  'of the band\'s edge. '


def _timing_text(scen):
    """What ``paper_timing`` does to the paper's vertical motions and circles (the ``scenarios`` step's MPC runs
    of the shipped model), in words."""
    scen = scen or {}

    def change(scenarios, keys):
        out = []
        for s in scenarios:
            a, b = scen.get(('shipped', 'mpc', s)), scen.get(('shipped_pt', 'mpc', s))
            if a and b and a.get('ok') and b.get('ok'):
                out += [(a[k], b[k]) for k in keys if a.get(k) and b.get(k)]
        return out
    vertical = change(report.VERTICAL_SCENARIOS, ('e_mu',))
    circles = change(report.CIRCLE_SCENARIOS, ('e_mu', 'e_mu_truth'))
    if not (scen and vertical and circles):
        return 'the vertical periodic motions (Table 5, no shared log): the `scenarios` step has not run'
    pct = [100.0 * (b / a - 1.0) for a, b in vertical]
    cpct = [100.0 * (b / a - 1.0) for a, b in circles]
    return ('the vertical periodic motions (Table 5, no shared log) grow by %.0f-%.0f %% (engine, MPC e_mu vs the '
            'estimate %s -> %s m; the circles, estimate and ground truth, by %.0f-%.0f %%)'
            % (min(pct), max(pct), ', '.join(F.fmt(a) for a, _ in vertical), ', '.join(F.fmt(b) for _, b in vertical),
               min(cpct), max(cpct)))


def _table3_timing_text(scen):
    """The issue's criterion for the MPC's timing (the one that best reproduces Table 3), shipped model, with
    the spread the timer phase alone gives (the ``scenarios`` step's runs; '' without them)."""
    t3 = F.table3_from_scenarios(scen or {})
    if not any(k[0] == 'shipped_pt' for k in t3):
        return ''
    parts, means, spreads = [], [], []
    for title, v in (('shipped defaults', 'shipped'), ('with paper_timing', 'shipped_pt')):
        k, n, m = F.table3_score(t3, 'shipped', v)
        ages = [F.table3_score(t3, 'shipped', F.age_name(v, a))[2] for a in AGES]
        means.append(m)
        spreads.append(max(ages) - min(ages))
        parts.append('%s %d / %d, mean abs ln %s (%s-%s with the waypoint %s ms old)'
                     % (title, k, n, F.fmt(m), F.fmt(min(ages)), F.fmt(max(ages)),
                        AGES_TEXT))
    verdict = ('the two timings differ on Table 3 by far less than one timer phase from another'
               if abs(means[0] - means[1]) < 0.25 * min(spreads) else
               'Table 3 prefers %s' % ('the shipped timing' if means[0] < means[1] else 'paper_timing'))
    return (' The MPC\'s timing on Table 3 (the issue\'s criterion for its default; shipped model, `scenarios` '
            'step): %s: %s.' % ('; '.join(parts), verdict))


def _age_spread(scen, mpc_v, pid_v):
    """(fewest, most) held-out middles within the band over the MPC variant's waypoint ages (``AGES``); None
    when those runs are missing."""
    counts = []
    for age in AGES:
        inside, outside, _ = F.held_out_score(scen or {}, F.age_name(mpc_v, age), pid_v)
        if inside + outside != F.HELD_OUT_CELLS:
            return None
        counts.append(inside)
    return min(counts), max(counts)


def _fusion_gain_intro(rows):
    """The fusion-gain section's first paragraph, its figures computed (the subsets' gains from ``rows``, the
    circles' periods from ``report.CIRCLES``)."""
    fits = dict((r.role, r.profile.fix_gain) for r in rows if r.role in ('static', 'straight', 'shipped'))
    periods = [2.0 * math.pi * radius / speed for radius, speed in report.CIRCLES]
    spread = ('fitted on the straight-line logs alone it is %.1fx the fit on the static-waypoint logs alone'
              % (fits['straight'] / fits['static']) if 'static' in fits and 'straight' in fits else
              'the logs of one kind alone do not fit it here')
    return ('The position fusion\'s gain k (1/k: how long the steady lag D x speed takes to build up) is a model '
            'parameter the shared logs pin loosely: %s (docs/calibration.md). It sets how much of the steady lag a '
            'periodic motion builds (the circles\' periods are %.0f-%.0f s%s), and so how stale the MPC\'s state '
            'is in a circle. The shipped model with k at those fits and at probes beyond them '
            '(`fidelity.FUSION_GAIN_PROBES`), D refitted for each k on every clean log (the shipped row: the '
            'shipped model\'s own k and D; `fit.fusion_profile`): the fit\'s rms, the shared-log replays '
            '(summary\'s cells) and the held-out middles (table above), `fusion_gain` step.'
            % (spread, min(periods), max(periods),
               ' against 1/k = %.1f s shipped' % (1.0 / fits['shipped']) if fits.get('shipped') else ''))


def _fusion_gain_text(rows):
    """The reading of the ``fusion_gain`` table in words (computed from its rows: ``F.fusion_gain_rows``)."""
    shipped = [r for r in rows if r.role == 'shipped']
    fits = [r for r in rows if r.role in ('static', 'straight')]
    probes = [r for r in rows if r.role == 'probe']
    if not (shipped and fits and all(r.held for r in rows)):
        return 'The `fusion_gain` step has not run for every gain.'
    s = shipped[0]
    text = ('Over the gains the subsets fit (k %s 1/s; shipped %.3f) the fast MPC circles\' middles against the '
            'estimate are %s (shipped %s) and the circles\' against ground truth %s (shipped %s); the held-out '
            'middles inside the band %s (shipped %d), the shared-log cells within +-10 %% %s (shipped %d).'
            % (' and '.join('%.3f' % r.profile.fix_gain for r in fits), s.profile.fix_gain,
               ', '.join(F.mids_text(r.fast) for r in fits), F.mids_text(s.fast),
               ', '.join(F.mids_range(r.truth) for r in fits), F.mids_range(s.truth),
               ', '.join(str(r.held[0]) for r in fits), s.held[0], ', '.join(str(r.shared[0]) for r in fits),
               s.shared[0]))
    if probes:
        worse = all(r.profile.rms_static > s.profile.rms_static for r in probes)
        text += (' Beyond them, k %s 1/s: the fast circles %s, the circles vs ground truth %s, held-out middles '
                 'inside %s, shared-log cells %s; they fit the static-waypoint logs %s (rms %s m, shipped %.4f m).'
                 % (' / '.join('%.2f' % r.profile.fix_gain for r in probes),
                    ', '.join(F.mids_text(r.fast) for r in probes), ', '.join(F.mids_range(r.truth) for r in probes),
                    ', '.join(str(r.held[0]) for r in probes), ', '.join(str(r.shared[0]) for r in probes),
                    'worse' if worse else 'not all worse', ', '.join('%.4f' % r.profile.rms_static
                                                                          for r in probes),
                    s.profile.rms_static))
    return text


def _self_replay_section(selfrep):
    """The section on the replay method against the stand-in's own runs (``F.self_replay_runs``), figures
    computed from its records."""
    default = F.self_replay_score(selfrep, 'shipped')
    own = F.self_replay_score(selfrep, 'shipped', key='ratio_latency')
    lines_ = F.self_replay_score(selfrep, 'shipped', scenarios=report.STRAIGHT)
    periodic = F.HELD_OUT_SCENARIOS
    held = F.self_replay_score(selfrep, 'shipped', scenarios=periodic)
    outside = collections.Counter()               # (controller, scenario kind) of the cells outside the band
    for (v, controller, scenario), r in selfrep.items():
        if v == 'shipped' and r.get('ok'):
            kind = ('lines' if scenario in report.STRAIGHT else 'periodic motions' if scenario in periodic
                    else 'static steps')
            outside[(report.LABELS[controller], kind)] += sum(
                1 for x in (r.get('ratio') or {}).values() if x is not None and not F.within(x, F.BANDS[0]))
    where = ', '.join('%s %s %d' % (c, k, n) for (c, k), n in sorted(outside.items()) if n) or 'none'
    return ['## The replay method on the stand-in\'s own runs', '',
            'A replay is only as good as the method that makes it. Every paper scenario is run on the engine with '
            'the shipped defaults, recorded from %.1f s before its measured window to its end the way the paper\'s '
            'logger recorded Sphinx (`fidelity.run_log`: 20 Hz, the latest waypoint, the estimate as a drifting '
            'logger sees it, half floats), and that log replayed like a Sphinx log (`fidelity.self_replay_runs`): '
            'ratio replay / log, 1 when the method adds nothing. A stream that repeats itself (circles, vertical '
            'motions) gets its first period repeated as the lead-in and its initial state from a parabola '
            '(`fidelity.stream_period`, `log_initial_state(curved=True)`). The waypoint latency (how long before '
            'the logger shows a waypoint it was published) is not in a log: the first ratios assume half a sample '
            '(as for Sphinx\'s logs), the second the recording\'s own (`fidelity.recorded_latency`).' % F.SELF_BEFORE,
            '',
            F.self_replay_table(selfrep, 'shipped'), '',
            'Cells within +-10 %%: %d / %d with the assumed latency (largest |ln ratio| %s; the straight lines %d / '
            '%d; outside the band, by controller and kind: %s), %d / %d with the recording\'s own (largest %s); '
            'the circles and vertical motions, whose Sphinx logs are held out, %d / %d with the assumed one '
            '(largest %s). That is the method\'s own error on logs of the same model, without noise or jitter, '
            'that start in steady flight and cover a period and a second; a Sphinx log adds its unknown latency '
            '(0-50 ms) and whatever the model misses. Sphinx\'s held-out logs (named `<scenario>_<pid|mpc>.csv`, '
            'in the shared logs\' format) replay with `python benchmarks/fidelity.py --logs DIR --steps replay '
            '--out OUT.md --figures OUTDIR` (its tables are theirs; its text is written for the shared logs).'
            % (default[0], default[1], F.fmt(default[2]), lines_[0], lines_[1], where, own[0], own[1],
               F.fmt(own[2]), held[0], held[1], F.fmt(held[2])), '']


def render(records, t3, logs, variants, ablation, phases, fitted, meta, walls, args, scen=None, gains=None,
           selfrep=None):
    timing = meta['paper_timing_supported']
    cols = _columns(variants, timing)
    rel_fig = os.path.relpath(args.figures, os.path.dirname(os.path.abspath(args.out)))
    # every configuration, the shipped defaults included (ranked: most cells within +-10 %, then mean |ln ratio|)
    best = sorted(configurations(cols), key=lambda c: (-F.score(F.combined(records, logs, c[2], c[1]))[0],
                                   F.score(F.combined(records, logs, c[2], c[1]))[2]))
    lines = [
        '# Fidelity: the stand-in against the Sphinx reference logs',
        '',
        'Generated by `%s` (last: `%s`, %s, %s; step wall times below). Core: '
        '`anafi_sim/experiments/fidelity.py`; regression test: `test/unit/test_fidelity.py`. Measured figures: '
        '`%s/fidelity.yaml`.' % (COMMAND, meta['command'], meta['date'], meta['machine'], rel_fig),
        '',
        '## Method',
        '',
        'Every shared log (`shared/reference_logs`, the paper\'s Sphinx runs) is replayed in closed loop: the '
        'log\'s waypoint columns, as the 10 Hz stream the controller saw, are fed to the controller the log '
        'name says (PID framework or the paper\'s MPC) on the stand-in, with the in-process engine '
        '(`anafi_sim/experiments/engine.py`, the ROS graph\'s schedule on virtual time). Each waypoint change '
        'is one 10 Hz generator tick, published half a log sample (25 ms) before the logger first shows it; '
        'the all-zero waypoint the static PID logs hold before the step (no waypoint yet; the drone hovers at '
        '1 m) is replaced by the hover point; a straight-line log (a steady-state segment) gets a %g s lead-in '
        '(its first waypoint extrapolated backwards at its velocity) so the controller has settled when the '
        'log begins; the replay runs in a frame shifted horizontally to the take-off point (the dynamics do '
        'not depend on x, y) and the positions are shifted back; the drone takes off at the heading at which '
        'its estimate shows the log\'s first estimated yaw (a 180 deg step turns the way it turned in Sphinx); '
        '%g s before log time 0 the replay is put in the log\'s initial state: the simulated drone translated so '
        'that its truth is the log\'s (a line through the first second of the float16 columns), the fused '
        'position estimate moved to the logged estimate and the velocity estimate\'s error set to the logged one '
        '(each only where the model has that state: without the fusion the position estimate holds no error of '
        'its own, and the drone is translated so that its estimate, the controller\'s input, is the log\'s); from '
        'there the model\'s dynamics take over. Where the log\'s estimate stream stalled (`fidelity.log_stalls`: '
        '3 or more unchanged estimate rows while the drone moves, until a row has caught up, i.e. moved at least '
        'half as far as the truth since the stall began; one 0.2-0.25 s stall in each of x_straight_2/3/5_mpc, '
        'none elsewhere) the replay holds the stand-in\'s published estimate too, while its filters run on '
        '(`StateEstimate.stall`): the MPC saw those stalls and reacted to them (its pitch rose by 1.1-2.4 deg '
        'within 0.8 s), '
        'so they are a condition of the run the controller experienced, replayed like its waypoint stream. '
        'The stand-in\'s estimate (its 20 Hz samples '
        'as a 20 Hz logger with a drifting phase sees them on average, like Sphinx\'s 19.5 Hz estimate in the '
        '20 Hz logs) and ground truth (interpolated) are resampled at the log\'s own sample times and evaluated '
        'with the '
        'log\'s waypoint columns, after being stored as the logger stored Sphinx\'s (every column of the logs is '
        'a half float written as its shortest repr, `reference_log.as_logged`: a 0.0625 m grid at 64-128 m, '
        '0.125 m at 128-256 m, which the e_max of the fast lines feels), by the function that recomputes the '
        'paper\'s Table 3 '
        '(`reference_log.tracking_error`, garbage excluded): e_mu and e_max against the estimate (the paper\'s '
        'metric) and against ground truth. In x_straight_2_pid and x_straight_3_pid every z_anafi sample is a '
        '16-bit wrap and Sphinx\'s drone sank below the ground under it, so those cells are the horizontal '
        'error (marked). Time base: log time, t = 0 at the log\'s first sample; the replay starts the motion '
        '(the step, the line) at the same log time as the log.' % (F.DEFAULT_LEAD, F.INITIAL_AHEAD),
        '',
        'Configurations: **effects off** = the calibration\'s baseline (`fit.calibrate(logs).baseline`: '
        '`anafi_sim/config/anafi_model.yaml` with every fidelity effect off, the keys an effect refits - the '
        'estimate\'s delay/smoothing, the attitude and vertical time constants - at their values without it); **effects on** = %s (position fusion, velocity error decay, tilt attenuation, descent limit, vertical acceleration limit, '
        'tilt-rate limit, the tilt loop\'s coupling to the yaw rate, yaw bias, quantisation; '
        'values below); **fusion only** = effects off plus the position fusion\'s keys. %s **shipped '
        'defaults** = `anafi_model.yaml` as committed (%s) and mpc.yaml (`paper_timing: %s`); **shipped, settled '
        'start** = the same, replayed without the initial state (every log starts settled on its line: the '
        'method before; not a configuration of the stand-in); **shipped, without the logs\' estimate stalls** = the '
        'same, replayed without holding the stand-in\'s estimate where the log\'s stalled (the method before; '
        'not a configuration either); **shipped, unrounded columns** = the same runs measured without the logger\'s '
        'half-float storage of the stand-in\'s columns (the measurement before).' % (
            '`%s`' % meta['fitted_model'] if meta['fitted_model'].endswith('.yaml') else meta['fitted_model'],
            ('For the MPC logs also `paper_timing: true` (mpc.yaml: the authors\' node computes each command '
             'from the state and waypoint of the previous cycle); the PID logs do not depend on it.')
            if timing else '(`paper_timing` of the MPC is not in mpc.yaml yet: not measured.)', meta['shipped_model'],
            str(mpc_config()[0].get('paper_timing', False)).lower() if timing else 'n/a'),
        '',
        '## Summary',
        '',
        'Cells (log x {e_mu, e_max} x {estimate, truth}) whose stand-in value is within the band of Sphinx\'s '
        '(ratio = stand-in / Sphinx):',
        '',
        F.score_table(records, logs, cols),
        '',
        'The same cells after the first second of each log (log time >= %g s): a replay starts from the log\'s '
        'state (Method), so the first second matches partly by construction; what follows is the model\'s:' % F.LATE,
        '',
        F.score_table(records, logs, cols, key='ratio_late'),
        '',
        'Best configuration on the shared logs (most cells within +-10 %%, then mean |ln ratio|): **%s**.' % best[0][0],
        '',
    ]
    if t3:
        t3best = sorted(configurations(cols), key=lambda c: (-F.table3_score(t3, c[1], c[2])[0], F.table3_score(t3, c[1], c[2])[2]))
        lines += ['Best on the paper\'s Table 3 (engine runs of straight_1..5, e_mu vs the estimate): **%s** '
                  '(%d / %d cells within +-10 %%).' % (t3best[0][0], F.table3_score(t3, t3best[0][1], t3best[0][2])[0],
                                                     F.table3_score(t3, t3best[0][1], t3best[0][2])[1])
                  + _table3_timing_text(scen), '']
    lines += ['## Recommendation for the defaults', '']
    k, n, m = F.score(F.combined(records, logs, best[0][2], best[0][1]))
    if best[0][1] == 'shipped':
        # the runner-up among the other configurations, so the reader sees what the choice is against
        other = best[1]
        k2, n2, m2 = F.score(F.combined(records, logs, other[2], other[1]))
        lines.append('By these measurements the shipped defaults score best (%d / %d shared-log cells within +-10 %%, '
                     'mean |ln ratio| %s); the next configuration is **%s** (%d / %d, %s). '
                     % (k, n, F.fmt(m), other[0], k2, n2, F.fmt(m2)))
    else:
        ks, ns, ms = F.score(F.combined(records, logs, 'shipped', 'shipped'))
        lines.append('By these measurements: **%s** (%d / %d shared-log cells within +-10 %%, mean |ln ratio| %s); '
                     'the shipped defaults score %d / %d, %s (why they are kept: "Shipped" below). '
                     % (best[0][0], k, n, F.fmt(m), ks, ns, F.fmt(ms)))
    lines[-1] += _held_out_text(scen, timing)
    lines[-1] += 'Per effect, against all effects off (ablation below: cells within +-10 %, mean |ln ratio|):'
    k0, n0, m0 = F.score(F.combined(records, logs, 'off', 'off'))
    lines.append('')
    lines.append('- all off: %d / %d, %s' % (k0, n0, F.fmt(m0)))
    for v in ablation:
        recs = F.combined(records, logs, v.name, v.name)
        if recs:
            k, n, m = F.score(recs)
            lines.append('- %s alone: %d / %d, %s' % (v.label, k, n, F.fmt(m)))
    lines += ['',
              'Reading of the tables at the time of writing (the figures of the initial state, the storage and '
              'the stalls come from the tables above). ' + _initial_text(records, logs) + ' Sphinx\'s lines start '
              'with the estimate off the truth by '
              'more than the steady lag (x_straight_4_mpc: lag 0.262 s in the first 2 s, 0.23 s at the end) and by up '
              'to 19 cm across the line (x_straight_4_pid), with a velocity estimate off by up to 0.11 m/s across it '
              '(docs/calibration.md), all decaying within the log: the history of each run (take-off, approach), '
              'which the replay now starts from. Those e_max cells sit in the first 1.2 s of the logs, where the '
              'replay starts at the log\'s state (the summary\'s second table leaves the first second out); after '
              'the first second the truth e_mu of x_straight_1/3/4_mpc '
              'is 0.085 / 0.167 / 0.189 m against Sphinx\'s 0.090 / 0.158 / 0.177 m: the decay is the model\'s '
              '(fusion gain k, velocity-error time constant T), not set from the log. The lag\'s drift follows '
              '(x_straight_4_mpc, 2 s bins: Sphinx 0.262, 0.253, 0.245, 0.237 s; the replay 0.264, 0.258, 0.254, '
              '0.248 s; x_straight_1_mpc: 0.249, 0.247, 0.241, 0.237 s and 0.257, 0.254, 0.251, 0.246 s). **The '
              'position fusion** is the effect that moves the ground-truth cells (Sphinx\'s truth '
              'runs ahead of its estimate): without it the stand-in\'s truth e_mu on the MPC lines is 1.4-4.0x '
              'Sphinx\'s, with it alone 0.54-1.00x, with the velocity error and the attenuation (shipped) '
              '0.95-1.11x; the velocity error acts mostly through the fusion (alone it moves one cell: the '
              'controllers see it in the velocity estimate, but without the fusion the position does not '
              'integrate it). **The tilt attenuation**, gated by '
              'speed (none up to 4 m/s, a fifth at 5 m/s), leaves every slower log as it was and brings the 5 m/s '
              'cells in: x_straight_5_mpc 0.81 -> 0.97 against the estimate and 0.54 -> 1.11 against ground truth '
              '(fusion only -> shipped), Table 3\'s 5 m/s MPC cell 0.75 -> 0.95. **The tilt-rate limit** (effects '
              'on, off as shipped) brings static_waypoint_yaw_0_mpc closer (0.94 / 0.91 -> 0.97 / 0.94) and the '
              'attitude history of the static PID steps closer when it is the only effect (roll / pitch rms against '
              'Sphinx 0.53 / 1.23 -> 0.33 / 0.90 deg and 3.35 / 4.58 -> 3.01 / 4.34 deg against all off), but it '
              'shrinks the yaw-0 step overshoots away from Sphinx\'s (overshoot = `step_response.overshoot` of the '
              'ground truth, the norm of the per-axis overshoots, as test/ros/test_mpc_closed_loop.py measures it; '
              'shipped -> effects on: PID 0.64 -> 0.44 m, Sphinx 0.58 m; MPC 0.19 -> 0.15 m, Sphinx 0.215 m). '
              '**The vertical '
              'acceleration limit** brings the vertical speed of the static steps closer (vz rms against Sphinx, '
              'all off -> it alone: 0.172 -> 0.154, 0.206 -> 0.188 m/s on the MPC steps, 0.035 -> 0.032, 0.041 -> '
              '0.035 m/s on the PID steps) and moves their cells by 1-2 %; its weight is in the vertical periodic '
              'motions (Table 5), which no shared log has. The descent limit, the yaw bias and the quantisation '
              'hardly move any cell (they act in saturated descents, on the yaw, below the centimetre). The '
              'MPC\'s `paper_timing` leaves the straight lines unchanged (the state and the waypoint are equally '
              'old) and moves the static-waypoint MPC cells (effects on, yaw 180: 0.99 / 0.99 -> 1.05 / 1.05; the '
              'shipped model below). **The coupling of the tilt '
              'loop to the yaw rate** (docs/calibration.md: while the drone yaws the roll/pitch loop loses authority, '
              'its steps are turned and slowed (G), the tilt precesses with the body) acts only in the two yaw-180 '
              'steps (at the time of writing, the shipped model without it -> with G alone, the model before -> with '
              'all three terms, as shipped): roll / pitch rms against Sphinx MPC 7.98 / 6.67 -> 3.18 / 4.17 -> 2.99 '
              '/ 3.58 deg, PID 3.21 / 4.54 -> 2.45 / 2.04 -> 1.14 / 1.31 deg; e_mu est / truth MPC 0.78 / 0.76 -> '
              '0.79 / 0.78 -> 0.93 / 0.94, PID 0.95 / 0.93 -> 0.92 / 0.90 -> 0.98 / 0.96: through the turn the tilt '
              'keeps its magnitude and swings round the long way in the sense of the yaw, as Sphinx\'s does, where it '
              'cut through level (none) or dipped to ~14 deg (G alone); the fitted file has the three terms refitted '
              'on its tilt-rate limited loop (docs/calibration.md; effects on: MPC 0.99 / 0.99, PID 1.00 / 0.98, '
              'histories 3.11 / 3.05 and 1.34 / 1.33 deg). The MPC line '
              'cells move by +-15-35 % with the waypoint\'s age at the MPC\'s cycle '
              '(timer phase section), which the logs do not record. Sphinx\'s estimate e_max on the MPC lines at 2, '
              '3 and 5 m/s comes from stalls of its estimate stream (below). ' + _method_text(records, logs), '',
              'Shipped (`SHIPPED_EFFECTS` in `anafi_sim/calibration/fit.py`, `paper_timing` in mpc.yaml): the '
              'position fusion, the velocity error\'s decay (it changes nothing in a flight: nothing in the model '
              'creates such an error; a replay sets it from the log), the speed-gated tilt attenuation, the '
              'vertical acceleration limit, the tilt loop\'s coupling to the yaw rate, the yaw bias and the '
              'quantisation on; the '
              'tilt-rate limit off: it fits the attitude better open loop, and with it (effects on, with the '
              'descent limit) as many cells are in the band with a lower mean |ln ratio| (summary), but it takes '
              'the yaw-0 step overshoots away from Sphinx\'s (overshoot as above; PID 0.64 -> 0.44 m, Sphinx 0.58 '
              'm; MPC 0.19 -> 0.15 m, Sphinx 0.215 m) while it brings the yaw-180 ones closer (PID 1.11 -> 0.89 m, '
              'MPC 0.94 -> 0.91 m, Sphinx 0.83 m both; at the time of writing): not switched (the ROS batch and the preview MPC\'s '
              'governor are measured with the first-order loop, and by the held-out bounds its faster loop takes '
              'the fast circles further from Sphinx: below); '
              'the descent limit '
              'off: it is identified only in x_straight_2/3_pid, where Sphinx\'s drone sank below the ground under '
              'a wrapped z estimate - not normal flight - and the held-out vertical runs would be the test of it '
              '(so "effects on" differs from the shipped defaults by these two). `paper_timing: false`: with it '
              'Sphinx\'s MPC step starts when the replay\'s does (~0.1 s later than without: one cycle of age) and '
              'the static MPC e_mu cells come closer (shipped model, offline replays, not a column of the tables: '
              'yaw 0 0.94 / 0.91 -> 1.00 / 0.98, yaw 180 0.93 / 0.94 -> 1.02 / 1.02), but ' + _timing_text(scen)
              + ' (the held-out comparison of the issue had the first delivery\'s vertical cells at 1.3-1.9x '
              'Sphinx\'s; the recommendation above counts the held-out cells), and the yaw-0 MPC '
              'step overshoots 2.2x Sphinx\'s (overshoot as above: Sphinx 0.215 m, shipped 0.19 m, with '
              'paper_timing 0.48 m; yaw 180: Sphinx 0.83 m, shipped 0.94 m, with it 0.81 m); Table 3 is '
              '10 / 10 either way. With the tilt-rate limit on, paper_timing matches '
              'the overshoots too (0.26 and 0.77 m, at the time of writing), but by the held-out bounds '
              '(recommendation above: "on + paper_timing") that pair does not do better on Tables 4 and 5: the '
              'tilt-rate limit\'s faster small-signal loop (0.114 s) shrinks the fast circles\' error, which the '
              'issue\'s comparison has too small already, and paper_timing takes the vertical motions out; the '
              'vertical loop of the MPC runs is not '
              'identified (their climbs reach 2.4 m/s under a 2.0 m/s command, the PID runs\' do not: '
              'docs/calibration.md).', '',
              'What remains off with the shipped defaults, and why (not modelled: the logs do not identify it): '
              'the truth e_max of x_straight_5_mpc (0.80) is one '
              'sample of Sphinx\'s truth stream: at 0.60 s its x is 0.108 m behind the 5.02 m/s line through its '
              'neighbours (0.40-0.75 s, each within 0.045 m of it; a value ~20 ms older than its stamp); the next '
              'largest error of that log is 0.404 m, the stand-in\'s e_max 0.404 m. Its truth e_mu (1.11) is the '
              'storage\'s (0.99 unrounded, above): at 5 m/s x advances by about whole storage steps each sample, '
              'so the rounding stays correlated over long stretches and what it adds to the mean depends on where '
              'the positions fall against the grid; '
              'x_straight_2/3_pid ground truth (0.80-0.89) is no normal flight (wrapped z estimate, the drone below '
              'the ground, its truth-estimate lag drifting from 0.09 to -0.16 s). '
              'static_waypoint_yaw_180_mpc was off (0.78 / 0.76 without a coupling to the yaw rate, 0.79 / 0.78 '
              'with G alone) until the loss of the loop\'s authority and the precession were modelled; the road '
              'there, offline experiments before them (figures of the model without any coupling unless said): '
              'paper_timing with the yaw loop\'s command one cycle old as well (as if the authors\' node computed it '
              'in the same cycle): the yaw turn then starts when Sphinx\'s does (yaw 8 / 18 / 40 deg at 0.5 / 0.7 / '
              '0.9 s after the step, Sphinx 6 / 17 / 42 deg; without it the stand-in leads by ~0.1 s) and with G '
              'alone the cells came to 0.86 / 0.86, but the histories moved away (5.9 / 4.9 deg); '
              '(four explanations ruled out: docs/calibration.md; a fifth, the yaw rate '
              'applied about the body z axis with its Euler coupling into roll and pitch, either sign, moves these '
              'e_mu by +-0.03 and brings the roll / pitch histories no closer; a sixth, a full-attitude loop on SO(3) '
              '(the firmware turning the body along the rotation to an attitude setpoint whose heading integrates '
              'the yaw-rate command, with the same small-signal time constants), moves these cells to 0.81 / 0.80 '
              'and the PID yaw-180 cells from 0.95 / 0.93 to 1.00 / 0.98, '
              'but takes the roll / pitch histories of both yaw-180 steps away from Sphinx\'s (MPC 7.98 / 6.67 -> '
              '9.06 / 6.63 deg, PID 3.21 / 4.54 -> 4.29 / 5.34 deg) and its tilt still falls to ~5 deg at 1.1 s '
              'where Sphinx\'s stays at 25-30 deg; a frame slip in the authors\' MPC - the velocity used in the body '
              'frame, either sign - is no candidate: the replay diverges, e_mu 7-9x; a seventh: each step of the '
              'roll/pitch loop rotated in the (roll, pitch) plane by kappa x the yaw rate: kappa = -0.6 s brings the '
              'roll / pitch histories of both yaw-180 steps much closer (MPC 7.98 / 6.67 -> 5.91 / 6.48 deg, PID '
              '3.21 / 4.54 -> 2.02 / 2.88 deg) but not the cells (MPC 0.77 / 0.75, PID 0.92 / 0.90), and the tilt '
              'still collapses to ~8 deg; its implicit form that also shortens the step, fitted open loop, was G '
              'alone; the tilt\'s magnitude came with a general linear coupling fitted open loop (the loop\'s decay '
              'and its attraction to the setpoint each changed by r times a scalar and a quarter turn): its decay and '
              'attraction terms came out equal and opposite, i.e. a loss of the loop\'s rate with |r| (the '
              'authority c), and its quarter-turn term a precession of the tilt (w), the terms now shipped with G '
              '(docs/calibration.md)). What the model had to '
              'reproduce: through the turn Sphinx\'s tilt keeps its magnitude (25-30 deg) and turns in the body '
              'frame with the yaw at 100-140 deg/s (from 23 to -166 deg in 1.65 s, the long way round; in the world '
              'frame its direction turns at ~2.3x the yaw, from 59 deg at 0.7 s after the step to 3 deg at 2.5 s '
              'through 180), where the '
              'MPC\'s command '
              '(recomputed from the log) swings from 31 to -150 deg through ~5 deg of tilt. Tried and not kept: '
              'a per-log heading (the replay\'s true yaw at the log\'s, i.e. the yaw bias of each log: 0.9-1.8 deg '
              'in the MPC logs, 4.4-5.4 deg in the PID logs) left the count as it was (46 / 56 then) and made the attitude '
              'histories of the static PID steps worse (roll / pitch rms 0.39 / 1.19 -> 0.78 / 1.45 deg), so the '
              'truth yaw of the PID logs does not set the thrust direction the way the model\'s does; the replay '
              'keeps the take-off heading at the log\'s estimate minus the shipped bias. Also tried and not kept: '
              'separate roll and pitch loops (fitted on the static PID steps alone, roll tau 0.10 s with delay '
              '0.175 s, pitch 0.24 s with 0.085 s, rms 0.0063 / 0.0130 rad against 0.0109 rad for the joint loop): '
              'in closed loop no cell moves, the PID steps\' roll / pitch histories come closer (0.39 / 1.19 -> '
              '0.30 / 0.89 deg, 3.21 / 4.55 -> 3.08 / 4.12 deg) and the MPC steps\' move away (1.21 / 1.76 -> 1.38 '
              '/ 1.97 deg, 7.98 / 6.67 -> 8.56 / 6.49 deg). Not explained either: the PID steps overshoot more '
              'across than Sphinx\'s (`step_response.overshoot` per axis, yaw 0: x / y 0.48 / 0.41 m, Sphinx 0.56 '
              '/ 0.07 m; yaw 180: 1.04 / 0.39 m, Sphinx 0.78 / 0.22 m; at the time of writing), with their e_mu and '
              'e_max in the band.',
              '']
    lines += [
        '## Every log: Sphinx vs the stand-in',
        '',
        'Ratios outside +-10 % in bold.',
        '',
        F.replay_table(records, logs, cols),
        '',
        '### Attitude and vertical speed histories',
        '',
        'rms difference of the ground-truth roll and pitch [deg] and vertical speed [m/s] of the stand-in '
        'against Sphinx over the whole log (same sample times).',
        '',
        F.history_table(records, logs, cols),
        '',
    ]
    if t3:
        lines += ['## Table 3 on the engine (straight-line scenarios)', '',
                  'The paper\'s straight-line scenarios (anafi_sim/config/scenarios/straight_*.yaml: 15 s settle, '
                  '12 s measured) on the in-process engine, e_mu against the estimate, vs the paper\'s Table 3.',
                  '', F.table3_table(t3, configurations(cols)), '']
    if scen:
        span = '%d-%d ms' % (round(AGES[0] * 1e3), round(AGES[-1] * 1e3))
        cols = [('PID', 'pid', ['shipped']), ('MPC', 'mpc', ['shipped']),
                ('MPC, waypoint age %s' % span, 'mpc', [F.age_name('shipped', a) for a in AGES])]
        if timing:
            cols += [('MPC + paper_timing', 'mpc', ['shipped_pt']),
                     ('MPC + paper_timing, age %s' % span, 'mpc', [F.age_name('shipped_pt', a) for a in AGES])]
        cols += [('effects on: PID', 'pid', ['on']), ('effects on: MPC', 'mpc', ['on'])]
        if timing:
            cols.append(('effects on: MPC + paper_timing', 'mpc', ['on_pt']))
        default_age = (DEFAULT_SCHEDULE['controller_phase'] - DEFAULT_SCHEDULE['generator_phase']) \
            % (1.0 / DEFAULT_SCHEDULE['generator_rate'])
        lines += ['## The paper\'s scenarios on the engine: both MPC timings', '',
                  'Every scenario of the paper (anafi_sim/config/scenarios: the static waypoints, Table 3\'s lines, '
                  'Table 4\'s circles, Table 5\'s vertical periodic motions) on the in-process engine (seed 0, no '
                  'wind), e_mu against the estimate / against ground truth [m]: the shipped defaults (`paper_timing` '
                  'false, the waypoint %d ms old at the MPC\'s cycle), the same with the waypoint %s ms old (the '
                  'ROS graph\'s timer phase is random per start-up: the range shows how much one run of a scenario '
                  'can differ from another for that reason alone, at least: the ages sampled cover %s of the '
                  '0-%d ms cycle), with `paper_timing` true, and the effects-on model. The PID framework does not '
                  'depend on `paper_timing`.'
                  % (round(default_age * 1e3), AGES_TEXT, span,
                     round(1e3 / DEFAULT_SCHEDULE['generator_rate'])), '',
                  F.scenario_table(scen, cols), '',
                  '### The held-out cells: what the issue\'s comparison implies', '',
                  'Sphinx\'s runs of Tables 4 and 5 are held out of this repository. The issue compared the first '
                  'delivery\'s stand-in with them and states one ratio range (first delivery / Sphinx) per group of '
                  'cells; with the first delivery\'s own e_mu (its ROS batch, 7494c02, '
                  '`anafi_sim.experiments.fidelity.FIRST_DELIVERY`) that bounds each Sphinx value, and so the '
                  'ratio of each configuration now. A bound, not a measurement: the ranges are per group, and the '
                  'issue\'s figures of the first delivery came from its own runs (whose timer phases, range above, '
                  'may differ from the committed batch\'s). now / Sphinx as the range the issue\'s range gives and '
                  '(in brackets) its geometric middle, in bold outside +-%d %% (the issue\'s goal for the held-out '
                  'cells); the last row counts the cells whose middle lies inside / outside that band. The issue '
                  'names the MPC cells more than 25 %% off by group (`fidelity.ISSUE_RATIOS`): the MPC\'s other '
                  'circles against the estimate are not among them (their range %.2f-%.2f is that inference; '
                  'its middle is %.2f, not 1); which of the MPC\'s vertical cells against ground truth are off '
                  'the count does not tell, so they are left out.'
                  % ((round(F.HELD_OUT_BAND * 100),) + F.INFERRED_RANGE
                     + (math.sqrt(F.INFERRED_RANGE[0] * F.INFERRED_RANGE[1]),)), '',
                  F.held_out_table(scen, held_out_configurations(timing)), '']
        if gains:
            rows = F.fusion_gain_rows(records, scen, gains, logs)
            lines += ['### The fusion gain: what the shared logs allow, and the held-out cells', '',
                      _fusion_gain_intro(rows), '',
                      F.fusion_gain_table(rows), '', _fusion_gain_text(rows), '']
    if selfrep:
        lines += _self_replay_section(selfrep)
    present = []
    for _, v in records:
        if v not in present:
            present.append(v)
    order = dict((v.name, i) for i, v in enumerate(list(ablation) + list(phases)))
    abl = sorted((v for v in present if v.startswith('only_')), key=lambda v: (order.get(v, 99), v))
    if abl:
        lines += ['## Ablation: each effect on its own', '',
                  'Ratio stand-in / Sphinx with the effects-off model plus one effect (the fitted values of its '
                  'keys; the estimate\'s delay/smoothing refit goes with the position fusion), beside all off '
                  'and all on (default MPC timing).', '',
                  F.ratio_matrix(records, logs, ['off'] + abl + ['on']), '',
                  F.score_table(records, logs, [(n, n, n) for n in ['off'] + abl + ['on']]), '']
    ph = sorted((v for v in present if v.startswith('on_age') or v.startswith('on_lat')), key=lambda v: (v[:6], v))
    if ph:
        lines += ['## Timer phase and waypoint latency (MPC logs, effects on)', '',
                  'The MPC tracks the waypoint as received; in the ROS graph the phase of the generator\'s timer '
                  'against the MPC\'s is random per start-up (engine default: the waypoint is 50 ms old at the '
                  'MPC\'s cycle). `ageNN`: the waypoint is NN ms old at the cycle (schedule `generator_phase`); '
                  '`latNN`: the replayed waypoint published NN ms before the logger first shows it (default 25 ms: '
                  'the true value lies in 0-50 ms).', '',
                  F.ratio_matrix(records, [l for l in logs if l.endswith('_mpc')], ['on'] + ph), '']
    lines += ['## The modelled effects and their residuals', '',
              'Fitted by `anafi_sim/scripts/calibrate_model.py` (`anafi_sim/calibration/fit.py`); the residual of '
              'every effect (before/after) and what the logs cannot identify: [docs/calibration.md]'
              '(calibration.md). Values of the effects-on model:', '',
              '| key | value |', '|---|---|']
    for k in EFFECTS_OFF:
        if k in fitted:
            lines.append('| %s | %s |' % (k, fitted[k]))
    lines += ['', '## Figures', '',
              'One per log: the position along the motion minus the waypoint (straight lines; estimate solid, '
              'truth dotted) or x and z (static waypoints), the tracking error against the estimate, the truth '
              'pitch and roll and the vertical speed; Sphinx black, the stand-in coloured: effects off, the shipped '
              'defaults from a settled start (before) and from the log\'s initial state (now).', '']
    for log in logs:
        lines += ['### %s' % log, '', '![%s](%s/%s.png)' % (log, rel_fig, log), '']
    lines += ['## Regenerate', '', '```', 'cd <checkout> && source env.bash',
              '%s --workers 2   # all steps (the step wall times below were measured on a machine loaded by '
              'other jobs)' % COMMAND,
              '%s --steps replay   # one step; the others are kept in docs/fidelity/fidelity.yaml' % COMMAND,
              'python -m pytest -q test/unit/test_fidelity.py    # the regression guard (shipped defaults)',
              '```', '', 'Wall time of the last run of each step [s] (a step run on a subset of the logs or variants keeps '
              'the figures of the rest): %s.' % ', '.join('%s %s' % kv for kv in sorted(walls.items())), '']
    return '\n'.join(lines)


if __name__ == '__main__':
    main()
