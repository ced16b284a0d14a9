"""Variants of the stand-in and the paper's scenarios on the engine (pure, no ROS).

- ``effect_groups`` / ``effect_variants``: the fidelity effects a fitted model switches on, one model per effect
  (the effects-off model plus that effect's keys);
- ``age_variants``: a variant with the waypoint NN ms old at the MPC's cycle (engine schedule ``generator_phase``;
  the ROS graph's timer phase is random per start-up);
- ``scenario_runs`` / ``table3_runs``: the paper's scenarios (static waypoints, Tables 3-5) on the in-process
  engine per variant and controller;
- ``self_replay_runs``: the replay method on the stand-in's own runs (recorded with ``replay.run_log`` as the
  paper's logger recorded Sphinx, then replayed like a Sphinx log: the method's own error);
- ``fusion_gain_variants``: a variant at other gains of the position fusion (its delay refitted for each).
"""
import collections

import numpy as np

from anafi_lab.engine.engine import DEFAULT_SCHEDULE, Engine
from anafi_lab.engine.replay import (CELLS, Variant, _controller_params, _num, compare, latest_waypoint,
                                       reference_cells, replay_plan, run_log, run_replay, waypoint_arrivals)
from anafi_lab import paper
from anafi_sim.sim.drone_model import EFFECT_GROUPS, load_model_params

AGES = (0.005, 0.030, 0.055, 0.080)          # s, waypoint age at the MPC's cycle (the ``phases`` / ``scenarios`` steps)
METHODS = ('settled', 'nostalls', 'unstored')    # variants that are replay methods, not configurations


def effect_groups(fitted):
    """{effect name: {model keys}} of the fidelity effects a fitted model dict switches on (the keys whose
    value differs from the effects-off model; the estimate's delay/smoothing refit goes with the fusion)."""
    return collections.OrderedDict((k, tuple(x for x in keys if x in fitted)) for k, keys in EFFECT_GROUPS.items())


def effect_variants(off, fitted):
    """One model dict per effect: ``off`` with only that effect's keys from ``fitted``; {name: dict}
    (effects whose fitted values equal the off values are left out: nothing to switch)."""
    out = collections.OrderedDict()
    for name, keys in effect_groups(fitted).items():
        model = dict(off)
        changed = False
        for k in keys:
            if model.get(k) != fitted[k]:
                changed = True
            model[k] = fitted[k]
        if changed:
            out[name] = model
    return out


def _scenario_engine(scenario, controller, variant, seed):
    """The engine of a paper scenario with ``variant``'s model, controller parameters and schedule (None: the
    shipped defaults)."""
    return Engine(scenario, controller, seed=seed,
                  controller_params=_controller_params(variant, controller),
                  schedule=variant.schedule if variant is not None else None,
                  model_params=variant.model_params if variant is not None else None)


def _per_scenario(variants, scenarios, seed, workers, progress, label, function):
    """``function`` (a worker taking (scenario, controller, variant, seed)) for every variant, controller (a
    variant's ``controllers`` only) and scenario; ``scenario_records`` of its records."""
    from anafi_lab.engine import runs
    tasks = [(s, c, v, seed) for v in variants for c in paper.CONTROLLERS for s in scenarios
             if v is None or not v.controllers or c in v.controllers]
    return scenario_records(runs.execute(tasks, workers=workers, progress=progress, label=label, function=function))


def _scenario_one(args):
    """Worker: (scenario, controller, variant, seed) -> plain record of one engine run (picklable)."""
    scenario, controller, variant, seed = args
    result = _scenario_engine(scenario, controller, variant, seed).run()
    s = result.summary or {}
    name = variant.name if variant is not None else 'default'
    return dict(scenario=scenario, controller=controller, variant=name, name='%s_%s [%s]' % (scenario, controller, name),
                wall_s=result.info.get('wall_s'), ok=result.ok, error=result.error,
                e_mu=(s.get('estimate') or {}).get('e_mu'), e_mu_truth=(s.get('truth') or {}).get('e_mu'),
                e_max=(s.get('estimate') or {}).get('e_max'))


def scenario_runs(variants, scenarios=paper.ALL_SCENARIOS, seed=None, workers=1, progress=None, label='scenarios'):
    """The paper's scenarios (``paper.ALL_SCENARIOS``: static waypoints, Tables 3-5) on the engine, PID and MPC
    (a variant's ``controllers`` only), for every variant; {(variant, controller, scenario): record with e_mu
    (vs the estimate, the paper's metric), e_mu_truth, e_max, ok}."""
    return _per_scenario(variants, scenarios, seed, workers, progress, label, _scenario_one)


SELF_BEFORE = 1.5      # s, recorded before the measured window: >= PERIOD_OVERLAP, so that a period recurs


def _self_replay_one(args):
    """Worker: (scenario, controller, variant, seed) -> plain record of a self-replay (picklable)."""
    scenario, controller, variant, seed = args
    name = variant.name if variant is not None else 'default'
    rec = dict(scenario=scenario, controller=controller, variant=name,
               name='%s_%s [%s]' % (scenario, controller, name), ok=False, error='', period=None)
    try:
        engine = _scenario_engine(scenario, controller, variant, seed)
        result = engine.run()
        if not result.ok:
            rec['error'] = 'run: %s' % result.error
            return rec
        end = engine.evaluator.t_end * 1e-9
        log = run_log(engine, begin=engine.evaluator.t_begin * 1e-9 - SELF_BEFORE, end=end,
                      name='%s_%s' % (scenario, controller))
        latency = recorded_latency(engine, log)
        plans = (replay_plan(log), replay_plan(log, latency=latency))
        reference = reference_cells(log)
        for key, plan in zip(('ratio', 'ratio_latency'), plans):
            rep = run_replay(plan, variant, seed=seed)
            if not rep.ok:
                rec['error'] = 'replay: %s' % rep.error
                return rec
            rec[key] = dict(('%s_%s' % k, _num(v[2])) for k, v in compare(reference, rep.cells).items())
    except (ValueError, RuntimeError, KeyError) as error:
        rec['error'] = '%s: %s' % (type(error).__name__, error)
        return rec
    rec.update(ok=True, period=plans[0].period, moving=plans[0].moving, latency=_num(latency))
    rec['reference'] = dict(('%s_%s' % k, _num(reference[k])) for k in CELLS)
    return rec


def recorded_latency(engine, log):
    """How long [s] after its arrival the log (``run_log`` of ``engine``'s run) first shows each new waypoint,
    on average over the changes of its waypoint columns (what ``replay_plan``'s ``latency`` assumes for a log:
    half a sample for Sphinx's, whose logger's phase is not recorded); 0 when the log shows no change."""
    wp = log.waypoint()
    changes = [i for i in range(1, len(wp)) if np.any(wp[i] != wp[i - 1])]
    if not changes:
        return 0.0
    arrivals = waypoint_arrivals(engine)
    index = latest_waypoint(arrivals, log.time_ns[changes])
    return float(np.mean((log.time_ns[changes] - arrivals[index]) * 1e-9))


def self_replay_runs(variants, scenarios=paper.ALL_SCENARIOS, seed=None, workers=1, progress=None):
    """The replay method on the stand-in's own runs: each paper scenario run on the engine (PID and MPC, per
    variant), recorded from ``SELF_BEFORE`` s before its measured window to its end as the paper's logger
    recorded Sphinx (``run_log``), that log replayed with the same variant (``replay_plan``, ``run_replay``);
    {(variant, controller, scenario): record with ok, error, the replay's period [ticks] (None: a straight
    lead-in), the log's cells ('reference'), replay / log with the method's default waypoint latency ('ratio':
    as for Sphinx's logs, whose logger phase is unknown) and with the recording's own (``recorded_latency``:
    'ratio_latency', 'latency' [s])}. A faithful method gives ratio 1; what it gives instead is the method's own
    error on such a log."""
    return _per_scenario(variants, scenarios, seed, workers, progress, 'self-replay', _self_replay_one)


def scenario_records(records):
    """``scenario_runs``' mapping {(variant, controller, scenario): record} of a list of its records (e.g. as
    stored in benchmarks/results/fidelity.yaml)."""
    return collections.OrderedDict(((r['variant'], r['controller'], r['scenario']), r) for r in records)


def table3_runs(variants, seed=None, workers=1, progress=None):
    """The paper's straight-line scenarios (Table 3: straight_1..5, PID and MPC) on the engine for every
    variant; {(variant, controller, speed): record with e_mu (vs estimate, the paper's), e_mu_truth}."""
    return table3_from_scenarios(scenario_runs(variants, paper.STRAIGHT, seed=seed, workers=workers,
                                               progress=progress, label='table3'))


def table3_from_scenarios(records):
    """The straight-line runs of ``scenario_runs`` records keyed as ``table3_runs`` keys them:
    {(variant, controller, speed): record}."""
    return collections.OrderedDict(((v, c, int(s.rsplit('_', 1)[1])), r) for (v, c, s), r in records.items()
                                   if s in paper.STRAIGHT)


def age_name(name, age):
    """Name of ``name``'s variant with the waypoint ``age`` [s] old at the MPC's cycle: '<name>_ageNN' (ms)."""
    return '%s_age%02d' % (name, round(age * 1e3))


def age_variants(variant, ages):
    """``variant`` with the waypoint ``age`` [s] old at the MPC's cycle, one per age (engine schedule
    ``generator_phase`` against the variant's ``controller_phase``, modulo the generator's period; the ROS
    graph's phase is random per start-up): names ``age_name``, MPC only."""
    out = []
    base = dict(DEFAULT_SCHEDULE)
    base.update(variant.schedule or {})
    period = 1.0 / base['generator_rate']
    for age in ages:
        schedule = dict(variant.schedule or {})
        schedule['generator_phase'] = round((base['controller_phase'] - age) % period, 6)
        out.append(variant._replace(name=age_name(variant.name, age), label='waypoint %d ms old' % round(age * 1e3),
                                    schedule=schedule, controllers=('mpc',)))
    return out


# The position fusion's gain k is a model parameter the shared logs pin loosely: fitted on the static-waypoint
# logs alone and on the straight-line logs alone it differs by 2x (docs/calibration.md), and it sets how much of
# the steady lag builds up in a periodic motion (1/k = 3.8 s against the circles' 6-19 s periods).
FUSION_GAIN_PROBES = (0.5, 1.0)     # 1/s: gains beyond the subsets' fits, to show the trend past them
FUSION_GAIN_ROLES = ('static', 'shipped', 'straight', 'probe')   # where a gain of the table comes from


def gain_name(name, gain):
    """Name of ``name``'s variant with the fusion's fix gain ``gain`` [1/s]: '<name>_kNNNN' (gain x 1000)."""
    return '%s_k%04d' % (name, round(gain * 1000))


def fusion_gain_variants(variant, rows):
    """``variant`` with the fusion's fix gain and fix delay of each ``estimate.FusionProfileRow`` in ``rows`` (the
    delay refitted for that gain), one per row: names ``gain_name`` (ValueError when two gains share one)."""
    out = []
    for row in rows:
        model = dict(variant.model_params)
        model['estimate_position_fix_gain'] = float(row.fix_gain)
        model['estimate_position_fix_delay'] = float(row.fix_delay)
        out.append(variant._replace(name=gain_name(variant.name, row.fix_gain),
                                    label='fix gain %.3g 1/s' % row.fix_gain, model_params=model))
    names = [v.name for v in out]
    if len(set(names)) != len(names):
        raise ValueError('fusion_gain_variants: gains too close for distinct names: %s' % names)
    return out


def main_variants(off, on, timing, shipped=None):
    """The configurations of the ``replay`` and ``table3`` steps: shipped defaults, effects off / on, fusion only
    (each with the MPC's timing explicit, and with ``paper_timing`` when ``timing``), and the replay methods
    (``METHODS``: the shipped model replayed from a settled start, without the logs' estimate stalls, unrounded)."""
    fusion = effect_variants(off, on).get('position_fusion', on)
    shipped = shipped if shipped is not None else load_model_params()
    out = [Variant('shipped', 'shipped defaults', shipped)]
    out += [Variant('off', 'effects off', off), Variant('on', 'effects on', on),
            Variant('fusion', 'fusion only', fusion)]
    if timing:
        out += [Variant('off_pt', 'effects off, paper_timing', off, {'mpc': {'paper_timing': True}},
                        controllers=('mpc',)),
                Variant('on_pt', 'effects on, paper_timing', on, {'mpc': {'paper_timing': True}},
                        controllers=('mpc',)),
                Variant('fusion_pt', 'fusion only, paper_timing', fusion, {'mpc': {'paper_timing': True}},
                        controllers=('mpc',))]
        for v in out[1:4]:     # the default runs state the timing explicitly (mpc.yaml may change its default)
            out[out.index(v)] = v._replace(controller_params={'mpc': {'paper_timing': False}})
    # the same model replayed without the log's initial state: every log starts settled on its line
    out.append(Variant('settled', 'shipped, settled start', shipped, plan={'initial_state': False}))
    # the same model, the replay not holding the estimate where the log's estimate stream stalled
    out.append(Variant('nostalls', 'shipped, without the logs\' estimate stalls', shipped, plan={'stalls': False}))
    # the same runs measured without the logger's storage: the stand-in's columns unrounded
    out.append(Variant('unstored', 'shipped, unrounded columns', shipped, plan={'stored': False}))
    return out


def phase_variants(model, name, ages=AGES, latencies=(0.0, 0.05)):
    """The ``phases`` step's variants of ``model``: the waypoint ``ages`` [s] old at the MPC's cycle and the
    replay's waypoint ``latencies`` [s] (MPC only)."""
    out = age_variants(Variant(name, name, model), ages)
    for latency in latencies:
        out.append(Variant('%s_lat%02d' % (name, round(latency * 1e3)), 'latency %d ms' % round(latency * 1e3),
                             model, plan={'latency': latency}, controllers=('mpc',)))
    return out


def scenario_variants(shipped, on, timing, ages=AGES):
    """The configurations of the ``scenarios`` step: shipped defaults and effects on, each with the MPC's
    timing explicit (false / true), and the shipped ones at the ``ages`` [s] (MPC)."""
    def mpc(pt):
        return {'mpc': {'paper_timing': pt}} if timing else None
    out = [Variant('shipped', 'shipped defaults', shipped, mpc(False)),
           Variant('on', 'effects on', on, mpc(False))]
    if timing:
        out += [Variant('shipped_pt', 'shipped, paper_timing', shipped, mpc(True), controllers=('mpc',)),
                Variant('on_pt', 'effects on, paper_timing', on, mpc(True), controllers=('mpc',))]
    for v in [v for v in out if v.name in ('shipped', 'shipped_pt')]:
        out += age_variants(v, ages)
    return out
