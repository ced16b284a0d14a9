"""Calibration outputs as text (pure Python, no ROS): the model YAML, the terminal summary, the Markdown report.

Stage: offline, a ``fit.Calibration`` -> ``anafi_sim/config/anafi_model.yaml`` (``format_model_yaml``: the
template ``templates/anafi_model.yaml`` filled with ``model_context``), the console (``format_summary``) and
``docs/calibration.md`` (``format_report``: the template ``templates/calibration.md`` filled with
``report_context``). The contexts are the figures as data, which ``calibrate_model.py`` also stores
(``stored_context``) so that the texts can be rendered again without the fits (``render_model_yaml``,
``render_report``). Only formatting: every number comes from the fits in ``anafi_lab.calibration`` or, for the
figures of offline checks the texts quote, from benchmarks/results/calibration_findings.yaml (``checks``).
"""
import functools
import inspect
import math
import os

import numpy as np
import yaml

from anafi_lab.calibration import commands, estimate
from anafi_lab.calibration.drag import steady_state_pitch
from anafi_lab.paper import CONTROLLERS
from anafi_lab.calibration.effects import fit_descent
from anafi_lab.calibration.fit import MODEL_KEYS, table3
from anafi_lab.reports.calibration_plot import REPLAY_LOG
from anafi_lab.reports.render import render
from anafi_sim import paths
from anafi_sim.mission.reference_log import STATE_NAMES, WRAP_16
from anafi_sim.sim.bridge import MAX_VERTICAL_SPEED
from anafi_sim.sim.drone_model import EFFECT_GROUPS, EFFECTS_OFF

#: how the texts name the folder of the logs they were fitted on, by default the reference logs shipped with the
#: package (``paths.reference_logs_dir()``)
LOGS_LABEL = 'anafi_sim/data/reference_logs'


def _fmt(value, digits=6):
    """YAML scalar: true/false, or a float with ``digits`` significant digits that reads back as a float."""
    if isinstance(value, bool):
        return 'true' if value else 'false'
    text = '%.*g' % (digits, value)
    if not any(ch in text for ch in '.en'):      # 20 -> 20.0 (nan/inf contain 'n')
        text += '.0'
    return text


def _turn_rms(gyroscopic, controller):
    """(rms off, rms on) [rad] of the static yaw-180 log of ``controller`` in a ``GyroscopicFit`` (NaN if absent)."""
    for name, figures in gyroscopic.per_file.items():
        if 'yaw_180' in name and name.endswith('_' + controller):
            return figures[0], figures[-1]
    return (float('nan'), float('nan'))


def _mean_rms(per_series):
    """Root of the mean square over series (each series weighted equally), like the fusion fit's rms."""
    values = np.array(list(per_series.values()), dtype=float)
    return float(np.sqrt(np.mean(values ** 2))) if values.size else float('nan')


def _angle_exponent(quanta):
    """n of the 2^n deg of latitude the y position grid is (0 without a grid)."""
    step = quanta.grids['y'][0] if 'y' in quanta.grids else None
    return int(round(math.log(step / (math.radians(1.0) * EARTH_RADIUS), 2))) if step else 0


def _quantum_figures(qu, columns, unit):
    """The figures of a quantum key's comment: the grid of the positions, the power-of-two step, or none found."""
    grids = [c for c in columns if c in qu.grids]
    found = [c for c in columns if qu.steps[c] > 0.0]
    shown = grids or found or list(columns)
    return {'unit': unit, 'columns': shown, 'grid': bool(grids),
            'steps': [qu.grids[c][0] for c in grids], 'concentration': [qu.grids[c][1] for c in grids],
            'truth': [qu.grids[c][2] for c in grids] if grids else [qu.truth_on_grid[c] for c in shown],
            'on_grid': [qu.on_grid[c] for c in shown],
            'inverse_step': int(round(1.0 / qu.steps[found[0]])) if found and not grids else 0}


def _effect_figures(cal, fitted):
    """The figures of the effect keys' comments; ``fitted``: for anafi_model_fitted.yaml (the coupling to the yaw
    rate is refitted on its tilt-rate limited loop)."""
    f = cal.effects
    gy = f.gyroscopic_limited if fitted else f.gyroscopic
    tau = cal.fitted['attitude_time_constant'] if fitted else cal.params['attitude_time_constant']
    fu, de, qu, ts = f.fusion, f.descent, f.quanta, f.tilt_speed
    clean_lags = [v for name, v in f.replay.steady_lag.items() if name in fu.files]
    return {
        'fusion': {'effective_delay': fu.effective_delay, 'rms': fu.rms, 'baseline_rms': _mean_rms(fu.baseline),
                   'replayed_lag': (min(v[2] for v in clean_lags), max(v[2] for v in clean_lags)),
                   'logged_lag': (min(v[0] for v in clean_lags), max(v[0] for v in clean_lags))},
        'tilt': {'gain': 1.0 - ts.attenuation, 'speed_full': ts.speed_full, 'lowest_full': 1.0 - ts.tolerance,
                 'gains_below': [row[5] for row in ts.rows.values() if row[0] <= ts.speed + 1e-9]},
        'max_vertical_speed': MAX_VERTICAL_SPEED, 'descent_replay': [de.replay[n] for n in de.files],
        'tilt_rate': {'rate_deg': np.degrees(f.tilt_rate.rate), 'time_constant': f.tilt_rate.time_constant,
                      'first_order_rms': f.tilt_rate.first_order[1], 'rms': f.tilt_rate.rms},
        'gyroscopic': {'rms_off': gy.rms_off, 'rms': gy.rms, 'turn_mpc': _turn_rms(gy, 'mpc'),
                       'turn_pid': _turn_rms(gy, 'pid'), 'alone': gy.alone, 'limited': bool(fitted), 'tau': tau,
                       'held_from_deg': _held_from_deg(gy, tau)},
        'vertical': {'time_constant': f.vertical.time_constant, 'first_order_rms': f.vertical.first_order[1],
                     'rms': f.vertical.rms},
        'velocity_error': {'rms_zero': f.velocity_error.rms_zero, 'rms': f.velocity_error.rms},
        'yaw': dict([('spread', f.yaw.spread)] + [(c, f.yaw.by_controller.get(c)) for c in CONTROLLERS]),
        'quanta': dict(('estimate_quantum_' + key, _quantum_figures(qu, columns, unit)) for key, columns, unit in
                       (('x', ('x',), 'm'), ('y', ('y',), 'm'), ('z', ('z',), 'm'),
                        ('velocity', ('vx', 'vy', 'vz'), 'm/s'))),
        'angle_exponent': _angle_exponent(qu), 'latitude_deg': checks()['latitude_deg'],
        'float16_margin': checks()['float16_margin'], 'quantum_probe': int(round(1.0 / estimate.PROBE_STEP))}


def model_context(cal, log_names, fitted=False, logs_label=LOGS_LABEL):
    """The figures of a model YAML (``templates/anafi_model.yaml``) as YAML-safe data: the header's logs (their
    folder ``logs_label``) and effects, the values of ``MODEL_KEYS`` and the figures of their comments."""
    p = cal.fitted if fitted else cal.params
    d, e, c = cal.drag, cal.estimate, cal.commands
    figures = _effect_figures(cal, fitted)
    figures.update({
        'attitude': _first_order(c.attitude), 'yaw_rms': c.yaw.rms if c.yaw else None, 'vertical_rms': c.vertical.rms,
        'tilt_rate_rms': cal.effects.tilt_rate.rms if p.get('tilt_rate_limit', 0.0) > 0.0 else None,
        'vertical_limited_rms': (cal.effects.vertical.rms if p.get('vertical_acceleration_limit', 0.0) > 0.0
                                 else None),
        'drag_linear_stderr': d.stderr['drag_linear'], 'drag_quadratic_stderr': d.stderr['drag_quadratic'],
        'drag_rms': d.rms, 'drag_vertical_fitted': d.drag_vertical_identified and d.drag_vertical >= 0.0,
        'chain': _first_order(cal.effects.estimate_chain) if p.get('estimate_position_fusion') else None,
        'effective_delay': e.effective_delay, 'estimate_fit': _first_order(e.fit), 'change_rate': e.change_rate,
        'log_rate': e.rate, 'float16': e.float16})
    on = [name for name, keys in EFFECT_GROUPS.items() if any(p[k] != EFFECTS_OFF[k] for k in keys if k in EFFECTS_OFF)]
    return _plain({'logs_label': logs_label, 'log_names': list(log_names),
                   'excluded': [name for name, report in cal.garbage.items() if report],
                   'effects_on': on, 'values': [(key, p[key]) for key in MODEL_KEYS],
                   'off': dict((key, cal.fitted[key]) for key, off in EFFECTS_OFF.items()
                               if p[key] == off and cal.fitted[key] != off),
                   'figures': figures})


def format_model_yaml(cal, log_names, fitted=False):
    """Text of a model YAML: a date-free header naming the logs, then exactly ``MODEL_KEYS``.

    ``fitted`` False: ``cal.params`` (anafi_model.yaml, the fidelity effects as shipped); True: ``cal.fitted``
    (anafi_model_fitted.yaml, every effect on). Each effect key's comment gives its fitted value, residual and
    method, also where the effect is off.
    """
    return render_model_yaml(model_context(cal, log_names, fitted))


def format_summary(cal):
    """Short plain-text summary of the fitted parameters and residuals (for the terminal)."""
    d, e, c = cal.drag, cal.estimate, cal.commands
    out = ['Fitted parameters:']
    for key in MODEL_KEYS:
        out.append('  %-30s %s' % (key, _fmt(cal.params[key])))
    out.append('Residuals:')
    out.append('  drag (horizontal acceleration)  rms %.4f m/s^2  R^2 %.4f  (%d samples, %d logs)'
               % (d.rms, d.r2, d.n, len(d.files)))
    out.append('  estimate (pos/vel/att, static)  rms %.4f (mixed units)  R^2 %.4f' % (e.fit.rms, e.fit.r2))
    for group, fit in e.groups.items():
        out.append('    %-9s delay %.3f s  tau %.3f s  rms %.4f  R^2 %.4f'
                   % (group, fit.delay, fit.time_constant, fit.rms, fit.r2))
    out.append('  attitude (PID replay, no turns) rms %.4f rad  R^2 %.3f' % (c.attitude.rms, c.attitude.r2))
    if c.attitude_turns is not None:
        out.append('  attitude during yaw turns       rms %.4f rad  R^2 %.3f (first order; see gyroscopic coupling)'
                   % (c.attitude_turns.rms, c.attitude_turns.r2))
    out.append('  vertical speed                  rms %.4f m/s  R^2 %.4f' % (c.vertical.rms, c.vertical.r2))
    if c.yaw is not None:
        out.append('  yaw rate                        rms %.4f rad/s  R^2 %.4f' % (c.yaw.rms, c.yaw.r2))
    f = cal.effects
    out.append('Fidelity effects (fitted values: anafi_model_fitted.yaml; in anafi_model.yaml: %s):'
               % (', '.join(cal.effects_on) + ' on' if cal.effects_on else 'off'))
    for key in EFFECTS_OFF:
        out.append('  %-30s %s' % (key, _fmt(cal.fitted[key])))
    out.append('  position fusion                 rms %.4f m (delay/smoothing model %.4f m)'
               % (f.fusion.rms, _mean_rms(f.fusion.baseline)))
    out.append('  velocity error decay            T %.2f s: straight logs vx/vy error rms %.4f -> %.4f m/s'
               % (f.velocity_error.time_constant, f.velocity_error.rms_zero, f.velocity_error.rms))
    out.append('  tilt attenuation (constant, static PID logs: reported only) rms %.4f -> %.4f rad, a = %.4f'
               % (f.tilt.rms_before, f.tilt.rms, f.tilt.attenuation))
    out.append('  tilt attenuation (speed-gated)  relative gain %s at %s m/s'
               % (', '.join('%.3f' % r[5] for r in f.tilt_speed.rows.values()),
                  ', '.join('%.2f' % r[0] for r in f.tilt_speed.rows.values())))
    for name, (before, after) in f.descent.replay.items():
        if name in f.descent.files:
            out.append('  descent limit %-17s vz rms %.3f -> %.3f m/s' % (name, before, after))
    out.append('  tilt rate limit                 R %.1f deg/s, tau %.4f s: steps roll/pitch rms %.4f -> %.4f rad'
               % (np.degrees(f.tilt_rate.rate), f.tilt_rate.time_constant, f.tilt_rate.first_order[1],
                  f.tilt_rate.rms))
    out.append('  gyroscopic coupling             G %.3f s, c %.3f 1/rad, w %.3f: static steps roll/pitch rms '
               '%.4f -> %.4f rad (G alone %.4f)' % (f.gyroscopic.coupling, f.gyroscopic.authority,
                                                   f.gyroscopic.precession, f.gyroscopic.rms_off, f.gyroscopic.rms,
                                                   f.gyroscopic.alone[1]))
    out.append('  vertical acceleration limit     A %.2f m/s^2, tau %.4f s: climbs vz rms %.4f -> %.4f m/s'
               % (f.vertical.limit, f.vertical.time_constant, f.vertical.first_order[1], f.vertical.rms))
    for note in cal.notes:
        out.append('Note: ' + note)
    return '\n'.join(out)


# --------------------------------------------------------------------------- the Markdown report
CHECKS_PATH = ('benchmarks', 'results', 'calibration_findings.yaml')
"""Below the checkout: the figures the report quotes that this calibration does not compute (facts of the
reference logs read off them once, results of checks done offline once), kept as data so that the templates hold
only words."""


@functools.lru_cache(maxsize=None)
def checks():
    """The figures of ``CHECKS_PATH`` (a dict; the report's context stores a copy)."""
    with open(os.path.join(paths.checkout(), *CHECKS_PATH)) as stream:
        return yaml.safe_load(stream)


EARTH_RADIUS = 6378137.0                  # m, WGS-84 equatorial: the length of a degree of latitude / longitude
TABLE3_TOLERANCE = 0.01                   # m, the paper's last digit: a cell matches within half a unit more


STORED_DIGITS = 10
"""Significant digits of a float in the contexts (and so in benchmarks/results/calibration.yaml): more than the texts
print, fewer than the float noise of the fits reaches (last bits that move with the BLAS kernel and the summation
order), so that a calibration regenerates the stored file byte for byte."""


def _plain(value):
    """``value`` as YAML-safe data: namedtuples and dicts as dicts, tuples as lists, numpy scalars as Python, floats
    rounded to ``STORED_DIGITS`` significant digits."""
    if hasattr(value, '_asdict'):
        value = value._asdict()
    if isinstance(value, dict):
        return dict((str(k), _plain(v)) for k, v in value.items())
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, (int, np.integer)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        return float('%.*g' % (STORED_DIGITS, value))
    return value


def _garbage(report):
    """[{log, column, count, samples, reasons [(reason, count)]}] of a ``GarbageReport``."""
    return [{'log': report.name, 'column': name, 'count': info.count, 'samples': report.n_samples,
             'reasons': list(info.reasons.items())} for name, info in report.columns.items()]


def _first_order(fit):
    return None if fit is None else dict((k, getattr(fit, k)) for k in ('time_constant', 'delay', 'rms', 'r2', 'n'))


def _held_from_deg(fit, tau):
    """The yaw rate [deg/s] from which the tilt is held, 1 / (c tau) (None without authority)."""
    return float(np.degrees(1.0 / (fit.authority * tau))) if fit.authority > 0.0 else None


def _model_context(cal, logs, plot_name, logs_label):
    """The report's header, garbage, fitted parameters, notes and method constants."""
    p = cal.params
    refit = [{'key': k, 'value': p[k], 'effect': name} for name, keys in EFFECT_GROUPS.items() for k in keys
             if k not in EFFECTS_OFF and name in cal.effects_on and p[k] != cal.baseline[k]]
    window = inspect.signature(commands.fit_command_responses).parameters
    replay = inspect.signature(estimate.replay_estimate).parameters
    method = {'command_rate': inspect.signature(commands.reconstruct_pid_commands).parameters['output_rate'].default,
              'pid_cycle_rate': inspect.signature(commands.reconstruct_pid_commands).parameters['cycle_rate'].default,
              'window': window['window'].default, 'turn_rate': window['turn_rate'].default, 'lead': commands.STEP_LEAD,
              'replay_rate': replay['rate'].default, 'replay_lead': replay['lead'].default,
              'lag_min_speed': inspect.signature(estimate.lag_along_motion).parameters['min_speed'].default,
              'quantum_probe': int(round(1.0 / estimate.PROBE_STEP)),
              'saturated_for': inspect.signature(fit_descent).parameters['settle'].default}
    return {'n_logs': len(logs), 'logs_label': logs_label, 'plot_name': plot_name, 'replay_log': REPLAY_LOG,
            'garbage': [g for report in cal.garbage.values() for g in _garbage(report)],
            'wrap': {'bits': int(round(math.log(WRAP_16, 2))), 'example': checks()['wrap_example'],
                     'example_value': checks()['wrap_example'] - WRAP_16},
            'refit': refit, 'params': dict(p), 'fitted': dict(cal.fitted), 'effects_on': list(cal.effects_on),
            'effects_off': list(EFFECTS_OFF.items()), 'method': method, 'checks': checks(),
            'max_vertical_speed': MAX_VERTICAL_SPEED, 'descent_speed': cal.effects.descent.max_descent_speed,
            'notes': {'drag_vertical': not cal.drag.drag_vertical_identified or cal.drag.drag_vertical < 0.0,
                      'yaw': cal.commands.yaw is None}}


def _drag_context(cal):
    d = cal.drag
    return {'window': d.window, 'trim_pitch': d.trim_pitch, 'trim_roll': d.trim_roll, 'stderr': dict(d.stderr),
            'rms': d.rms, 'r2': d.r2, 'n': d.n, 'per_file_rms': list(d.per_file_rms.items()),
            'drag_vertical': d.drag_vertical, 'identified': d.drag_vertical_identified,
            'vertical_by_window': list(d.vertical_by_window.items()),
            'steady_tilt': [(v, steady_state_pitch(v, d.drag_linear, d.drag_quadratic)) for v in range(1, 6)]}


def _estimate_context(cal):
    e = cal.estimate
    units = {'position': 'm', 'velocity': 'm/s', 'attitude': 'rad'}
    lags = list(e.steady_position_lag.values())
    grids = cal.effects.quanta.grids
    return {'files': list(e.files), 'fit': _first_order(e.fit), 'delay': e.delay, 'time_constant': e.time_constant,
            'effective_delay': e.effective_delay, 'rate': e.rate, 'change_rate': e.change_rate,
            'change_fraction': e.change_fraction,
            'groups': [dict(_first_order(fit), name=group, unit=units.get(group, ''))
                       for group, fit in e.groups.items()],
            'lags': list(e.steady_position_lag.items()), 'lag_range': (min(lags), max(lags)) if lags else None,
            'velocity_rms': e.groups['velocity'].rms if 'velocity' in e.groups else None,
            'yaw_bias': list(e.yaw_bias.items()),
            'quanta_anafi': [e.quanta[c + '_anafi'] for c in ('z', 'vx', 'vy', 'vz')],
            'quanta_sphinx': [e.quanta[c + '_sphinx'] for c in ('z', 'vx', 'vy', 'vz')],
            'grid_x': grids['x'][0] if 'x' in grids else None, 'grid_y': grids['y'][0] if 'y' in grids else None,
            'float16': [(name, e.float16_fractions[name + '_sphinx'], e.float16_fractions[name + '_anafi'])
                        for name in STATE_NAMES]}


def _commands_context(cal):
    c = cal.commands
    loops = ('pitch', 'roll', 'vertical_speed', 'yaw_rate')
    return {'files': list(c.files), 'attitude': _first_order(c.attitude),
            'attitude_turns': _first_order(c.attitude_turns),
            'vertical': _first_order(c.vertical), 'vertical_free': _first_order(c.vertical_free),
            'yaw': _first_order(c.yaw), 'yaw_free': _first_order(c.yaw_free),
            'per_file': [(name, [rms.get(k) for k in loops]) for name, rms in c.per_file.items()]}


def _table3_context(logs):
    rows = [dict(r._asdict(), mean_e=r.mean_e if np.isfinite(r.mean_e) else None, garbage=_garbage(r.garbage))
            for r in table3(logs)]
    return {'rows': rows, 'tolerance': TABLE3_TOLERANCE,
            'off': [r for r in rows if r['mean_e'] is not None
                    and abs(r['mean_e'] - r['paper']) > TABLE3_TOLERANCE + 0.0005],
            'horizontal_only': [r for r in rows if r['mean_e'] is None]}


def _fusion_context(f):
    fu, rp = f.fusion, f.replay
    channels = ('x', 'y', 'z', 'vx', 'vy', 'vz', 'yaw')
    worse = ['%s %s' % (name, c) for name, per in rp.rms.items() for c in ('x', 'y', 'z')
             if c in per and per[c][1] > 1.1 * per[c][0] and name in fu.files]
    return {'fusion': {'fix_gain': fu.fix_gain, 'effective_delay': fu.effective_delay, 'fix_delay': fu.fix_delay,
                       'rms': fu.rms, 'baseline_rms': _mean_rms(fu.baseline), 'files': list(fu.files),
                       'groups': [(group,) + tuple(figures) for group, figures in fu.groups.items()],
                       'pure_delay': [(label,) + tuple(figures) for label, figures in fu.pure_delay.items()],
                       'common_static': fu.groups['static'][3], 'common_straight': fu.groups['straight'][3],
                       'static_rms_max': max(v for (n, a), v in fu.per_series.items() if n.startswith('static'))},
            'replay': {'lags': list(rp.steady_lag.items()) + list(rp.transient_lag.items()), 'channels': channels,
                       'rms': [(name, [per.get(c) for c in channels]) for name, per in rp.rms.items()],
                       'worse': worse, 'on_grid': list(rp.on_grid.items())},
            'estimate_chain': _first_order(f.estimate_chain)}


def _attenuation_context(f):
    ts, ti = f.tilt_speed, f.tilt
    rows = list(ts.rows.values())
    straight = list(ti.straight.items())
    return {'tilt_speed': {'attenuation': ts.attenuation, 'speed': ts.speed, 'speed_full': ts.speed_full,
                           'tolerance': ts.tolerance, 'trim': ts.trim,
                           'rows': [(name,) + tuple(row) for name, row in ts.rows.items()],
                           'bottom_speed': rows[0][0], 'top_speed': rows[-1][0], 'top_log': list(ts.rows)[-1]},
            'tilt': {'attenuation': ti.attenuation, 'rms_before': ti.rms_before, 'rms': ti.rms, 'n': ti.n,
                     'files': list(ti.files), 'joint': ti.joint, 'saturation': ti.saturation,
                     'airspeed': ti.airspeed,
                     'per_file': [(name, per['pitch'], per['roll']) for name, per in ti.per_file.items()],
                     'straight': [(name,) + tuple(v) for name, v in straight],
                     'ratio_range': (min(v[3] for _, v in straight), max(v[3] for _, v in straight)),
                     'top_speed': straight[-1][1][0], 'top_ratio': straight[-1][1][3]}}


def _loops_context(cal):
    f = cal.effects
    de, tr, ve = f.descent, f.tilt_rate, f.vertical

    def limited(fit):
        return {'first_order': fit.first_order, 'time_constant': fit.time_constant, 'rms': fit.rms,
                'all_static': fit.all_static, 'files': list(fit.files),
                'per_file': [(name,) + tuple(v) for name, v in fit.per_file.items()]}

    def coupling(fit, tau, rate_limit):
        return {'coupling': fit.coupling, 'authority': fit.authority, 'precession': fit.precession, 'rms': fit.rms,
                'rms_off': fit.rms_off, 'alone': fit.alone, 'compared': fit.compared,
                'held_from_deg': _held_from_deg(fit, tau), 'rate_limit_deg': float(np.degrees(rate_limit)),
                'per_file': list(fit.per_file.items())}

    return {'descent': {'commanded': de.commanded, 'climb': list(de.climb.values()),
                        'per_file': [(name,) + tuple(v) for name, v in de.per_file.items()],
                        'replay': list(de.replay.items())},
            'tilt_rate': dict(limited(tr), rate=tr.rate, rate_deg=float(np.degrees(tr.rate)),
                              all_static_rate_deg=float(np.degrees(tr.all_static[0]))),
            'vertical': dict(limited(ve), limit=ve.limit),
            'gyroscopic': coupling(f.gyroscopic, cal.params['attitude_time_constant'], 0.0),
            'gyroscopic_limited': coupling(f.gyroscopic_limited, cal.fitted['attitude_time_constant'],
                                           cal.fitted['tilt_rate_limit'])}


def _estimate_effects_context(f):
    ve, qu, yw = f.velocity_error, f.quanta, f.yaw
    candidates = estimate.QUANTUM_CANDIDATES
    grid = inspect.signature(estimate.estimate_grid).parameters
    exponent = _angle_exponent(qu)
    degree = math.radians(2.0 ** exponent) * EARTH_RADIUS       # m per 2^exponent deg of latitude
    return {'velocity_error': {'time_constant': ve.time_constant, 'rms': ve.rms, 'rms_zero': ve.rms_zero,
                               'window': ve.window,
                               'per_series': [(name, axis) + tuple(v) for (name, axis), v in ve.per_series.items()]},
            'yaw': {'bias': yw.bias, 'per_file': list(yw.per_file.items()),
                    'by_controller': list(yw.by_controller.items()),
                    'turn': [(name,) + tuple(v) for name, v in yw.turn.items()]},
            'quanta': {'candidates': (int(round(1.0 / max(candidates))), int(round(1.0 / min(candidates)))),
                       'hit': inspect.signature(estimate.estimate_quantum).parameters['hit'].default,
                       'storage_margin': checks()['float16_margin'], 'grid_range': estimate.GRID_RANGE,
                       'grid_hit': grid['hit'].default, 'grid_span_steps': checks()['grid_span_steps'],
                       'columns': [{'name': name, 'grid': name in qu.grids, 'on_grid': qu.on_grid[name],
                                    'inverse_step': int(round(1.0 / step)) if step else 0,
                                    'truth_on_grid': qu.truth_on_grid[name], 'samples': qu.samples[name]}
                                   for name, step in qu.steps.items()],
                       'grids': [(name,) + tuple(v) for name, v in qu.grids.items()],
                       'angle_exponent': exponent,
                       'angle_steps_m': (degree * math.cos(math.radians(checks()['latitude_deg'])), degree)}}


def report_context(cal, logs, plot_name=None, logs_label=LOGS_LABEL):
    """The figures of the Markdown report (``templates/calibration.md``) as YAML-safe data (dicts, lists, numbers,
    short labels): what ``format_report`` renders and ``calibrate_model.py`` stores beside the report."""
    context = _model_context(cal, logs, plot_name, logs_label)
    context.update(drag=_drag_context(cal), estimate=_estimate_context(cal), commands=_commands_context(cal),
                   table3=_table3_context(logs))
    effects = _fusion_context(cal.effects)
    effects.update(_attenuation_context(cal.effects))
    effects.update(_loops_context(cal))
    effects.update(_estimate_effects_context(cal.effects))
    context['effects'] = effects
    return _plain(context)


def stored_context(cal, logs, plot_name=None, logs_label=LOGS_LABEL):
    """Everything ``calibrate_model.py`` writes as text, as figures (what it stores in
    benchmarks/results/calibration.yaml): {'report': ``report_context``, 'model': ``model_context`` of
    anafi_model.yaml, 'model_fitted': of anafi_model_fitted.yaml}."""
    names = [log.name + '.csv' for log in logs]
    return {'report': report_context(cal, logs, plot_name, logs_label),
            'model': model_context(cal, names, logs_label=logs_label),
            'model_fitted': model_context(cal, names, fitted=True, logs_label=logs_label)}


def render_model_yaml(context):
    """The text of a model YAML from its ``model_context`` (e.g. read back from the stored YAML)."""
    return render('anafi_model.yaml', **context)


def format_report(cal, logs, plot_name=None, logs_label=LOGS_LABEL):
    """The Markdown calibration report (method, parameters, residuals per file, Table 3 with garbage flags)."""
    return render_report(report_context(cal, logs, plot_name, logs_label))


def render_report(context):
    """The Markdown calibration report of a ``report_context`` (e.g. read back from its stored YAML)."""
    return render('calibration.md', **context)
