#!/usr/bin/env python3
"""Fidelity of the stand-in against the Sphinx reference logs (shipped: anafi_sim/data/reference_logs): closed-loop
replays -> docs/fidelity.md and docs/fidelity/*.png (the cores are anafi_lab/fidelity/, the report
anafi_lab/reports/fidelity_report.py and its template; this script only wires them to files).

Stage: benchmark (not a test; the regression guard is test/unit/lab/test_fidelity.py). Steps (``--steps``,
default all; measured figures are kept in benchmarks/results/fidelity.yaml (``--store``) so that a step can be
rerun alone and the report re-rendered: ``--steps ,`` measures nothing and re-renders the report from it):

- ``replay``: every reference log replayed in closed loop by its controller on the in-process engine with the
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
  the waypoint 5 / 30 / 55 / 80 ms old at its cycle; with what the comparison with Sphinx's runs implies for the
  held-out cells of Tables 4 and 5 (``held_out.held_out_bounds``);
- ``fusion_gain``: the shipped model with the position fusion's gain k (and its delay refitted) at the fits of
  the static-waypoint logs alone and of the straight-line logs alone, and at ``variants.FUSION_GAIN_PROBES``
  beyond them: how well the logs allow each k (``estimate.fusion_profile``), the shared-log replays and the
  held-out scenarios with it;
- ``self_replay``: the replay method on the stand-in's own runs of every paper scenario (``variants.self_replay_runs``):
  recorded as the paper's logger recorded Sphinx, replayed, compared (ratio 1 = the method adds nothing).

Logs of other scenarios (e.g. Sphinx's runs of Tables 4 and 5, in the reference logs' format, named
``<scenario>_<pid|mpc>.csv``) are replayed alike: ``--logs DIR --steps replay`` (with ``--out`` / ``--figures`` /
``--store`` elsewhere); the models are calibrated on ``--calibration-logs`` (default the shipped logs) whatever
``--logs`` is.

    python anafi_lab/cli/measure_fidelity.py [--steps replay,...,self_replay] [--workers 2]
"""
import argparse
import collections
import datetime
import os
import sys
import time

import yaml

from anafi_sim import paths, processes, run_files
from anafi_lab.calibration import estimate, fit
from anafi_lab.engine import replay as F
from anafi_lab.fidelity import held_out as H
from anafi_lab.fidelity import variants as V
from anafi_lab.reports.fidelity_plot import plot_replay
from anafi_lab.reports import conditions_report, fidelity_report as report
from anafi_lab.engine.engine import mpc_config
from anafi_sim.mission.reference_log import read_log
from anafi_sim.sim.drone_model import EFFECTS_OFF, load_model_params

STEPS = ('replay', 'ablation', 'phases', 'table3', 'scenarios', 'fusion_gain', 'self_replay')
PLOTTED = ('off', 'settled', 'shipped')       # the variants in each log's figure: before (settled start) / after
COMMAND = report.COMMAND


def parse_args(argv):
    root = paths.checkout()
    parser = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    parser.add_argument('--logs', default=paths.reference_logs_dir(),
                        help='directory with the reference-log CSVs (default: the shipped ones, '
                             'anafi_sim/data/reference_logs)')
    parser.add_argument('--calibration-logs', default=paths.reference_logs_dir(),
                        help='directory of the logs the models are calibrated on (default: the shipped reference logs)')
    parser.add_argument('--out', default=os.path.join(root, 'docs', 'fidelity.md'), help='Markdown report')
    parser.add_argument('--figures', default=os.path.join(root, 'docs', 'fidelity'),
                        help='directory of the figures (one PNG per log)')
    parser.add_argument('--store', default=os.path.join(root, 'benchmarks', 'results', 'fidelity.yaml'),
                        help='YAML of the measured figures (read, updated by the steps run, re-rendered)')
    parser.add_argument('--facts', default=os.path.join(root, 'benchmarks', 'results', 'fidelity_log_facts.yaml'),
                        help='YAML of the facts of the shared logs the report quotes (not measured by a step)')
    parser.add_argument('--findings', default=os.path.join(root, 'benchmarks', 'results', 'fidelity_findings.yaml'),
                        help='YAML of the offline findings the report\'s reading quotes (not measured by a step)')
    parser.add_argument('--fitted', default=paths.config_path('anafi_model_fitted.yaml'),
                        help='model YAML with every effect on (missing: calibrate the logs)')
    parser.add_argument('--steps', default=','.join(STEPS),
                        help='comma-separated subset of %s (none, e.g. ",": re-render the report from --store)'
                             % ', '.join(STEPS))
    parser.add_argument('--workers', type=int, default=os.cpu_count() or 1, help='worker processes')
    parser.add_argument('--only', default='', help='comma-separated log names (default: every log)')
    parser.add_argument('--variants', default='',
                        help='replay / table3 / scenarios: comma-separated configurations (replay, table3: off, on, '
                             'off_pt, on_pt, ...; scenarios: shipped, shipped_pt, on, on_pt, shipped_age05, ...; '
                             'default all; a subset draws no figures)')
    parser.add_argument('--effects', default='', help='ablation: comma-separated effects (default: every one)')
    parser.add_argument('--ages', default=','.join(str(round(a * 1e3)) for a in V.AGES),
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
    ``estimate.PositionFusionFit``)."""
    shipped = load_model_params()
    cal = fit.calibrate([read_log(p) for p in paths_])    # ~15 s: the baseline (every effect off)
    # (paths_: the calibration logs, the shared ones by default: a --logs directory of other scenarios is only
    # replayed)
    off = dict(cal.baseline)          # an effect's refitted keys (e.g. the vertical time constant) at their off values
    if os.path.isfile(args.fitted):
        on, how = load_model_params(args.fitted), os.path.relpath(os.path.realpath(args.fitted), paths.checkout())
    else:
        on = dict(cal.fitted)
        how = 'anafi_lab.calibration.fit.calibrate(logs).fitted (%s missing)' % args.fitted
    groups = [g for g, keys in V.effect_groups(on).items()           # on: an effect key off its off value
              if any(shipped.get(k, v) != v for k, v in EFFECTS_OFF.items() if k in keys)]
    name = 'with %s on' % ', '.join(groups) if groups else 'with every effect off'
    return off, dict(on), name, how, dict(shipped), cal.effects.fusion


def fusion_gain_entries(fusion, shipped, logs):
    """[(role, label, ``estimate.FusionProfileRow``, variant name)] of the ``fusion_gain`` step (roles
    ``variants.FUSION_GAIN_ROLES``): the fix gain k fitted on the static-waypoint logs alone, the shipped model's (its
    own delay: the ``shipped`` runs of the other steps), the one fitted on the straight-line logs alone, and
    ``variants.FUSION_GAIN_PROBES``; the others with the delay refitted for their k on every clean log
    (``estimate.fusion_profile``). ``fusion``: the calibration's ``PositionFusionFit`` (a subset without static or
    straight logs has no fit of its own: left out)."""
    rate = shipped['estimate_rate']
    gains = [('static', 'static-waypoint logs alone', (fusion.groups.get('static') or (None,))[0], None),
             ('shipped', 'shipped model', shipped['estimate_position_fix_gain'],
              shipped['estimate_position_fix_delay'] + 0.5 / rate),
             ('straight', 'straight-line logs alone', (fusion.groups.get('straight') or (None,))[0], None)]
    gains += [('probe', 'probe beyond the fits', g, None) for g in V.FUSION_GAIN_PROBES]
    gains = [g for g in gains if g[2] is not None]
    rows = estimate.fusion_profile(logs, [g[2] for g in gains], rate, [g[3] for g in gains])
    return [(role, label, row, 'shipped' if role == 'shipped' else V.gain_name('shipped', row.fix_gain))
            for (role, label, _, _), row in zip(gains, rows)]


def supports_paper_timing():
    """True when mpc.yaml / the engine know the MPC's ``paper_timing`` key."""
    try:
        mpc_config({'paper_timing': True})
        return True
    except ValueError:
        return False


def strip(rec):
    """A replay record without its plotted series (the store keeps the figures, not the histories)."""
    return dict((k, v) for k, v in rec.items() if k != 'series')


def load_store(path):
    """The store of measured figures at ``path`` ({} when there is none yet)."""
    return run_files.read_yaml(path, {})


def render(args):
    """Re-render the report from the store (nothing measured); exits when the store has no measured figures."""
    store = load_store(args.store)
    if not store.get('meta') or not store.get('replays'):
        sys.exit('no measured figures in %s: run a step first (--steps replay)' % args.store)
    out_dir = os.path.dirname(os.path.abspath(args.out))
    store_name = os.path.relpath(os.path.abspath(args.store), paths.checkout())
    text = report.report_from_store(store, os.path.relpath(args.figures, out_dir),
                                    os.path.relpath(args.store, out_dir), store_name,
                                    report.load_log_facts(args.facts), report.load_findings(args.findings))
    run_files.atomic_write_text(args.out, with_real_flights(text, args.out))


def with_real_flights(text, out):
    """``text`` with the "real flights" section of the report at ``out`` kept as it is (calibrate_conditions.py
    writes it from its own measured figures)."""
    begin, end = conditions_report.FIDELITY_BEGIN, conditions_report.FIDELITY_END
    kept = conditions_report.existing_section(open(out).read(), begin, end) \
        if os.path.exists(out) else ''
    return conditions_report.replace_section(text, kept, begin, end) if kept else text


Plan = collections.namedtuple('Plan', 'log_paths chosen variants run_variants ablation phases scen_variants')
Plan.__doc__ = ('What the steps run: log_paths (the logs replayed), chosen (--variants, [] = all), variants (the '
                '``replay`` / ``table3`` configurations), run_variants (those chosen), ablation, phases, '
                'scen_variants (the ``scenarios`` configurations).')


def plan_steps(args, off, on, shipped_model, timing):
    """The ``Plan`` of a run from the arguments and the models."""
    all_paths = F.find_logs(args.logs)
    only = [s for s in args.only.split(',') if s]
    log_paths = [p for p in all_paths if not only or os.path.splitext(os.path.basename(p))[0] in only]
    variants = V.main_variants(off, on, timing, shipped_model)
    chosen = [v for v in args.variants.split(',') if v]
    effects = [e for e in args.effects.split(',') if e]
    ablation = [F.Variant('only_%s' % k, k, m, {'mpc': {'paper_timing': False}} if timing else None)
                for k, m in V.effect_variants(off, on).items() if not effects or k in effects]   # vs 'off'
    phases = V.phase_variants(on, 'on', [float(a) * 1e-3 for a in args.ages.split(',') if a],
                              [float(a) * 1e-3 for a in args.latencies.split(',') if a])
    return Plan(log_paths, chosen, variants, [v for v in variants if not chosen or v.name in chosen], ablation,
                phases, V.scenario_variants(shipped_model, on, timing))


def prune(measured, plan, off, on):
    """Drop the records of variants the script no longer has (a subset run keeps the others)."""
    known = set(v.name for v in plan.variants + plan.phases + V.phase_variants(on, 'on'))
    known.update('only_%s' % k for k in V.effect_variants(off, on))
    known.update(name for _, _, _, name in measured.gains)
    for key in [k for k in measured.records if k[1] not in known]:
        del measured.records[key]
    known_scen = set(v.name for v in plan.scen_variants) | set(name for _, _, _, name in measured.gains)
    for key in [k for k in measured.scen if k[0] not in known_scen]:
        del measured.scen[key]


def run_step(step, args, plan, measured):
    """Run one step; the new replay records ({(log, variant): record}; the other steps update ``measured``)."""
    if step == 'replay':
        new = F.replay_all(plan.log_paths, plan.run_variants, workers=args.workers)
        for p in (plan.log_paths if not plan.chosen else []):
            name = os.path.splitext(os.path.basename(p))[0]
            series = [(v.label, new[(name, v.name)]['series']) for v in plan.variants
                      if (name, v.name) in new and new[(name, v.name)].get('series') and v.name in PLOTTED]
            plot_replay(os.path.join(args.figures, name + '.png'), read_log(p), series,
                        title='%s: Sphinx (black) vs the stand-in' % name)
        return new
    if step in ('ablation', 'phases'):
        return F.replay_all(plan.log_paths, plan.ablation if step == 'ablation' else plan.phases,
                            workers=args.workers)
    if step == 'table3':
        measured.t3.update(V.table3_runs([v for v in plan.run_variants if v.name not in V.METHODS],
                                         workers=args.workers))
    elif step == 'scenarios':
        chosen = [v for v in plan.scen_variants if not plan.chosen or v.name in plan.chosen]
        measured.scen.update(V.scenario_runs(chosen, workers=args.workers))
    elif step == 'self_replay':
        measured.selfrep.clear()
        measured.selfrep.update(V.self_replay_runs([v for v in plan.scen_variants if v.name == 'shipped'],
                                                   workers=args.workers))
    else:
        # each step's own 'shipped' variant with the other gains (the same MPC timing as the runs they join)
        rows = [row for role, _, row, _ in measured.gains if role != 'shipped']
        new = F.replay_all(plan.log_paths, V.fusion_gain_variants(
            [v for v in plan.variants if v.name == 'shipped'][0], rows), workers=args.workers)
        shipped = [v for v in plan.scen_variants if v.name == 'shipped'][0]
        measured.scen.update(V.scenario_runs(V.fusion_gain_variants(shipped, rows), H.HELD_OUT_SCENARIOS,
                                             workers=args.workers, label='fusion_gain'))
        return new
    return {}


def main(argv=None):
    argv = argv if argv is not None else sys.argv[1:]
    args = parse_args(argv)
    if not args.steps:
        render(args)
        print('re-rendered %s from %s' % (args.out, args.store))
        return
    if not F.find_logs(args.logs):
        sys.exit('no reference logs in %s' % args.logs)
    calibration_paths = F.find_logs(args.calibration_logs)
    if not calibration_paths:
        sys.exit('no calibration logs in %s' % args.calibration_logs)
    off, on, shipped, how, shipped_model, fusion = models(args, calibration_paths)
    timing = supports_paper_timing()
    measured = report.measured_from_store(load_store(args.store))
    if 'fusion_gain' in args.steps:
        measured = measured._replace(gains=fusion_gain_entries(fusion, shipped_model,
                                                               [read_log(p) for p in calibration_paths]))
    measured = measured._replace(walls=dict((k, v) for k, v in measured.walls.items() if k in STEPS))
    plan = plan_steps(args, off, on, shipped_model, timing)
    prune(measured, plan, off, on)
    load = processes.load_average()      # the machine's load before the steps
    t0 = time.perf_counter()
    for step in args.steps:
        t = time.perf_counter()
        new = run_step(step, args, plan, measured)
        measured.records.update((k, strip(r)) for k, r in new.items())
        measured.walls[step] = round(time.perf_counter() - t, 1)
        meta = collections.OrderedDict([
            ('command', (COMMAND + ' ' + ' '.join(argv)).rstrip()),
            ('date', datetime.datetime.now().strftime('%Y-%m-%d %H:%M')),
            ('machine', processes.machine(load)),
            ('shipped_model', shipped), ('fitted_model', how), ('paper_timing_supported', timing),
            ('wall_s', round(time.perf_counter() - t0, 1))])
        measured = measured._replace(meta=dict(meta), fitted=dict(on))
        # the figures and the report after every step (a later step may be cut short)
        run_files.atomic_write_text(args.store, yaml.safe_dump(report.store_from_measured(measured), default_flow_style=False,
                                                sort_keys=False))
        render(args)
    print('wrote %s and %s (%.0f s)' % (args.out, args.store, time.perf_counter() - t0))


if __name__ == '__main__':
    main()
