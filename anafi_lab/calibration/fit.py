"""Calibration of the simulated Anafi: fit its parameters to reference logs (pure numpy/scipy, no ROS).

Stage: offline, reference logs -> model parameters (``calibrate``), written to
``anafi_sim/config/anafi_model.yaml`` (read by ``anafi_sim/sim/drone_model.py`` and
``anafi_sim/sim/state_estimate.py``) by ``anafi_lab.reports.calibration_report``, which also writes the
Markdown report; ``plot`` draws the replay figure. The fits, one module per section of the report:
``responses`` (first order + delay, the limited loops), ``logs`` (helpers on logs), ``drag`` (a),
``estimate`` (b and the estimate's effects), ``commands`` (c-e, the translation replay), ``effects`` (f, the
loops' effects); this module puts them together (``fit_effects``, ``calibrate``) and recomputes Table 3.
The fits follow the model's equations exactly:

- attitude: roll/pitch (FLU Euler, R = Rz(yaw) Ry(pitch) Rx(roll), + pitch =
  nose down -> +x acceleration at yaw 0, + roll -> -y) track the setpoint
  first-order (``attitude_time_constant`` [s]) after ``attitude_delay`` [s],
  which delays the whole piloting command; yaw rate and vertical speed are
  first order too (``yaw_rate_time_constant``, ``vertical_speed_time_constant``);
- translation (world ENU): a = T z_body - g e_z - drag, with the specific
  thrust T chosen so that the vertical acceleration is what the vertical loop
  wants, horizontal drag (drag_linear + drag_quadratic |v_h|) v_h [1/s, 1/m],
  vertical drag drag_vertical v_z [1/s]; no wind in the logs (airspeed =
  ground speed);
- estimate: pure delay, first-order smoothing, sample-and-hold at
  ``estimate_rate`` [Hz], optional float16 quantisation.

Ground truth (``*_sphinx``) is the plant, ``*_anafi`` the estimate. Every fit
returns its values with the residual RMS (and R^2 where meaningful).
Units: SI (s, m, m/s, m/s^2, rad, rad/s) unless a name says otherwise.
"""
import collections

import numpy as np

from anafi_lab.calibration.commands import fit_command_responses
from anafi_lab.calibration.drag import GRAVITY, fit_drag
from anafi_lab.calibration.effects import (fit_descent, fit_gyroscopic_coupling, fit_tilt_attenuation,
                                           fit_tilt_attenuation_speed, fit_tilt_rate_limit,
                                           fit_vertical_acceleration_limit)
from anafi_lab.calibration.estimate import (estimate_series, fit_estimate, fit_position_fusion, fit_quantisation,
                                            fit_velocity_error, fit_yaw_bias, replay_estimates)
from anafi_lab.calibration.logs import is_clean
from anafi_lab.calibration.responses import ESTIMATE_STEP, fit_first_order_delay
from anafi_lab.paper import CONTROLLERS, PAPER_TABLE3
from anafi_sim.mission.reference_log import detect_garbage, tracking_error
from anafi_sim.sim.drone_model import EFFECT_GROUPS, EFFECTS_OFF

# The keys of anafi_model.yaml, in file order (drone_model.MODEL_KEYS must be the same set): the fitted
# model, then the fidelity effects (EFFECTS_OFF: the values that switch each off, shipped in anafi_model.yaml).
MODEL_KEYS = (
    'gravity', 'attitude_time_constant', 'attitude_delay', 'yaw_rate_time_constant',
    'vertical_speed_time_constant', 'drag_linear', 'drag_quadratic', 'drag_vertical',
    'estimate_delay', 'estimate_time_constant', 'estimate_rate', 'estimate_float16',
) + tuple(EFFECTS_OFF)


Effects = collections.namedtuple('Effects', ['fusion', 'tilt', 'descent', 'quanta', 'yaw', 'estimate_chain',
                                             'replay', 'tilt_speed', 'vertical', 'tilt_rate', 'velocity_error',
                                             'gyroscopic', 'gyroscopic_limited'])
Effects.__doc__ = ('The fidelity effects: PositionFusionFit, TiltFit (constant attenuation, static PID logs), '
                   'DescentFit, QuantumFit, YawBiasFit, the FirstOrderFit of the estimate delay/smoothing on '
                   'velocity and attitude alone (the position has its own model once the fusion is on), '
                   'EstimateReplay (open-loop check), TiltSpeedFit (the model\'s speed-gated attenuation, '
                   'straight MPC logs), VerticalLimitFit (the vertical-speed loop\'s acceleration limit), TiltRateFit '
                   '(the roll/pitch loop\'s tilt-rate limit), VelocityErrorFit (the decay of the velocity '
                   'estimate\'s own error), GyroscopicFit (the roll/pitch loop\'s coupling to the yaw rate, on the '
                   'first-order loop: anafi_model.yaml), GyroscopicFit (the same refitted on the tilt-rate limited '
                   'loop: anafi_model_fitted.yaml).')

# The effects calibrate() writes ON into anafi_model.yaml (the others keep their off values; every fitted value
# is in anafi_model_fitted.yaml). Chosen by the closed-loop replay of the shared logs (docs/fidelity.md): the
# position fusion brings the ground-truth cells in; the speed-gated tilt attenuation (none up to 4 m/s, about a
# fifth at 5 m/s) brings the 5 m/s MPC cells and Table 3's 5 m/s MPC cell in and leaves the slower logs alone;
# the descent limit is seen only in x_straight_2/3_pid, where Sphinx's drone sank below the ground under a
# wrapped z estimate - not normal flight - so it stays off; the vertical acceleration limit fits every static
# climb better and moves the cells by 1-2 %; the tilt-rate limit fits the attitude of every static step better
# open loop, but in closed loop it shrinks the yaw-0 step overshoots away from Sphinx's (PID 1.10x -> 0.76x, MPC
# 0.88x -> 0.70x; the yaw-180 ones come closer) for the same cells in the band, so it stays off (a candidate:
# docs/fidelity.md); the velocity error's decay changes nothing in
# a flight (no part of the model creates such an error) and lets a replay start from a logged velocity
# estimate. Edit and rerun anafi_lab/cli/calibrate_model.py.
SHIPPED_EFFECTS = ('position_fusion', 'velocity_error', 'tilt_attenuation', 'vertical_acceleration_limit',
                   'gyroscopic_coupling', 'yaw_bias', 'quantisation')


def fit_effects(logs, params, commands, estimate, trim_pitch=0.0, shipped=None):
    """Fit every effect and return (``Effects``, the fitted model dict with every effect on). ``trim_pitch``
    [rad]: the drag fit's offset of the thrust axis against the logged pitch (for the speed-gated attenuation);
    ``shipped``: the effects the model ships with (default ``SHIPPED_EFFECTS``): the attenuation is measured
    against closed-loop replays of that model without it."""
    clean = [log for log in logs if is_clean(log)]
    dynamic = [log for log in clean if log.name.startswith('static')] or clean
    channels = ('vx', 'vy', 'vz', 'roll', 'pitch')
    series, scales = estimate_series(dynamic, channels)
    chain = fit_first_order_delay(series, hold=False, fit_offset=True, scales=scales, tau_range=(0.0, 0.5),
                                  delay_range=(0.0, 0.4), step=ESTIMATE_STEP)
    fusion = fit_position_fusion(logs, estimate.rate, params['estimate_delay'], params['estimate_time_constant'])
    tilt = fit_tilt_attenuation(logs, commands.attitude)
    descent = fit_descent(logs, params['vertical_speed_time_constant'], params['attitude_delay'])
    # the first-order baselines are section (c)'s fits (same data, their own discretisation and offsets)
    vertical = fit_vertical_acceleration_limit(logs, params['attitude_delay'], params['vertical_speed_time_constant'])
    tilt_rate = fit_tilt_rate_limit(logs, params['attitude_delay'], params['attitude_time_constant'])
    gyroscopic = fit_gyroscopic_coupling(logs, params['attitude_time_constant'], params['attitude_delay'])
    # the same terms on the loop of the fitted file (every effect on: the tilt-rate limited loop)
    gyroscopic_limited = fit_gyroscopic_coupling(logs, tilt_rate.time_constant, params['attitude_delay'],
                                                 rate_limit=tilt_rate.rate, compare=gyroscopic[:3])
    quanta = fit_quantisation(logs)
    yaw = fit_yaw_bias(logs, estimate)
    velocity_error = fit_velocity_error(logs)
    fitted = collections.OrderedDict(params)
    fitted['estimate_delay'] = max(0.0, chain.delay - 0.5 / estimate.rate)
    fitted['estimate_time_constant'] = chain.time_constant
    fitted['tilt_attenuation'] = 0.0       # set below by the speed-gated fit (the constant one is reported)
    fitted['max_descent_speed'] = descent.max_descent_speed
    fitted['vertical_acceleration_limit'] = vertical.limit
    fitted['vertical_speed_time_constant'] = vertical.time_constant
    fitted['tilt_rate_limit'] = tilt_rate.rate
    fitted['attitude_time_constant'] = tilt_rate.time_constant
    fitted['gyroscopic_coupling'] = gyroscopic_limited.coupling
    fitted['yaw_tilt_authority'] = gyroscopic_limited.authority
    fitted['yaw_tilt_precession'] = gyroscopic_limited.precession
    fitted['estimate_position_fusion'] = True
    fitted['estimate_position_fix_delay'] = fusion.fix_delay
    fitted['estimate_position_fix_gain'] = fusion.fix_gain
    fitted['estimate_velocity_error_time_constant'] = velocity_error.time_constant
    fitted['estimate_yaw_bias'] = yaw.bias
    steps = quanta.steps
    fitted['estimate_quantum_x'] = steps['x']
    fitted['estimate_quantum_y'] = steps['y']
    fitted['estimate_quantum_z'] = steps['z']
    velocity_steps = [steps[c] for c in ('vx', 'vy', 'vz') if steps[c] > 0.0]
    fitted['estimate_quantum_velocity'] = float(np.median(velocity_steps)) if velocity_steps else 0.0
    before = collections.OrderedDict(params)
    before.update(EFFECTS_OFF)
    replay = replay_estimates(logs, before, fitted)
    # the speed-gated attenuation is measured against closed-loop replays of the model that ships without it
    unattenuated = collections.OrderedDict(before)
    for name in (SHIPPED_EFFECTS if shipped is None else shipped):
        if name != 'tilt_attenuation':
            for key in EFFECT_GROUPS[name]:
                unattenuated[key] = fitted[key]
    tilt_speed = fit_tilt_attenuation_speed(logs, unattenuated, trim=trim_pitch)
    fitted['tilt_attenuation'] = tilt_speed.attenuation
    fitted['tilt_attenuation_speed'] = tilt_speed.speed
    fitted['tilt_attenuation_speed_full'] = tilt_speed.speed_full
    return Effects(fusion, tilt, descent, quanta, yaw, chain, replay, tilt_speed, vertical, tilt_rate,
                   velocity_error, gyroscopic, gyroscopic_limited), fitted


# --------------------------------------------------------------------------- everything
Calibration = collections.namedtuple('Calibration', ['params', 'drag', 'estimate', 'commands', 'garbage',
                                                     'notes', 'fitted', 'effects', 'effects_on', 'baseline'])
Calibration.__doc__ = ('Result of ``calibrate``: params {MODEL_KEYS: value} (what anafi_model.yaml gets), DragFit, '
                       'EstimateFit, CommandFits, {file: GarbageReport}, [notes on what is not identified / not '
                       'modelled], fitted {MODEL_KEYS: value} with every effect on (anafi_model_fitted.yaml), '
                       'Effects, effects_on (the names of the EFFECT_GROUPS on in params), baseline {MODEL_KEYS: '
                       'value} with every effect off (the keys an effect refits, e.g. vertical_speed_time_constant, '
                       'at their values without it).')


def calibrate(logs, gravity=GRAVITY, effects=None):
    """Run every fit on ``logs`` (ReferenceLog list) and assemble the model parameters; ``Calibration``.

    ``effects`` (default ``SHIPPED_EFFECTS``): names of ``EFFECT_GROUPS`` whose fitted values go into params
    (the others off; every fitted value is in ``fitted``); True = all, False = none.
    """
    names = list(EFFECT_GROUPS)
    if effects is None:
        effects = SHIPPED_EFFECTS
    effects_on = tuple(names) if effects is True else () if effects is False else tuple(effects)
    unknown = [name for name in effects_on if name not in names]
    if unknown:
        raise ValueError('unknown fidelity effects %s (known: %s)' % (unknown, names))
    garbage = collections.OrderedDict((log.name, detect_garbage(log)) for log in logs)
    drag = fit_drag(logs, gravity=gravity)
    estimate = fit_estimate(logs)
    commands = fit_command_responses(logs)
    notes = []
    drag_vertical = drag.drag_vertical
    if not drag.drag_vertical_identified or drag_vertical < 0.0:
        drag_vertical = drag.drag_linear
        notes.append('drag_vertical is not identifiable from these logs (fit %s 1/s over Savitzky-Golay windows '
                     '%s); set to drag_linear (isotropic linear drag assumption). The model\'s vertical loop '
                     'compensates it, so it only matters through v_z tan(tilt).'
                     % (', '.join('%.3f' % v for v in drag.vertical_by_window.values()),
                        ', '.join(str(w) for w in drag.vertical_by_window)))
    params = collections.OrderedDict()
    params['gravity'] = float(gravity)
    params['attitude_time_constant'] = commands.attitude.time_constant
    params['attitude_delay'] = commands.attitude.delay
    params['yaw_rate_time_constant'] = commands.yaw.time_constant if commands.yaw else float('nan')
    params['vertical_speed_time_constant'] = commands.vertical.time_constant
    params['drag_linear'] = drag.drag_linear
    params['drag_quadratic'] = drag.drag_quadratic
    params['drag_vertical'] = float(drag_vertical)
    params['estimate_delay'] = estimate.delay
    params['estimate_time_constant'] = estimate.time_constant
    params['estimate_rate'] = estimate.rate
    params['estimate_float16'] = estimate.float16
    if commands.yaw is None:
        notes.append('yaw_rate_time_constant: no PID log with a yaw turn; not identified.')
    params.update(EFFECTS_OFF)
    found, fitted = fit_effects(logs, params, commands, estimate, trim_pitch=drag.trim_pitch, shipped=effects_on)
    shipped = collections.OrderedDict(params)
    for name, keys in EFFECT_GROUPS.items():
        if name in effects_on:
            for key in keys:
                shipped[key] = fitted[key]
    if 'gyroscopic_coupling' in effects_on and 'tilt_rate_limit' not in effects_on:
        # the coupling's terms are fitted on each loop: the fitted file's are the tilt-rate limited loop's
        gy = found.gyroscopic
        shipped['gyroscopic_coupling'] = gy.coupling
        shipped['yaw_tilt_authority'] = gy.authority
        shipped['yaw_tilt_precession'] = gy.precession
    return Calibration(shipped, drag, estimate, commands, garbage, notes, fitted, found, effects_on,
                       collections.OrderedDict(params))


# --------------------------------------------------------------------------- Table 3 recomputed
Table3Row = collections.namedtuple('Table3Row', ['controller', 'speed', 'file', 'paper', 'mean_e', 'mean_e_h',
                                                 'n_excluded', 'garbage'])
Table3Row.__doc__ = ('One Table-3 cell recomputed: controller, speed [m/s], file, paper mean e [m], mean e [m] '
                     '(garbage excluded; NaN if nothing valid), mean horizontal e [m], samples excluded, '
                     '``GarbageReport`` of the log.')


def table3(logs):
    """Recompute the paper's Table 3 from the x_straight_<speed>_<controller> logs; list of ``Table3Row``."""
    by_name = dict((log.name, log) for log in logs)
    rows = []
    for controller in CONTROLLERS:
        for k, paper in enumerate(PAPER_TABLE3[controller]):
            name = 'x_straight_%d_%s' % (k + 1, controller)
            log = by_name.get(name)
            if log is None:
                continue
            te = tracking_error(log, 'anafi', exclude_garbage=True)
            rows.append(Table3Row(controller, k + 1, name, paper, te.stats.mean, te.stats_h.mean,
                                  te.stats.n_excluded, te.garbage))
    return rows
