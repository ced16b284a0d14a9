"""The calibration's replay figure (pure Python + matplotlib, no ROS): the fitted model against the logs.

Stage: offline, a ``fit.Calibration`` and its reference logs -> ``docs/calibration_replay.png``. Twelve
panels: the translational model replaying a static-waypoint log (velocity, position), steady-flight tilt
vs speed, the firmware loops (attitude, vertical speed, yaw rate) fed the reconstructed PID commands,
the estimate model on the truth against the logged estimate, Table 3 paper vs recomputed, and the
fidelity effects (position fusion in steady flight and in a transient, descent limit).
matplotlib is imported when a figure is drawn (Agg backend).
"""
import numpy as np

from anafi_lab.calibration.commands import reconstruct_pid_commands, replay_translation
from anafi_lab.calibration.drag import steady_state_pitch
from anafi_lab.calibration.estimate import estimate_model_response, replay_estimate
from anafi_lab.calibration.fit import table3
from anafi_lab.calibration.logs import is_clean, measured_yaw_rate
from anafi_lab.calibration.responses import first_order_response
from anafi_lab.paper import CONTROLLERS

REPLAY_LOG = 'static_waypoint_yaw_0_pid'
STEADY_LOG = 'x_straight_5_mpc'
DESCENT_LOG = 'x_straight_2_pid'
YAW_LOG = 'static_waypoint_yaw_180_pid'
STEP_AXIS = 'time since waypoint step [s]'


def _label(ax, title, xlabel, ylabel):
    """The panel's title, axis labels and legend in the figure's sizes."""
    ax.set_title(title, fontsize=9)
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.legend(fontsize=7)


def _loop_panel(ax, t_cmd, command, t, truth, model, color, command_label, title, unit):
    """One firmware loop: the replayed command (steps), the truth and the fitted model, -1..8 s."""
    ax.step(t_cmd, command, where='post', color=color, lw=0.8, alpha=0.6, label=command_label)
    ax.plot(t, truth, 'k-', lw=1.5, label='truth')
    ax.plot(t, model, '--', color=color, lw=1.2, label='model')
    ax.set_xlim(-1.0, 8.0)
    _label(ax, title, STEP_AXIS, unit)


def plot_replay(cal, logs, path):
    """Figure: model replaying a reference log, loop responses, estimate model, drag curve, Table 3."""
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    by_name = dict((log.name, log) for log in logs)
    fig, axes = plt.subplots(4, 3, figsize=(15, 14.0))
    log = by_name[REPLAY_LOG]
    trace = reconstruct_pid_commands(log)
    _translation_panels(axes[0], cal, logs, log, trace)
    _loop_panels(axes[1], cal, by_name, log, trace)
    _estimate_panels(axes[2, :2], cal, log, log.t - log.t[trace.start_index])
    _table3_panel(axes[2, 2], table3(logs))
    _effect_panels(axes[3], cal, by_name)
    fig.tight_layout()
    fig.savefig(path, dpi=62)
    plt.close(fig)


def _translation_panels(axes, cal, logs, log, trace):
    """Top row: the translational model replaying ``log`` (velocity, position), steady tilt vs speed."""
    p = cal.params
    t0 = log.t[trace.start_index]
    window = (log.t >= t0 - 1.0) & (log.t <= t0 + 25.0)
    part = log.select(window)                       # its own time starts at 0
    shift = log.t[window][0]                        # log time of part.t == 0
    rel = part.t + shift - t0                       # time since the waypoint step
    trim = (cal.drag.trim_pitch, cal.drag.trim_roll)
    replay = replay_translation(part, p, trim=trim, vertical_command=(trace.t - shift, trace.vertical_speed))
    ax = axes[0]
    ax.plot(rel, part.vx_sphinx, 'k-', lw=1.5, label='vx truth')
    ax.plot(rel, replay['vx'], 'C0--', lw=1.2, label='vx model')
    ax.plot(rel, part.vy_sphinx, color='0.5', lw=1.5, label='vy truth')
    ax.plot(rel, replay['vy'], 'C1--', lw=1.2, label='vy model')
    ax.plot(rel, part.vz_sphinx, color='0.75', lw=1.5, label='vz truth')
    ax.plot(rel, replay['vz'], 'C2--', lw=1.2, label='vz model')
    ax.set_title('%s: velocity replay from truth attitude' % REPLAY_LOG, fontsize=9)
    ax.set_xlabel(STEP_AXIS)
    ax.set_ylabel('m/s')
    ax.legend(fontsize=7, ncol=2)
    ax = axes[1]
    for name, color in (('x', 'C0'), ('y', 'C1'), ('z', 'C2')):
        ax.plot(rel, part.columns[name + '_sphinx'], 'k-', lw=1.5)
        ax.plot(rel, replay[name], '--', color=color, lw=1.2, label='%s model' % name)
    ax.plot([], [], 'k-', label='truth')
    _label(ax, 'position replay (open-loop integration)', STEP_AXIS, 'm')
    ax = axes[2]
    speeds, tilts = [], []
    for other in logs:
        if other.name.startswith('x_straight') and is_clean(other):
            speeds.append(float(np.mean(np.hypot(other.vx_sphinx, other.vy_sphinx))))
            tilts.append(float(np.mean(other.pitch_sphinx)) + cal.drag.trim_pitch)
    v = np.linspace(0.0, 5.5, 50)
    ax.plot(v, [steady_state_pitch(s, p['drag_linear'], p['drag_quadratic']) for s in v], 'C3-',
            label='fit: atan((%.3f + %.4f v) v / g)' % (p['drag_linear'], p['drag_quadratic']))
    ax.plot(speeds, tilts, 'ko', ms=4, label='straight-line logs (mean pitch + trim)')
    _label(ax, 'steady level flight: tilt vs speed', 'speed [m/s]', 'tilt [rad]')


def _loop_panels(axes, cal, by_name, log, trace):
    """Second row: the firmware loops (attitude, vertical speed, yaw rate) fed the replayed PID commands."""
    c = cal.commands
    t0 = log.t[trace.start_index]
    rel_log = log.t - t0
    show = (rel_log >= -1.0) & (rel_log <= 8.0)
    ax = axes[0]
    for name, u, color in (('pitch', trace.pitch, 'C0'), ('roll', trace.roll, 'C1')):
        model = first_order_response(trace.t, u, c.attitude.time_constant, c.attitude.delay, log.t)
        ax.step(trace.t - t0, u, where='post', color=color, lw=0.8, alpha=0.6, label='%s command (replay)' % name)
        ax.plot(rel_log[show], log.columns[name + '_sphinx'][show], 'k-', lw=1.5)
        ax.plot(rel_log[show], model[show], '--', color=color, lw=1.2, label='%s model' % name)
    ax.plot([], [], 'k-', label='truth')
    ax.set_xlim(-1.0, 8.0)
    _label(ax, 'attitude: tau %.3f s, delay %.3f s (rms %.4f rad)'
           % (c.attitude.time_constant, c.attitude.delay, c.attitude.rms), STEP_AXIS, 'rad')
    model = first_order_response(trace.t, trace.vertical_speed, c.vertical.time_constant, c.vertical.delay,
                                 log.t)
    _loop_panel(axes[1], trace.t - t0, trace.vertical_speed, rel_log[show], log.vz_sphinx[show], model[show],
                'C2', 'vz command (replay)', 'vertical speed: tau %.3f s, delay %.3f s (rms %.3f m/s)'
                % (c.vertical.time_constant, c.vertical.delay, c.vertical.rms), 'm/s')
    if c.yaw is not None and YAW_LOG in by_name:
        ylog = by_name[YAW_LOG]
        ytrace = reconstruct_pid_commands(ylog)
        yt0 = ylog.t[ytrace.start_index]
        yrel = ylog.t - yt0
        yshow = (yrel >= -1.0) & (yrel <= 8.0)
        model = first_order_response(ytrace.t, ytrace.yaw_rate, c.yaw.time_constant, c.yaw.delay, ylog.t)
        _loop_panel(axes[2], ytrace.t - yt0, ytrace.yaw_rate, yrel[yshow], measured_yaw_rate(ylog)[yshow],
                    model[yshow], 'C4', 'yaw rate command (replay)',
                    '%s yaw rate: tau %.3f s (rms %.3f rad/s)' % (YAW_LOG, c.yaw.time_constant, c.yaw.rms), 'rad/s')


def _estimate_panels(axes, cal, log, rel_log):
    """Third row, first two panels: the estimate model on the truth against the logged estimate (vx, pitch);
    ``rel_log``: the log's time since the waypoint step [s]."""
    p = cal.params
    for ax, name, unit in ((axes[0], 'vx', 'm/s'), (axes[1], 'pitch', 'rad')):
        truth = log.columns[name + '_sphinx']
        est_model = estimate_model_response(log.t, truth, p['estimate_delay'], p['estimate_time_constant'],
                                            p['estimate_rate'])
        zoom = (rel_log >= -0.3) & (rel_log <= 2.0)
        ax.plot(rel_log[zoom], truth[zoom], 'k.-', lw=1.0, ms=3, label='%s truth' % name)
        ax.plot(rel_log[zoom], log.columns[name + '_anafi'][zoom], 'C3o-', lw=1.0, ms=3,
                label='%s estimate (logged)' % name)
        ax.plot(rel_log[zoom], est_model[zoom], 'C0s--', lw=1.0, ms=3, mfc='none', label='estimate model on truth')
        _label(ax, 'estimate: delay %.3f s + hold at %.0f Hz, tau %.3f s (effective lag %.3f s)'
               % (p['estimate_delay'], p['estimate_rate'], p['estimate_time_constant'], cal.estimate.effective_delay),
               STEP_AXIS, unit)


def _effect_panels(axes, cal, by_name):
    """Bottom row: the position estimate with the effects off / on (steady flight, transient), the descent limit."""
    from anafi_sim.sim.drone_model import EFFECTS_OFF
    before = dict(cal.fitted)
    before.update(EFFECTS_OFF)
    before['estimate_delay'] = cal.params['estimate_delay']
    before['estimate_time_constant'] = cal.params['estimate_time_constant']
    for ax, name in ((axes[0], STEADY_LOG), (axes[1], REPLAY_LOG)):
        if name not in by_name:
            continue
        log = by_name[name]
        off = replay_estimate(log, before)
        on = replay_estimate(log, cal.fitted)
        ax.plot(log.t, log.x_sphinx - log.x_anafi, 'k-', lw=1.5, label='logged')
        ax.plot(log.t, log.x_sphinx - off['x'], 'C0--', lw=1.2, label='model, effects off')
        ax.plot(log.t, log.x_sphinx - on['x'], 'C3--', lw=1.2, label='model, fusion on')
        _label(ax, '%s: x truth - x estimate (k %.3f 1/s, D %.3f s)'
               % (name, cal.fitted['estimate_position_fix_gain'], cal.fitted['estimate_position_fix_delay']),
               'log time [s]', 'm')
    ax = axes[2]
    de = cal.effects.descent
    if DESCENT_LOG in by_name and de.max_descent_speed > 0.0:
        log = by_name[DESCENT_LOG]
        trace = reconstruct_pid_commands(log)
        c = cal.commands.vertical
        ax.step(trace.t, trace.vertical_speed, where='post', color='C2', lw=0.8, alpha=0.6,
                label='vz command (replay)')
        ax.plot(log.t, log.vz_sphinx, 'k-', lw=1.5, label='truth')
        for cap, style, text in ((None, 'C0--', 'model, no limit'), (de.max_descent_speed, 'C3--', 'model, limit')):
            u = trace.vertical_speed if cap is None else np.maximum(trace.vertical_speed, -cap)
            ax.plot(log.t, first_order_response(trace.t, u, c.time_constant, c.delay, log.t,
                                                    initial=log.vz_sphinx[0]), style, lw=1.2, label=text)
        _label(ax, '%s: descent limit %.2f m/s (truth valid, z estimate garbage)'
               % (DESCENT_LOG, de.max_descent_speed), 'log time [s]', 'm/s')


def _table3_panel(ax, rows):
    """Bars: the paper's Table 3 next to the values recomputed from the logs (horizontal where z is garbage)."""
    for k, controller in enumerate(CONTROLLERS):
        sel = [r for r in rows if r.controller == controller]
        xs = np.array([r.speed for r in sel], dtype=float)
        ax.bar(xs - 0.2 + 0.4 * k - 0.09, [r.paper for r in sel], width=0.18, color='C%d' % (k * 2),
               alpha=0.5, label='%s paper' % controller.upper())
        vals = [r.mean_e if np.isfinite(r.mean_e) else r.mean_e_h for r in sel]
        ax.bar(xs - 0.2 + 0.4 * k + 0.09, vals, width=0.18, color='C%d' % (k * 2),
               label='%s recomputed' % controller.upper())
        for r, val in zip(sel, vals):
            if not np.isfinite(r.mean_e):
                ax.annotate('garbage z:\nhoriz. only', (r.speed - 0.2 + 0.4 * k + 0.09, val), fontsize=6,
                            ha='center', va='bottom')
    _label(ax, 'Table 3: mean tracking error e on the estimate', 'target speed [m/s]', 'm')
