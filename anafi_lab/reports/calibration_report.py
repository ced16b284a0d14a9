"""Calibration outputs as text (pure Python, no ROS): the model YAML, the terminal summary, the Markdown report.

Stage: offline, a ``fit.Calibration`` -> ``anafi_sim/config/anafi_model.yaml`` (``format_model_yaml``),
the console (``format_summary``) and ``docs/calibration.md`` (``format_report``). Only formatting: every
number comes from the fits in ``fit``.
"""
import numpy as np

from anafi_lab.calibration.drag import steady_state_pitch
from anafi_lab.calibration.estimate import GRID_RANGE
from anafi_lab.calibration.fit import MODEL_KEYS, table3
from anafi_sim.mission.reference_log import STATE_NAMES
from anafi_sim.sim.drone_model import EFFECT_GROUPS, EFFECTS_OFF

# Which keys belong to which effect (docs/calibration.md section (f)); the other effect keys are its parameters.
def _fmt(value, digits=6):
    """YAML scalar: true/false, or a float with ``digits`` significant digits that reads back as a float."""
    if isinstance(value, bool):
        return 'true' if value else 'false'
    text = '%.*g' % (digits, value)
    if not any(ch in text for ch in '.en'):      # 20 -> 20.0 (nan/inf contain 'n')
        text += '.0'
    return text


def _effect_comments(cal, fitted=False):
    """{effect key: how it was fitted and its residual} from ``cal.effects`` (the fitted values); ``fitted``: for
    anafi_model_fitted.yaml (the coupling to the yaw rate is refitted on its tilt-rate limited loop)."""
    f = cal.effects
    gy = f.gyroscopic_limited if fitted else f.gyroscopic
    loop = ('the tilt-rate limited loop\'s tau %.4f s' % cal.fitted['attitude_time_constant'] if fitted
            else 'the first order\'s tau %.4f s' % cal.params['attitude_time_constant'])
    tau = cal.fitted['attitude_time_constant'] if fitted else cal.params['attitude_time_constant']
    fu, de, qu, yw, ts = f.fusion, f.descent, f.quanta, f.yaw, f.tilt_speed
    lags = f.replay.steady_lag
    clean_lags = [v for name, v in lags.items() if name in fu.files]

    def quantum(columns):
        grids = [c for c in columns if c in qu.grids]
        if grids:
            return ('grid %s (no power of two): phase concentration %s of the estimate, %s of the truth (2^-22 deg '
                    'of longitude/latitude at ~48.8 deg)' % ('/'.join('%.5f' % qu.grids[c][0] for c in grids),
                                                            '/'.join('%.3f' % qu.grids[c][1] for c in grids),
                                                            '/'.join('%.2f' % qu.grids[c][2] for c in grids)))
        found = [c for c in columns if qu.steps[c] > 0.0]
        if not found:
            return ('none found: %s on no power-of-two grid (on 1/256: %s of the estimate, %s of the truth)'
                    % ('/'.join(columns), '/'.join('%.2f' % qu.on_grid[c] for c in columns),
                       '/'.join('%.2f' % qu.truth_on_grid[c] for c in columns)))
        return ('step 1/%d: %s of the %s estimate on it (truth: %s; where float16 is 4x finer)'
                % (round(1.0 / qu.steps[found[0]]), '/'.join('%.3f' % qu.on_grid[c] for c in found),
                   '/'.join(found), '/'.join('%.2f' % qu.truth_on_grid[c] for c in found)))

    return {
        'estimate_position_fusion': 'position = estimated velocity integrated, corrected toward the truth '
                                    'delayed by D with gain k (steady lag D x speed, lag-free transients)',
        'estimate_position_fix_delay': 's, D: effective lag %.3f s minus half a hold period; fit of the logged '
                                       'position estimate rms %.3f m (delay/smoothing model: %.3f m)'
                                       % (fu.effective_delay, fu.rms, _mean_rms(fu.baseline)),
        'estimate_position_fix_gain': '1/s, k, same fit; replayed steady lag %.3f-%.3f s (logged %.3f-%.3f s)'
                                      % (min(v[2] for v in clean_lags), max(v[2] for v in clean_lags),
                                         min(v[0] for v in clean_lags), max(v[0] for v in clean_lags)),
        'tilt_attenuation': 'a: delivered = (1 - a) x the driving part of the commanded roll/pitch above '
                            'tilt_attenuation_speed_full; '
                            'straight MPC logs: recomputed MPC command vs delivered pitch, relative to the '
                            'stand-in\'s replay: gain %.3f at %.2f m/s' % (1.0 - ts.attenuation, ts.speed_full),
        'tilt_attenuation_speed': 'm/s, v0: none below (relative gain >= %.2f up to this log\'s speed: %s)'
                                  % (1.0 - ts.tolerance, ', '.join('%.2f' % row[5] for row in ts.rows.values()
                                                                    if row[0] <= ts.speed + 1e-9)),
        'tilt_attenuation_speed_full': 'm/s, v1: the fastest log\'s speed (linear ramp v0..v1: no log in between)',
        'max_descent_speed': 'm/s, truth descent under the saturated -2 m/s command (x_straight_2/3_pid, the '
                             'only saturated descents): vz replay rms %s m/s'
                             % ', '.join('%.2f -> %.3f' % de.replay[n] for n in de.files),
        'tilt_rate_limit': 'rad/s, R: the roll/pitch loop turns the tilt at most this fast (%.1f deg/s; refits '
                           'attitude_time_constant to %.4f s); PID replay of the steps outside the turns rms %.4f -> '
                           '%.4f rad' % (np.degrees(f.tilt_rate.rate), f.tilt_rate.time_constant,
                                         f.tilt_rate.first_order[1], f.tilt_rate.rms),
        'gyroscopic_coupling': 's, G: while yawing at r the roll/pitch step is multiplied by (I - G r J)^-1 '
                               '(turned by atan(G r), slowed); fitted with the next two: static steps roll/pitch '
                               'rms %.4f -> %.4f rad (yaw-180 MPC %.4f -> %.4f, PID %.4f -> %.4f; G alone %.3f: '
                               '%.4f)' % ((gy.rms_off, gy.rms) + _turn_rms(gy, 'mpc') + _turn_rms(gy, 'pid')
                                          + tuple(gy.alone)),
        'yaw_tilt_authority': '1/rad, c: the roll/pitch loop\'s rate 1/tau reduced by c |r| (fitted with %s: the '
                              'tilt held beyond |r| = 1/(c tau) = %.0f deg/s)'
                              % (loop, np.degrees(1.0 / (gy.authority * tau) if gy.authority > 0.0 else np.inf)),
        'yaw_tilt_precession': '-, w: the tilt turns in the body frame at w r (with the yaw for w > 0)',
        'vertical_acceleration_limit': 'm/s^2, A: the vertical-speed loop ramps at most this fast (refits '
                                       'vertical_speed_time_constant to %.4f s); PID replay of the climbs rms %.4f '
                                       '-> %.4f m/s' % (f.vertical.time_constant, f.vertical.first_order[1],
                                                       f.vertical.rms),
        'estimate_velocity_error_time_constant': 's, T: the velocity estimate\'s own error decays as exp(-t/T) '
                                                 '(straight-line logs from their initial error, rms %.4f -> %.4f '
                                                 'm/s); only a replay from a logged estimate sets one'
                                                 % (f.velocity_error.rms_zero, f.velocity_error.rms),
        'estimate_yaw_bias': 'rad, median of the per-log mean yaw_anafi - yaw_sphinx (%.3f..%.3f; MPC logs %.3f, '
                             'PID logs %.3f)' % (yw.spread[0], yw.spread[1], yw.by_controller.get('mpc', np.nan),
                                                 yw.by_controller.get('pid', np.nan)),
        'estimate_quantum_x': 'm, ' + quantum(('x',)),
        'estimate_quantum_y': 'm, ' + quantum(('y',)),
        'estimate_quantum_z': 'm, ' + quantum(('z',)),
        'estimate_quantum_velocity': 'm/s, ' + quantum(('vx', 'vy', 'vz')),
    }


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


def format_model_yaml(cal, log_names, fitted=False):
    """Text of a model YAML: a date-free header naming the logs, then exactly ``MODEL_KEYS``.

    ``fitted`` False: ``cal.params`` (anafi_model.yaml, the fidelity effects as shipped); True: ``cal.fitted``
    (anafi_model_fitted.yaml, every effect on). Each effect key's comment gives its fitted value, residual and
    method, also where the effect is off.
    """
    p = cal.fitted if fitted else cal.params
    d, e, c = cal.drag, cal.estimate, cal.commands
    chain = cal.effects.estimate_chain
    excluded = [name for name, report in cal.garbage.items() if report]
    comments = {
        'gravity': 'm/s^2, fixed',
        'attitude_time_constant': 's, PID replay fit (%d samples, rms %.4f rad, R^2 %.3f)'
                                  % (c.attitude.n, c.attitude.rms, c.attitude.r2),
        'attitude_delay': 's, same fit; delays the whole piloting command',
        'yaw_rate_time_constant': 's, PID replay of the yaw turn with attitude_delay (rms %.3f rad/s)'
                                  % c.yaw.rms if c.yaw else 'not identified',
        'vertical_speed_time_constant': 's, PID replay of the climbs with attitude_delay (rms %.3f m/s)'
                                        % c.vertical.rms,
        'drag_linear': '1/s, attitude->acceleration least squares (+-%.4f, rms %.3f m/s^2)'
                       % (d.stderr['drag_linear'], d.rms),
        'drag_quadratic': '1/m, same fit (+-%.5f)' % d.stderr['drag_quadratic'],
        'drag_vertical': ('1/s, fitted' if d.drag_vertical_identified and d.drag_vertical >= 0.0
                          else '1/s, NOT identifiable: set to drag_linear (see docs/calibration.md)'),
        'estimate_delay': 's, estimate vs truth: effective lag %.3f s minus half a hold period' % e.effective_delay,
        'estimate_time_constant': 's, same fit (rms %.4f, R^2 %.4f)' % (e.fit.rms, e.fit.r2),
        'estimate_rate': 'Hz, values change at %.1f Hz in the %.0f Hz logs (cannot show more)'
                         % (e.change_rate, e.rate),
        'estimate_float16': 'all logged columns incl. ground truth are float16: log storage, not the estimate'
                            if not e.float16 else 'only the estimate columns are float16-quantised',
    }
    if p.get('estimate_position_fusion'):     # the position has its own model: delay/smoothing of the rest
        comments['estimate_delay'] = ('s, velocity/roll/pitch estimate vs truth (static logs; the position has the '
                                      'fusion): effective lag %.3f s minus half a hold period' % chain.delay)
        comments['estimate_time_constant'] = 's, same fit (rms %.4f, R^2 %.4f)' % (chain.rms, chain.r2)
    if p.get('tilt_rate_limit', 0.0) > 0.0:               # the small-signal lag of the limited loop
        comments['attitude_time_constant'] = ('s, with tilt_rate_limit: PID replay of the steps outside the turns '
                                              '(rms %.4f rad)' % cal.effects.tilt_rate.rms)
    if p.get('vertical_acceleration_limit', 0.0) > 0.0:   # the small-signal lag of the limited loop
        comments['vertical_speed_time_constant'] = ('s, with vertical_acceleration_limit: PID replay of the climbs '
                                                    'with attitude_delay (rms %.3f m/s)' % cal.effects.vertical.rms)
    effects = _effect_comments(cal, fitted)
    for key, off in EFFECTS_OFF.items():
        if p[key] == off and cal.fitted[key] != off:
            comments[key] = 'OFF (fitted: %s in anafi_model_fitted.yaml; %s)' % (_fmt(cal.fitted[key]), effects[key])
        else:
            comments[key] = effects[key]
    on = [name for name, keys in EFFECT_GROUPS.items() if any(p[k] != EFFECTS_OFF[k] for k in keys if k in EFFECTS_OFF)]
    lines = ['# Parameters of the simulated Anafi (anafi_sim/sim/drone_model.py, anafi_sim/sim/state_estimate.py).',
             '# Generated by anafi_lab/cli/calibrate_model.py - do not edit by hand, rerun the script.',
             '# Fitted on the reference logs (shared/reference_logs): %s.' % ', '.join(log_names)]
    if excluded:
        lines.append('# Logs with garbage samples, excluded from the fits: %s.' % ', '.join(excluded))
    lines.append('# Fidelity effects on: %s.' % (', '.join(on) if on else 'none (anafi_model_fitted.yaml has '
                                                                      'every fitted one on)'))
    lines.append('# Method, residuals and what is not identified: docs/calibration.md. SI units.')
    for key in MODEL_KEYS:
        lines.append('%s: %s  # %s' % (key, _fmt(p[key]), comments[key]))
    return '\n'.join(lines) + '\n'


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


def format_report(cal, logs, plot_name=None, logs_label='shared/reference_logs'):
    """The Markdown calibration report (method, parameters, residuals per file, Table 3 with garbage flags)."""
    d, e, c = cal.drag, cal.estimate, cal.commands
    p = cal.params
    L = []
    add = L.append
    add('# Calibration of the simulated Anafi')
    add('')
    add('Generated by `anafi_lab/cli/calibrate_model.py` from the %d reference logs in `%s` '
        '(the paper\'s Sphinx runs, see its README); rerun the script to regenerate this file, '
        '`anafi_sim/config/anafi_model.yaml` and the figure. Model equations: `anafi_lab/calibration/fit.py` '
        'module docstring (they are those of `anafi_sim/sim/drone_model.py`).' % (len(logs), logs_label))
    add('')
    add('## Data quality (garbage detection)')
    add('')
    flagged = [(name, r) for name, r in cal.garbage.items() if r]
    if flagged:
        for name, report in flagged:
            for line in report.summary():
                add('- `%s`' % line)
        add('')
        add('A 16-bit wrap means a value that is plausible once 2^16 is subtracted (z_anafi = 65280 is -256 m). '
            'In the reference logs the truth shows the drone more than 100 m below the ground, descending under '
            'the saturated descent command the PID computes from such an altitude. Files with garbage are '
            'excluded from every fit; the tracking error excludes the garbage samples (3-D) and stays valid '
            'horizontally.')
    else:
        add('No garbage found.')
    add('')
    add('## Fitted parameters')
    add('')
    refit = [(k, name) for name, keys in EFFECT_GROUPS.items() for k in keys
             if k not in EFFECTS_OFF and name in cal.effects_on and p[k] != cal.baseline[k]]
    if refit:
        add('Values of the plain model (effects off); refitted with an effect shipped on in anafi_model.yaml: %s '
            '(section (f)).' % ', '.join('%s %s (%s)' % (k, _fmt(p[k], 4), name) for k, name in refit))
        add('')
    add('| key | value | how | quality |')
    add('|---|---|---|---|')
    add('| gravity | %s | fixed | - |' % _fmt(p['gravity']))
    add('| attitude_time_constant | %.4f s | first order + delay, PID command replay -> truth roll/pitch '
        '(static-waypoint PID logs, yaw turns excluded) | rms %.4f rad, R^2 %.3f, %d samples |'
        % (c.attitude.time_constant, c.attitude.rms, c.attitude.r2, c.attitude.n))
    add('| attitude_delay | %.4f s | same fit (includes bridge/transport latency after our 10 Hz command) '
        '| as above |' % p['attitude_delay'])
    if c.yaw is not None:
        add('| yaw_rate_time_constant | %.4f s | PID replay of the 180 deg turn, delay fixed to attitude_delay '
            '| rms %.4f rad/s, R^2 %.3f (own delay: tau %.3f s, delay %.3f s, rms %.4f) |'
            % (p['yaw_rate_time_constant'], c.yaw.rms, c.yaw.r2, c.yaw_free.time_constant, c.yaw_free.delay,
               c.yaw_free.rms))
    add('| vertical_speed_time_constant | %.4f s | PID replay of the 1 m -> 5 m climbs, delay fixed to '
        'attitude_delay | rms %.4f m/s, R^2 %.4f (own delay: tau %.3f s, delay %.3f s) |'
        % (c.vertical.time_constant, c.vertical.rms, c.vertical.r2, c.vertical_free.time_constant,
           c.vertical_free.delay))
    add('| drag_linear | %.4f 1/s | linear least squares of truth horizontal acceleration on attitude, '
        'velocity (all clean logs, both axes) | +-%.4f; rms %.4f m/s^2, R^2 %.4f, %d samples |'
        % (p['drag_linear'], d.stderr['drag_linear'], d.rms, d.r2, d.n))
    add('| drag_quadratic | %.5f 1/m | same fit | +-%.5f |' % (p['drag_quadratic'], d.stderr['drag_quadratic']))
    add('| drag_vertical | %.4f 1/s | %s | fitted %.3f +-%.3f, varies with smoothing: %s |'
        % (p['drag_vertical'], 'same fit' if d.drag_vertical_identified else
           '**not identifiable**, set to drag_linear (isotropy assumption)', d.drag_vertical,
           d.stderr['drag_vertical'], ', '.join('w%d: %.3f' % kv for kv in d.vertical_by_window.items())))
    add('| estimate_delay | %.4f s | estimate vs truth, first order + delay, static-waypoint logs, '
        'pos/vel/roll/pitch jointly; effective lag %.4f s minus 1/(2 rate) for the model\'s hold | '
        'rms %.4f (residuals scaled per channel), R^2 %.4f |' % (e.delay, e.effective_delay,
                                                                e.fit.rms, e.fit.r2))
    add('| estimate_time_constant | %.4f s | same fit | as above |' % e.time_constant)
    add('| estimate_rate | %.1f Hz | values change at %.1f Hz (%.1f %% of the samples where the truth moved) '
        'in %.0f Hz logs: the rate is at least the log rate, which is all the logs can show | - |'
        % (p['estimate_rate'], e.change_rate, 100.0 * e.change_fraction, e.rate))
    add('| estimate_float16 | %s | float16 round trip of every column (table below) | - |'
        % _fmt(p['estimate_float16']))
    add('')
    add('## (a) Attitude -> acceleration, drag')
    add('')
    add('Model: a_h = T z_h - (drag_linear + drag_quadratic |v_h|) v_h with T z_z = a_z + g + drag_vertical v_z '
        '(the thrust the vertical loop needs), z = body z axis of the logged truth attitude, a = Savitzky-Golay '
        'derivative (window %d samples, quadratic) of the truth velocity; the regressors are smoothed by the '
        'same filter. Two nuisance parameters absorb a constant trim of the thrust axis against the logged '
        'attitude (the drone hovers at pitch %.4f rad, yaw-independent): trim pitch %.5f +-%.5f rad, '
        'trim roll %.5f +-%.5f rad (not model keys: the closed loops absorb it).'
        % (d.window, -d.trim_pitch, d.trim_pitch, d.stderr['trim_pitch'], d.trim_roll, d.stderr['trim_roll']))
    add('')
    add('| log | rms [m/s^2] |')
    add('|---|---|')
    for name, rms in d.per_file_rms.items():
        add('| %s | %.4f |' % (name, rms))
    add('')
    add('Steady straight flight (level, no trim) needs tilt = atan((drag_linear + drag_quadratic v) v / g): '
        + ', '.join('%d m/s: %.4f rad' % (v, steady_state_pitch(v, d.drag_linear, d.drag_quadratic))
                    for v in range(1, 6)) + '.')
    add('')
    add('## (b) State estimate vs ground truth')
    add('')
    add('Fit: estimate = first order (tau) of the truth delayed by d, with a free offset per file and channel '
        '(estimate bias), on the static-waypoint logs (%s); each residual scaled by the per-sample change of '
        'the truth. The straight-line logs hardly move except along x, where a lag and a position bias are '
        'indistinguishable.' % ', '.join(e.files))
    add('')
    add('| channels | delay [s] | tau [s] | rms | R^2 |')
    add('|---|---|---|---|---|')
    add('| all (joint, used) | %.4f | %.4f | %.4f | %.4f |' % (e.fit.delay, e.fit.time_constant, e.fit.rms,
                                                             e.fit.r2))
    units = {'position': 'm', 'velocity': 'm/s', 'attitude': 'rad'}
    for group, fit in e.groups.items():
        add('| %s | %.4f | %.4f | %.4f %s | %.4f |' % (group, fit.delay, fit.time_constant, fit.rms,
                                                      units.get(group, ''), fit.r2))
    add('')
    add('Findings the delay/smoothing model does not represent (modelled as switchable effects, section (f)):')
    add('')
    add('- At constant speed the *position* estimate trails the truth by a lag of %s s times the speed '
        '(straight-line logs: %s), while velocity and attitude show the ~%.2f s lag above and the transients '
        'of the static runs show no such position lag. Consistent with a position estimate that fuses a '
        'delayed absolute fix; the paper\'s e (on the estimate) includes it, the truth is ahead by that much.'
        % ('%.2f-%.2f' % (min(e.steady_position_lag.values()), max(e.steady_position_lag.values()))
           if e.steady_position_lag else '?',
           ', '.join('%s %.3f' % kv for kv in e.steady_position_lag.items()), e.effective_delay))
    add('- Velocity residuals (rms %.3f m/s) are largest at the peaks of the transients, where the logged '
        'estimate reads lower than the truth (see the figure); a delay/smoothing model does not capture that.'
        % e.groups['velocity'].rms if 'velocity' in e.groups else '- (no velocity fit)')
    add('- Yaw estimate bias (mean yaw_anafi - yaw_sphinx): ' +
        ', '.join('%s %.3f rad' % kv for kv in e.yaw_bias.items()) + '.')
    add('- Quantisation of the estimate: the fraction of values on a 1/256 grid is %s for z/vx/vy/vz_anafi '
        'vs %s for the truth columns: altitude [m] and velocities [m/s] of the estimate come in steps of '
        '1/256; the horizontal position near the origin comes in steps of ~0.017 m (x) and ~0.027 m (y).'
        % ('/'.join('%.2f' % e.quanta[c] for c in ('z_anafi', 'vx_anafi', 'vy_anafi', 'vz_anafi')),
           '/'.join('%.2f' % e.quanta[c] for c in ('z_sphinx', 'vx_sphinx', 'vy_sphinx', 'vz_sphinx'))))
    add('')
    add('float16 round trip (fraction of values that are the shortest repr of a half float):')
    add('')
    add('| column | sphinx | anafi |')
    add('|---|---|---|')
    for name in STATE_NAMES:
        add('| %s | %.3f | %.3f |' % (name, e.float16_fractions[name + '_sphinx'],
                                      e.float16_fractions[name + '_anafi']))
    add('')
    add('Every column of every log (truth and waypoint included) is float16: the logger stored half floats, '
        'so the quantisation says nothing about the estimate itself -> estimate_float16: %s.'
        % _fmt(p['estimate_float16']))
    add('')
    add('## (c-e) Firmware loops from PID command replays')
    add('')
    add('The commands are not logged. `reconstruct_pid_commands` replays the paper\'s PID framework '
        '(`anafi_control/pid_framework.py`, Table 2 gains, pid-package filters) at 30 Hz on the logged '
        'estimate and waypoint from the waypoint step on, samples it at 10 Hz and quantises it to PCMD percents '
        '(`anafi_sim/sim/bridge.py`). First order + delay fits of truth roll/pitch, vertical speed and yaw rate '
        '(Savitzky-Golay derivative of the truth yaw) to those setpoints, from 0.5 s before to 20 s after the '
        'step, on %s. The MPC logs are not used here (its commands cannot be reconstructed yet).'
        % ', '.join(c.files))
    add('')
    add('| loop | tau [s] | delay [s] | rms | R^2 |')
    add('|---|---|---|---|---|')
    add('| roll/pitch (yaw turns excluded) | %.4f | %.4f | %.4f rad | %.3f |'
        % (c.attitude.time_constant, c.attitude.delay, c.attitude.rms, c.attitude.r2))
    if c.attitude_turns is not None:
        add('| roll/pitch during the yaw turn (same tau, delay) | %.4f | %.4f | %.4f rad | %.3f |'
            % (c.attitude_turns.time_constant, c.attitude_turns.delay, c.attitude_turns.rms,
               c.attitude_turns.r2))
    add('| vertical speed (delay = attitude_delay) | %.4f | %.4f | %.4f m/s | %.4f |'
        % (c.vertical.time_constant, c.vertical.delay, c.vertical.rms, c.vertical.r2))
    add('| vertical speed (own delay) | %.4f | %.4f | %.4f m/s | %.4f |'
        % (c.vertical_free.time_constant, c.vertical_free.delay, c.vertical_free.rms, c.vertical_free.r2))
    if c.yaw is not None:
        add('| yaw rate (delay = attitude_delay) | %.4f | %.4f | %.4f rad/s | %.4f |'
            % (c.yaw.time_constant, c.yaw.delay, c.yaw.rms, c.yaw.r2))
        add('| yaw rate (own delay) | %.4f | %.4f | %.4f rad/s | %.4f |'
            % (c.yaw_free.time_constant, c.yaw_free.delay, c.yaw_free.rms, c.yaw_free.r2))
    add('')
    add('Per file rms of the used fits:')
    add('')
    add('| log | pitch [rad] | roll [rad] | vertical speed [m/s] | yaw rate [rad/s] |')
    add('|---|---|---|---|---|')
    for name, rms in c.per_file.items():
        add('| %s | %s |' % (name, ' | '.join('%.4f' % rms[k] if k in rms else '-'
                                               for k in ('pitch', 'roll', 'vertical_speed', 'yaw_rate'))))
    add('')
    add('Limits of these fits: the delay contains the unknown phase of the reference 10 Hz command stream and '
        'the logger\'s timing (20 Hz samples); the vertical speed shows a fast rise to ~94 % of the command '
        'then a slow creep that one time constant averages; during the 180 deg turn the measured roll/pitch '
        'do not follow the replayed command the way a first-order loop would (rms above): that coupling is the '
        'gyroscopic coupling of the effects below (attitude: coupling to the yaw rate), not this first order\'s '
        '(the measured tilt turns with the body, ~27 deg along its nose at 100 deg/s of yaw, where '
        'the replayed command already points back at the waypoint; ruled out offline, rms of roll/pitch in the '
        'turns of both yaw-180 logs: a stability-frame rotation of the controllers with the opposite yaw sign or '
        'none, 0.35-0.37 rad against 0.16-0.18 rad; the command held as a world-frame tilt, 0.18 rad; a tilt '
        'rate limit of 50-120 deg/s, 0.17 rad; the tilt applied in the frame of the integrated yaw-rate '
        'setpoint, either sign, 0.17-0.19 rad); in the two garbage logs the drone descended at ~1.5 m/s under a saturated -2 m/s '
        'command (modelled as max_descent_speed, section (f)). Refit once the project\'s controllers fly the same '
        'waypoints in closed loop (issue 2: "attitude response from closed-loop replays").')
    add('')
    L.extend(format_effects(cal))
    add('## Table 3 recomputed (mean tracking error e = |wp - p_anafi| [m])')
    add('')
    add('| controller | speed [m/s] | paper | e (3-D) | e horizontal | garbage |')
    add('|---|---|---|---|---|---|')
    rows = table3(logs)
    for row in rows:
        garbage = '; '.join(row.garbage.summary()) if row.garbage else '-'
        e3 = 'n/a (all %d samples excluded)' % row.n_excluded if not np.isfinite(row.mean_e) else '%.3f' % row.mean_e
        add('| %s | %d | %.2f | %s | %.3f | %s |' % (row.controller.upper(), row.speed, row.paper, e3,
                                                     row.mean_e_h, garbage))
    add('')
    off = ['%s %d m/s (%.3f vs %.2f)' % (r.controller.upper(), r.speed, r.mean_e, r.paper) for r in rows
           if np.isfinite(r.mean_e) and abs(r.mean_e - r.paper) > 0.0105]
    add('The 3-D values match the paper to 0.01 m%s. For the files with garbage only the horizontal error is '
        'meaningful: %s.' % ((' except ' + ', '.join(off)) if off else '',
                            ', '.join('%s %d m/s %.3f (paper %.2f)' % (r.controller.upper(), r.speed, r.mean_e_h,
                                                                       r.paper)
                                      for r in rows if not np.isfinite(r.mean_e)) or 'none'))
    add('')
    if plot_name:
        add('## Replay figure')
        add('')
        add('![model replaying a reference log](%s)' % plot_name)
        add('')
        add('Top: static_waypoint_yaw_0_pid replayed by the fitted translational model fed the logged truth '
            'attitude (plus trim) and the model\'s vertical loop fed the reconstructed PID vertical command; '
            'steady straight-flight tilt vs speed with the fitted drag. Middle: firmware loops (first order + '
            'delay) fed the reconstructed PID commands. Bottom: the fitted estimate model applied to the truth '
            'vs the logged estimate; Table 3 paper vs recomputed.')
        add('')
    if cal.notes:
        add('## Notes')
        add('')
        for note in cal.notes:
            add('- ' + note)
        add('')
    return '\n'.join(L)


def _without_with_table(per_log, without, with_, number):
    """Markdown rows: per log (``per_log`` {log: (without, with, ...)}) its figures, formatted with ``number``,
    under the headers ``without`` and ``with_`` (a string, or a tuple of headers for the figures after the
    first)."""
    heads = (without,) + ((with_,) if isinstance(with_, str) else tuple(with_))
    rows = ['| log | %s |' % ' | '.join(heads), '|---' * (len(heads) + 1) + '|']
    for name, figures in per_log.items():
        rows.append('| %s | %s |' % (name, ' | '.join(number % v for v in figures)))
    return rows


def _limited_loop_table(fit, limit_text):
    """Markdown rows: per static log the rms of section (c)'s first order and of the limited loop (a
    ``fit.TiltRateFit`` / ``fit.VerticalLimitFit``); the logs not in the fit marked as checks."""
    rows = ['| log | first order (tau %.4f s) | limited (%s, tau %.4f s) |' % (fit.first_order[0], limit_text,
                                                                             fit.time_constant),
            '|---|---|---|']
    for name, (before, after) in fit.per_file.items():
        rows.append('| %s%s | %.4f | %.4f |' % (name, '' if name in fit.files else ' (check)', before, after))
    return rows


def format_effects(cal):
    """Markdown lines of the report's section (f): every fidelity effect, its fit, residuals and limits."""
    f = cal.effects
    fu, ti, de, qu, yw, rp = f.fusion, f.tilt, f.descent, f.quanta, f.yaw, f.replay
    L = []
    add = L.append
    add('## (f) Fidelity effects (switchable model keys)')
    add('')
    add('Each effect has keys whose "off" values (`EFFECTS_OFF` in `anafi_sim/sim/drone_model.py`) give the model '
        'above bit for bit. `anafi_sim/config/anafi_model_fitted.yaml` has every fitted effect on; '
        '`anafi_model.yaml` has **%s** on (`SHIPPED_EFFECTS` in `anafi_lab/calibration/fit.py`, chosen by the '
        'closed-loop replay in docs/fidelity.md: edit it and rerun the script to change that). The simulator loads the fitted file with `~model_file:=%s` '
        '(`sim.launch model_file:=...`). With the fusion on, estimate_delay and estimate_time_constant are '
        'refitted on velocity, roll and pitch alone (the position has its own model): %.4f s and %.4f s '
        '(rms %.4f, R^2 %.4f).' % (', '.join(cal.effects_on) if cal.effects_on else 'none', 'anafi_model_fitted.yaml',
                                   cal.fitted['estimate_delay'], cal.fitted['estimate_time_constant'],
                                   f.estimate_chain.rms, f.estimate_chain.r2))
    add('')
    add('| key | fitted (anafi_model_fitted.yaml) | off | anafi_model.yaml |')
    add('|---|---|---|---|')
    for key, off in EFFECTS_OFF.items():
        add('| %s | %s | %s | %s |' % (key, _fmt(cal.fitted[key]), _fmt(off), _fmt(cal.params[key])))
    add('')

    add('### Position estimate: fusion of the velocity with a delayed fix')
    add('')
    add('Model (`StateEstimate`): p\' = v_est + k (p_truth(t - D) - p), v_est the modelled velocity estimate. In '
        'steady flight the position trails the truth by D x speed (plus the hold); a manoeuvre shorter than 1/k '
        '= %.1f s does not build that lag up. Fit: the logged velocity estimate integrated and corrected toward '
        'the delayed truth, started at the logged position estimate, against the logged position estimate; x '
        'and y of every clean log, z of the static-waypoint logs only (the straight flights are level); (k, D) '
        'common (Nelder-Mead from a grid); every series weighted equally. Result: k = %.4f 1/s, effective '
        'D = %.4f s (model D = %.4f s after half a hold period), rms %.4f m; the delay/smoothing model gave %.4f m '
        'on the same series.' % (1.0 / fu.fix_gain, fu.fix_gain, fu.effective_delay, fu.fix_delay, fu.rms,
                                 _mean_rms(fu.baseline)))
    add('')
    add('Does one structure explain both the steady lag and the lag-free transients? Fits on subsets, and the '
        'rms each subset gets with the common (k, D):')
    add('')
    add('| subset | k [1/s] | effective D [s] | rms own fit [m] | rms common fit [m] |')
    add('|---|---|---|---|---|')
    for group, (k, d, own, common) in fu.groups.items():
        add('| %s | %.4f | %.4f | %.4f | %.4f |' % (group, k, d, own, common))
    add('')
    add('A pure delay of the truth cannot do both:')
    add('')
    add('| position = truth delayed by | delay [s] | rms static transients [m] | rms steady flight [m] |')
    add('|---|---|---|---|')
    for label, (delay, rms_static, rms_straight) in fu.pure_delay.items():
        add('| %s | %.4f | %.4f | %.4f |' % (label, delay, rms_static, rms_straight))
    add('| (the fusion, common fit) | - | %.4f | %.4f |' % (fu.groups['static'][3], fu.groups['straight'][3]))
    add('')
    add('Separate horizontal/vertical gains change the rms by less than the table shows between "own" and '
        '"common"; a delay growing with speed and an extra velocity-bias state (p\' = v + b + k1 e, b\' = k2 e) '
        'were tried offline and fitted to a negligible speed term and k2 ~ 0 (rms gain < 1 %), so the single '
        '(k, D) is kept. The static transients alone prefer a shorter delay (table): the residual left is '
        'mostly there.')
    add('')
    add('Open-loop replay of the simulator\'s `StateEstimate` fed the logged truth at 200 Hz (after 20 s of '
        'steady flight at the first sample\'s velocity), lag along the motion (least squares of truth - estimate '
        'on the velocity, |v| > 0.5 m/s) [s]:')
    add('')
    add('| log | logged | effects off | effects on |')
    add('|---|---|---|---|')
    for name, lags in list(rp.steady_lag.items()) + list(rp.transient_lag.items()):
        flag = '' if name in fu.files else ' (garbage z: x lag meaningless)'
        add('| %s%s | %.3f | %.3f | %.3f |' % (name, flag, lags[0], lags[1], lags[2]))
    add('')
    add('Per log rms of the replayed estimate against the logged one (effects off -> on; position [m], velocity '
        '[m/s], yaw [rad]):')
    add('')
    channels = ('x', 'y', 'z', 'vx', 'vy', 'vz', 'yaw')
    add('| log | %s |' % ' | '.join(channels))
    add('|---|%s' % ('---|' * len(channels)))
    worse = []
    for name, per in rp.rms.items():
        cells = []
        for c in channels:
            if c in per:
                cells.append('%.3f -> %.3f' % per[c])
                if c in ('x', 'y', 'z') and per[c][1] > 1.1 * per[c][0] and name in fu.files:
                    worse.append('%s %s' % (name, c))
            else:
                cells.append('garbage')
        add('| %s | %s |' % (name, ' | '.join(cells)))
    add('')
    add('Not captured: %s. There the replay integrates the *modelled* velocity estimate for ~1/k s, and the '
        'logged position estimate of these short static runs drifts from the truth by more than the fusion '
        'explains (the fit, which integrates the logged velocity, has per-series rms up to %.3f m on them). The '
        'remaining residual is the logged velocity estimate\'s own error, which the delay/smoothing velocity '
        'model does not reproduce (section (b)); fitting (k, D) with the modelled velocity estimate instead (what '
        'the simulator integrates) was tried offline: a gain about half as large and a residual only a few '
        'per cent lower, so the fit keeps the velocity the firmware integrates.'
        % (', '.join(worse) if worse else 'nothing worse than before',
           max(v for (n, a), v in fu.per_series.items() if n.startswith('static'))))
    add('')

    ve = f.velocity_error
    add('### Velocity estimate: an error of its own that decays')
    add('')
    add('The straight-line logs start with a velocity estimate that is off the truth across the motion (up to '
        '0.1 m/s) and comes back to it over ~10 s; integrated by the fusion, that error holds the position '
        'estimate off to the side (Sphinx\'s MPC lines fly 4-12 cm left of the line in ground truth at their '
        'start). Model (`StateEstimate`, `estimate_velocity_error_time_constant` T): an error b added to the '
        'velocity estimate, b\' = -b / T; nothing in the model creates it (the logs do not show what did: the '
        'approach before each line is not logged), a replay sets it from the log (docs/fidelity.md). Fit: '
        'b = v_anafi - v_sphinx of every clean straight-line log, x and y, against b0 exp(-t / T), b0 the '
        'error at log time 0 (a line through the first %g s), common T: **T = %.2f s**, rms %.4f m/s (b = 0: '
        '%.4f m/s). Per log and axis, b0 [m/s] and rms without -> with the decay [m/s]:'
        % (ve.window, ve.time_constant, ve.rms, ve.rms_zero))
    add('')
    add('| log | axis | b0 | rms b = 0 -> decay |')
    add('|---|---|---|---|')
    for (name, axis), (b0, zero, fit) in ve.per_series.items():
        add('| %s | %s | %.3f | %.4f -> %.4f |' % (name, axis, b0, zero, fit))
    add('')
    add('What the logs cannot identify: what creates the error (an acceleration, a turn, a heading error: the '
        'approach is not in the logs) and its shape beyond one exponential (the larger errors decay slowly at '
        'first, then faster: x_straight_4_pid y); a velocity bias driven by the position error (b\' = k2 (fix - '
        'p), the classic second state of such a filter) was checked once offline and rejected (figures of that '
        'check, 2026-11-25, not recomputed by this script): a regression of the change of b on the integral of '
        'that error gives k2 ~ 0.07-0.09 1/s^2 on the logs with the largest b, which would leave about k2 x D x '
        '5 m ~ 0.09 m/s of velocity error after each 5 m step of the static logs (during a short move the fused '
        'position leads the fix by D x speed), where their velocity estimate is within ~0.02 m/s of the truth '
        'a few seconds after the step.')
    add('')

    add('### Tilt attenuation')
    add('')
    ts = f.tilt_speed
    add('Model: above a horizontal speed the firmware delivers less roll/pitch than commanded, as a speed '
        'governor: of the part of the commanded tilt that drives the drone along its velocity it delivers '
        '(1 - a r), r = clip((|v| - v0) / (v1 - v0), 0, 1), |v| the true horizontal speed when the PCMD arrives; '
        'a braking or sideways tilt is delivered whole (before the max-tilt clamp; the hover brake is not '
        'attenuated; `drone_model.delivered_tilt`). Fitted: a = %.4f, v0 = %.2f m/s, v1 = %.2f m/s.'
        % (ts.attenuation, ts.speed, ts.speed_full))
    add('')
    add('Fit (`fit_tilt_attenuation_speed`): with eq. (15) the paper\'s MPC command is a function of the '
        'estimate and the waypoint alone, so it is recomputed on each straight-line MPC log (10 Hz, PCMD '
        'percents); its steady mean is set against the mean delivered pitch (+ the drag fit\'s trim %.5f rad). '
        'The recomputation has a bias of its own (the 10 Hz waypoint\'s sawtooth at the log\'s sample phase: '
        'on the stand-in, which delivers exactly the command, it reads 0.91-1.02), so the same is done on the '
        'stand-in\'s closed-loop replay of the log (the shipped model without the attenuation) and the ratio '
        'of the two is the firmware\'s gain relative to the stand-in:' % ts.trim)
    add('')
    add('| log | speed [m/s] | Sphinx commanded [rad] | Sphinx delivered + trim [rad] | stand-in commanded [rad] '
        '| stand-in delivered [rad] | relative gain |')
    add('|---|---|---|---|---|---|---|')
    for name, row in ts.rows.items():
        add('| %s | %.2f | %.4f | %.4f | %.4f | %.4f | %.3f |' % ((name,) + tuple(row)))
    add('')
    add('Up to %.2f m/s the relative gain is within %.0f %% of 1 (above it at 1 m/s, where the trim is as large '
        'as the tilt); at %.2f m/s it is %.3f. v1 = the fastest log\'s speed, a = 1 - its gain, v0 = the '
        'fastest slower log within the tolerance. The logs have no speed between v0 and v1 nor above v1: the '
        'linear ramp between them and the constant fraction above are assumptions, and so is the speed being '
        'the ground speed (the logs have no wind to tell it from the airspeed) and braking and sideways tilt '
        'being delivered whole (the logs show steady fast flight only). The 5 m/s cells are the '
        'check: with it the stand-in\'s ground-truth error of x_straight_5_mpc, which the fit does not use, '
        'moves from about 0.5x to about 1.1x of Sphinx\'s (docs/fidelity.md).'
        % (ts.speed, 100.0 * ts.tolerance, ts.speed_full, 1.0 - ts.attenuation))
    add('')
    add('A constant attenuation fitted on the static PID logs instead (PID command replays of %s, a least '
        'squares with the attitude loop\'s time constant and delay fixed) gives a = %.4f, rms %.4f -> %.4f rad '
        '(%d samples), but in closed loop it makes the 1-4 m/s MPC lines 13-17 %% worse than Sphinx and the '
        'straight logs above show no attenuation there; it is reported, not used.'
        % (', '.join(ti.files), ti.attenuation, ti.rms_before, ti.rms, ti.n))
    add('')
    add('| log | pitch rms off -> on [rad] | roll rms off -> on [rad] |')
    add('|---|---|---|')
    for name, per in ti.per_file.items():
        add('| %s | %.4f -> %.4f | %.4f -> %.4f |' % ((name,) + per['pitch'] + per['roll']))
    add('')
    add('Alternatives on the same static data (each with the loop\'s tau and delay refitted): constant '
        'attenuation a = %.4f (tau %.3f s, delay %.3f s) rms %.4f rad; saturation S tanh(u / S) with S = %.3f '
        'rad rms %.4f rad; airspeed-dependent u / (1 + c |v|) with c = %.3f s/m rms %.4f rad. The static runs '
        'reach only a few m/s, so they cannot tell these apart.'
        % (ti.joint[2], ti.joint[0], ti.joint[1], ti.joint[3], ti.saturation[0], ti.saturation[1],
           ti.airspeed[0], ti.airspeed[1]))
    add('')
    add('Check on the straight-line PID logs (steady means; the replayed PID command there depends on the '
        'waypoint timing, so this is a check, not a fit):')
    add('')
    add('| log | speed [m/s] | commanded pitch [rad] | delivered - trim [rad] | ratio |')
    add('|---|---|---|---|---|')
    for name, (speed, commanded, delivered, ratio) in ti.straight.items():
        add('| %s | %.2f | %.4f | %.4f | %.2f |' % (name, speed, commanded, delivered, ratio))
    add('')
    add('The PID ratios scatter (0.8-1.2) without a trend the logs could resolve; the 5 m/s one is below 1, as '
        'the model says.')
    add('')

    add('### Vertical asymmetry: descent limit')
    add('')
    add('Model: the firmware descends at most `max_descent_speed` [m/s] whatever the commanded vertical speed; '
        'climbs are unchanged. Fit: the mean truth vertical speed where the replayed PID command has been '
        'saturated at %.1f m/s for 1 s: %s. Climbs under the saturated +2 m/s command reach %s m/s (no climb '
        'limit). Vertical speed replay rms (loop of (c-e), without -> with the limit):'
        % (de.commanded, ', '.join('%s %.3f m/s (std %.3f, %d samples)' % ((n,) + v)
                                   for n, v in de.per_file.items()),
           ', '.join('%.2f' % v for v in de.climb.values())))
    add('')
    L.extend(_without_with_table(de.replay, 'vz rms without [m/s]', 'with [m/s]', '%.3f'))
    add('')
    add('What the logs cannot identify: the only saturated descents are those of the two logs with garbage z '
        '(their truth is valid), both at the same command, so a speed cap, a reduced gain for descents or a '
        'limit that depends on the max vertical speed setting are indistinguishable; the cap is the simplest '
        'model consistent with both. drag_vertical remains unidentified (section (a)).')
    add('')

    tr = f.tilt_rate
    add('### Attitude: tilt-rate limit')
    add('')
    add('Model: the roll/pitch loop of section (c) moves the tilt vector (roll, pitch) by its exact first-order step, '
        'shortened to `tilt_rate_limit` R [rad/s] x dt when longer (`AnafiModel`), with its own time constant. Why: '
        'the static steps command ~30 deg at once; Sphinx\'s tilt ramps toward it, while the small corrections '
        'afterwards are faster than the single first order that has to average both (tau %.4f s, rms %.4f rad). '
        'Fit: the same PID replays, windows and calm samples (|yaw rate| <= 0.1 rad/s) as section (c), delay = '
        'attitude_delay, a constant offset per log and axis removed (the trim), (R, tau) by Nelder-Mead: R = %.3f '
        'rad/s (%.1f deg/s), tau = %.4f s, rms %.4f rad. Per static log (the MPC ones with their recomputed '
        'commands: a check, not fitted), roll/pitch rms [rad]:'
        % (tr.first_order[0], tr.first_order[1], tr.rate, np.degrees(tr.rate), tr.time_constant, tr.rms))
    add('')
    L.extend(_limited_loop_table(tr, 'R %.1f deg/s' % np.degrees(tr.rate)))
    add('')
    add('The same fit on all four static logs gives R = %.1f deg/s, tau = %.4f s (rms %.4f rad). What the logs '
        'cannot identify: whether the firmware limits the tilt rate itself or the body rates (the same thing '
        'without yaw); the turns of the yaw-180 logs are not explained by it (the gyroscopic coupling below is).'
        % (np.degrees(tr.all_static[0]), tr.all_static[1], tr.all_static[2]))
    add('')

    gy = f.gyroscopic
    add('### Attitude: coupling to the yaw rate (gyroscopic)')
    add('')
    add('Model (`frames.tilt_loop_step`, used by `AnafiModel`, this fit and the preview MPC): while the drone yaws '
        'at r [rad/s] the roll/pitch loop of section (c) changes in three ways, in the (forward, left) tilt plane '
        '(J a quarter turn counter-clockwise): its rate 1 / tau is reduced by c |r| (`yaw_tilt_authority` c '
        '[1/rad]; none left beyond |r| = 1 / (c tau): the tilt is held, not driven to the setpoint); its exact '
        'first-order step is multiplied by (I - G r J)^-1 (`gyroscopic_coupling` G [s]: d(tilt)/dt = (setpoint - '
        'tilt) / tau + G r J d(tilt)/dt, a term in the tilt\'s own rate as a gyroscopic torque would give; each '
        'step turned by atan(G r) and shortened by 1 / sqrt(1 + (G r)^2)); and the tilt then turns by w r dt '
        '(`yaw_tilt_precession` w [-], with the yaw for w > 0). Nothing changes without a yaw rate. Why: through '
        'the 180 deg turns of both static yaw-180 logs Sphinx\'s tilt keeps its magnitude (25-30 deg) and swings '
        'round the long way, in the sense of the yaw (counter-clockwise in the MPC run, clockwise in the PID run), '
        'turning in the body frame at ~1.3x the yaw rate, where the replayed command (PID) or the recomputed one '
        '(MPC, eq. 15; it swings through ~5 deg) and a plain first order cut through level; in the yaw-0 logs the '
        'tilt follows the command through level. Fit: least squares on roll and pitch of every clean static step '
        '(0.5 s before the step to 20 s after it, the turns included, the truth\'s yaw rate), with the first order '
        'of section (c) (tau %.4f s, delay %.4f s; tilt_rate_limit off, as shipped): G alone (the model before the '
        'other two terms) %.3f s, rms %.4f -> %.4f rad; all three together: G = %.3f s, c = %.3f 1/rad (the tilt '
        'held from |r| = %.0f deg/s on), w = %.3f, rms %.4f rad. Per static log, roll/pitch rms [rad]:'
        % (cal.params['attitude_time_constant'], cal.params['attitude_delay'], gy.alone[0], gy.rms_off,
           gy.alone[1], gy.coupling, gy.authority,
           np.degrees(1.0 / (gy.authority * cal.params['attitude_time_constant'])) if gy.authority > 0 else np.inf,
           gy.precession, gy.rms))
    add('')
    L.extend(_without_with_table(gy.per_file, 'none', ('G alone', 'G, c, w'), '%.4f'))
    add('')
    add('Both turn senses give the same signs: the terms follow the yaw rate (c its magnitude). Found by a fit '
        'of a general linear coupling (offline, 2026-11-25: the loop\'s decay and its attraction to the setpoint '
        'each changed by r times a scalar and a quarter turn, four numbers): its decay and attraction terms came '
        'out equal and opposite (a loss of the loop\'s rate with |r|, c) and its turn of the tilt itself as a '
        'precession (w); the four-number form fits no better than these three. Tried and rejected on the same '
        'data before (offline checks of 2026-11-25, roll/pitch rms over the 4 s after the yaw-180 steps): the '
        'step turned by kappa x r at full length (best kappa -0.6 s: ~7-8 deg against ~5 deg with G alone, ~9-10 '
        'deg without; the tilt still cuts through level); the step turned by atan(G r) and shortened by (1 + (G '
        'r)^2)^(-p/2) with p free: p = 1.04, i.e. G\'s form; a second-order roll/pitch loop with such a term in '
        'its rate, with the model\'s delay no better than G alone (rms 0.0343 against 0.0342 rad over the four '
        'steps). What the logs cannot identify: the source of the terms (the mixer saturating while the rotors '
        'yaw the drone, the rotors\' angular momentum, or the firmware\'s rate loop); whether they scale with the '
        'yaw rate, the yaw torque or the rotor speeds (one turn rate per log, ~100-140 deg/s).')
    add('')
    gl = f.gyroscopic_limited
    add('anafi_model_fitted.yaml (every effect on) has the tilt-rate limited loop of the section above (tau %.4f s, '
        'R %.1f deg/s): the three terms are refitted on it (the same fit with the rate limit in every step; the '
        'terms fitted on the first order, on this loop: rms %.4f rad): G alone %.3f s, rms %.4f -> %.4f rad; all '
        'three: G = %.3f s, c = %.3f 1/rad (the tilt held from |r| = %.0f deg/s on), w = %.3f, rms %.4f rad. Per '
        'static log, roll/pitch rms [rad] on that loop:'
        % (cal.fitted['attitude_time_constant'], np.degrees(cal.fitted['tilt_rate_limit']),
           gl.compared, gl.alone[0], gl.rms_off, gl.alone[1], gl.coupling, gl.authority,
           np.degrees(1.0 / (gl.authority * cal.fitted['attitude_time_constant'])) if gl.authority > 0 else np.inf,
           gl.precession, gl.rms))
    add('')
    L.extend(_without_with_table(gl.per_file, 'none', ('G alone', 'G, c, w'), '%.4f'))
    add('')

    ve = f.vertical
    add('### Vertical speed: acceleration limit')
    add('')
    add('Model: the vertical-speed loop is the first order of section (c) whose acceleration is clipped to '
        '+-`vertical_acceleration_limit` A [m/s^2] (`AnafiModel`: the loop\'s exact first-order step, then the '
        'clip), with its own time constant. Why: under the saturated 2 m/s climb command of the static PID logs '
        'Sphinx\'s vertical speed rises along a straight line, stops sharply at ~94 %% of the command and then '
        'creeps to it; one first order has to average the ramp and the stop (tau %.4f s, rms %.4f m/s), so it '
        'overstates the lag a small command sees (a slow periodic vertical motion) and understates the ramp. '
        'Fit: the same PID replays and windows as section (c), delay = attitude_delay, (A, tau) by Nelder-Mead: '
        'A = %.3f m/s^2, tau = %.4f s, rms %.4f m/s. Per static log (the MPC ones with their recomputed commands, '
        'eq. 15: a check, not fitted), vz rms [m/s]:'
        % (ve.first_order[0], ve.first_order[1], ve.limit, ve.time_constant, ve.rms))
    add('')
    L.extend(_limited_loop_table(ve, 'A %.2f' % ve.limit))
    add('')
    add('The same fit on all four static logs gives A = %.3f m/s^2, tau = %.4f s (rms %.4f m/s). What the logs '
        'cannot identify: the MPC static runs climb at up to 2.4 m/s under the 2.0 m/s command and then come '
        'back (an overshoot a PI loop with wind-up would give; the PID runs show none)'
        ', which no single model of both explains, so the MPC runs are left out of the fit (tried offline, '
        '2026-11-25, vz rms of the MPC / PID static steps against 0.12-0.15 / 0.034 m/s with this loop: a gain on '
        'the MPC\'s command, 1.06-1.10: MPC 0.09-0.14; the command taken from another step of the prediction, '
        'x_pred[2..8]: step 5 fits best; a PI or altitude-reference loop integrating below a saturated command: '
        'MPC 0.06-0.11 but PID 0.04-0.06; a two-degree-of-freedom loop - feed-forward, slow feedback, a lagged '
        'tilt compensation, vertical drag; six numbers - all four 0.082 -> 0.070: none kept; the MPC runs\' tilt '
        'and vertical speed start ~0.1 s after the delay of the PID fit, the one cycle of age of the authors\' '
        'node, `paper_timing`); the creep '
        'from ~94 %% to the command (seconds) is not modelled; the limit for descents is assumed equal to the one '
        'for climbs (no large descent step in a clean log).' % ve.all_static)
    add('')

    add('### Yaw estimate bias')
    add('')
    add('Model: a constant added to the published yaw (wrapped). Value: the median of the per-log mean '
        'yaw_anafi - yaw_sphinx, %.4f rad. Per log: %s. By controller: %s. The logs with a 180 deg turn '
        '(before the turn -> end): %s. The bias is not constant: it differs between the MPC and the PID runs '
        'and changes across the turn, i.e. a slowly drifting heading error the logs are too short to model; '
        'the constant removes its median only.'
        % (yw.bias, ', '.join('%s %.3f' % kv for kv in yw.per_file.items()),
           ', '.join('%s %.3f' % kv for kv in yw.by_controller.items()),
           ', '.join('%s %.3f -> %.3f' % ((n,) + v) for n, v in yw.turn.items())))
    add('')

    add('### Estimate quantisation')
    add('')
    add('Test: the coarsest power-of-two step (1/8 .. 1/512) with >= 98 % of the estimate values on its grid, '
        'where the float16 storage is at least 4x finer than the step; the truth columns are the control (what '
        'chance gives). Published values are rounded to the nearest multiple.')
    add('')
    add('| column | step found | estimate on grid | truth on grid | values tested |')
    add('|---|---|---|---|---|')
    for name, step in qu.steps.items():
        if name in qu.grids:
            add('| %s | none of the powers of two (1/256 shown; grid below) | %.3f | %.3f | %d |'
                % (name, qu.on_grid[name], qu.truth_on_grid[name], qu.samples[name]))
            continue
        add('| %s | %s | %.3f | %.3f | %d |' % (name, ('1/%d' % round(1.0 / step)) if step else 'none (1/256 shown)',
                                               qu.on_grid[name], qu.truth_on_grid[name], qu.samples[name]))
    add('')
    if qu.grids:
        add('The horizontal position estimate is on a grid that is no power of two (`estimate_grid`: the coarsest '
            'step in %g..%g m whose grid, with any offset per log, holds the values with a phase concentration '
            '|mean exp(2 pi i v / step)| >= 0.9; logs whose values span 20 steps at least; the truth is the '
            'control):' % GRID_RANGE)
        add('')
        add('| column | step [m] | estimate concentration | truth concentration |')
        add('|---|---|---|---|')
        for name, (step, conc, conc_truth) in qu.grids.items():
            add('| %s | %.5f | %.3f | %.3f |' % (name, step, conc, conc_truth))
        add('')
        add('Both steps are 2^-22 deg of longitude (x, east) and latitude (y, north) at a latitude of about 48.8 '
            'deg (0.0175 m and 0.0265 m): consistent with a geographic position of that resolution behind the '
            'estimate (an inference, the logs do not say how it is computed). The model rounds x and y to these '
            'steps (grid through the origin).')
        add('')
    add('Not identifiable from these float16 logs: any quantisation finer than the float16 storage (attitude, '
        'and every column above a few m or m/s); rounding cannot be told from truncation (a constant offset of '
        'half a step, absorbed by the estimate offsets).')
    if rp.on_grid:
        add('Replayed estimate on its grid: %s.' % ', '.join('%s %.3f' % kv for kv in rp.on_grid.items()))
    add('')
    return L
