#!/usr/bin/env python3
"""Fit the simulated Anafi's parameters to reference logs; write the YAML, a report and a replay figure.

Usage: calibrate_model.py [--logs DIR] [--out YAML] [--report MD] [--plot PNG]
Defaults: logs <repo>/../shared/reference_logs, out anafi_sim/config/anafi_model.yaml,
report docs/calibration.md, plot docs/calibration_replay.png (paths relative to the repo).
The fits live in anafi_sim/calibration/fit.py; this script only wires them to files.
"""
import argparse
import glob
import os
import sys

REPO = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
if REPO not in sys.path:
    sys.path.insert(0, REPO)

import numpy as np  # noqa: E402

from anafi_sim.calibration import fit as calibration  # noqa: E402
from anafi_sim.experiments.reference_log import read_log  # noqa: E402

REPLAY_LOG = 'static_waypoint_yaw_0_pid'
YAW_LOG = 'static_waypoint_yaw_180_pid'


def plot_replay(cal, logs, path):
    """Figure: model replaying a reference log, loop responses, estimate model, drag curve, Table 3."""
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    by_name = dict((log.name, log) for log in logs)
    p = cal.params
    fig, axes = plt.subplots(3, 3, figsize=(15, 10.5))
    log = by_name[REPLAY_LOG]
    trace = calibration.reconstruct_pid_commands(log)
    t0 = log.t[trace.start_index]
    window = (log.t >= t0 - 1.0) & (log.t <= t0 + 25.0)
    part = log.select(window)                       # its own time starts at 0
    shift = log.t[window][0]                        # log time of part.t == 0
    rel = part.t + shift - t0                       # time since the waypoint step
    trim = (cal.drag.trim_pitch, cal.drag.trim_roll)
    replay = calibration.replay_translation(part, p, trim=trim,
                                            vertical_command=(trace.t - shift, trace.vertical_speed))
    ax = axes[0, 0]
    ax.plot(rel, part.vx_sphinx, 'k-', lw=1.5, label='vx truth')
    ax.plot(rel, replay['vx'], 'C0--', lw=1.2, label='vx model')
    ax.plot(rel, part.vy_sphinx, color='0.5', lw=1.5, label='vy truth')
    ax.plot(rel, replay['vy'], 'C1--', lw=1.2, label='vy model')
    ax.plot(rel, part.vz_sphinx, color='0.75', lw=1.5, label='vz truth')
    ax.plot(rel, replay['vz'], 'C2--', lw=1.2, label='vz model')
    ax.set_title('%s: velocity replay from truth attitude' % REPLAY_LOG, fontsize=9)
    ax.set_xlabel('time since waypoint step [s]')
    ax.set_ylabel('m/s')
    ax.legend(fontsize=7, ncol=2)
    ax = axes[0, 1]
    for name, color in (('x', 'C0'), ('y', 'C1'), ('z', 'C2')):
        ax.plot(rel, part.columns[name + '_sphinx'], 'k-', lw=1.5)
        ax.plot(rel, replay[name], '--', color=color, lw=1.2, label='%s model' % name)
    ax.plot([], [], 'k-', label='truth')
    ax.set_title('position replay (open-loop integration)', fontsize=9)
    ax.set_xlabel('time since waypoint step [s]')
    ax.set_ylabel('m')
    ax.legend(fontsize=7)
    ax = axes[0, 2]
    speeds, tilts, labels = [], [], []
    for other in logs:
        if other.name.startswith('x_straight') and calibration.is_clean(other):
            speeds.append(float(np.mean(np.hypot(other.vx_sphinx, other.vy_sphinx))))
            tilts.append(float(np.mean(other.pitch_sphinx)) + cal.drag.trim_pitch)
            labels.append(other.name)
    v = np.linspace(0.0, 5.5, 50)
    ax.plot(v, [calibration.steady_state_pitch(s, p['drag_linear'], p['drag_quadratic']) for s in v], 'C3-',
            label='fit: atan((%.3f + %.4f v) v / g)' % (p['drag_linear'], p['drag_quadratic']))
    ax.plot(speeds, tilts, 'ko', ms=4, label='straight-line logs (mean pitch + trim)')
    ax.set_title('steady level flight: tilt vs speed', fontsize=9)
    ax.set_xlabel('speed [m/s]')
    ax.set_ylabel('tilt [rad]')
    ax.legend(fontsize=7)

    c = cal.commands
    rel_log = log.t - t0
    show = (rel_log >= -1.0) & (rel_log <= 8.0)
    ax = axes[1, 0]
    for name, u, color in (('pitch', trace.pitch, 'C0'), ('roll', trace.roll, 'C1')):
        model = calibration.first_order_response(trace.t, u, c.attitude.time_constant, c.attitude.delay, log.t)
        ax.step(trace.t - t0, u, where='post', color=color, lw=0.8, alpha=0.6, label='%s command (replay)' % name)
        ax.plot(rel_log[show], log.columns[name + '_sphinx'][show], 'k-', lw=1.5)
        ax.plot(rel_log[show], model[show], '--', color=color, lw=1.2, label='%s model' % name)
    ax.plot([], [], 'k-', label='truth')
    ax.set_xlim(-1.0, 8.0)
    ax.set_title('attitude: tau %.3f s, delay %.3f s (rms %.4f rad)'
                 % (c.attitude.time_constant, c.attitude.delay, c.attitude.rms), fontsize=9)
    ax.set_xlabel('time since waypoint step [s]')
    ax.set_ylabel('rad')
    ax.legend(fontsize=7)
    ax = axes[1, 1]
    model = calibration.first_order_response(trace.t, trace.vertical_speed, c.vertical.time_constant,
                                             c.vertical.delay, log.t)
    ax.step(trace.t - t0, trace.vertical_speed, where='post', color='C2', lw=0.8, alpha=0.6,
            label='vz command (replay)')
    ax.plot(rel_log[show], log.vz_sphinx[show], 'k-', lw=1.5, label='truth')
    ax.plot(rel_log[show], model[show], 'C2--', lw=1.2, label='model')
    ax.set_xlim(-1.0, 8.0)
    ax.set_title('vertical speed: tau %.3f s, delay %.3f s (rms %.3f m/s)'
                 % (c.vertical.time_constant, c.vertical.delay, c.vertical.rms), fontsize=9)
    ax.set_xlabel('time since waypoint step [s]')
    ax.set_ylabel('m/s')
    ax.legend(fontsize=7)
    ax = axes[1, 2]
    if c.yaw is not None and YAW_LOG in by_name:
        ylog = by_name[YAW_LOG]
        ytrace = calibration.reconstruct_pid_commands(ylog)
        yt0 = ylog.t[ytrace.start_index]
        yrel = ylog.t - yt0
        yshow = (yrel >= -1.0) & (yrel <= 8.0)
        model = calibration.first_order_response(ytrace.t, ytrace.yaw_rate, c.yaw.time_constant, c.yaw.delay,
                                                 ylog.t)
        ax.step(ytrace.t - yt0, ytrace.yaw_rate, where='post', color='C4', lw=0.8, alpha=0.6,
                label='yaw rate command (replay)')
        ax.plot(yrel[yshow], calibration.measured_yaw_rate(ylog)[yshow], 'k-', lw=1.5, label='truth')
        ax.plot(yrel[yshow], model[yshow], 'C4--', lw=1.2, label='model')
        ax.set_xlim(-1.0, 8.0)
        ax.set_title('%s yaw rate: tau %.3f s (rms %.3f rad/s)' % (YAW_LOG, c.yaw.time_constant, c.yaw.rms),
                     fontsize=9)
        ax.set_xlabel('time since waypoint step [s]')
        ax.set_ylabel('rad/s')
        ax.legend(fontsize=7)

    e = cal.estimate
    for ax, name, unit in ((axes[2, 0], 'vx', 'm/s'), (axes[2, 1], 'pitch', 'rad')):
        truth = log.columns[name + '_sphinx']
        est_model = calibration.estimate_model_response(log.t, truth, p['estimate_delay'],
                                                        p['estimate_time_constant'], p['estimate_rate'])
        zoom = (rel_log >= -0.3) & (rel_log <= 2.0)
        ax.plot(rel_log[zoom], truth[zoom], 'k.-', lw=1.0, ms=3, label='%s truth' % name)
        ax.plot(rel_log[zoom], log.columns[name + '_anafi'][zoom], 'C3o-', lw=1.0, ms=3,
                label='%s estimate (logged)' % name)
        ax.plot(rel_log[zoom], est_model[zoom], 'C0s--', lw=1.0, ms=3, mfc='none',
                label='estimate model on truth')
        ax.set_title('estimate: delay %.3f s + hold at %.0f Hz, tau %.3f s (effective lag %.3f s)'
                     % (p['estimate_delay'], p['estimate_rate'], p['estimate_time_constant'], e.effective_delay),
                     fontsize=9)
        ax.set_xlabel('time since waypoint step [s]')
        ax.set_ylabel(unit)
        ax.legend(fontsize=7)
    ax = axes[2, 2]
    rows = calibration.table3(logs)
    for k, controller in enumerate(('mpc', 'pid')):
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
    ax.set_title('Table 3: mean tracking error e on the estimate', fontsize=9)
    ax.set_xlabel('target speed [m/s]')
    ax.set_ylabel('m')
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=62)
    plt.close(fig)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    parser.add_argument('--logs', default=os.path.join(os.path.dirname(REPO), 'shared', 'reference_logs'),
                        help='directory with reference-log CSVs (default: <repo>/../shared/reference_logs)')
    parser.add_argument('--out', default=os.path.join(REPO, 'anafi_sim', 'config', 'anafi_model.yaml'),
                        help='model YAML to write')
    parser.add_argument('--report', default=os.path.join(REPO, 'docs', 'calibration.md'),
                        help='Markdown report to write ("" to skip)')
    parser.add_argument('--plot', default=os.path.join(REPO, 'docs', 'calibration_replay.png'),
                        help='PNG figure to write ("" to skip)')
    args = parser.parse_args(argv)

    paths = sorted(glob.glob(os.path.join(args.logs, '*.csv')))
    if not paths:
        parser.error('no *.csv reference logs in %s' % args.logs)
    logs = [read_log(path) for path in paths]
    for log in logs:
        for line_no, reason in log.parse_errors:
            print('warning: %s line %d skipped: %s' % (log.name, line_no, reason))
    cal = calibration.calibrate(logs)
    for report in cal.garbage.values():
        for line in report.summary():
            print('garbage: ' + line)
    print(calibration.format_summary(cal))

    with open(args.out, 'w') as stream:
        stream.write(calibration.format_model_yaml(cal, [log.name + '.csv' for log in logs]))
    print('wrote %s' % args.out)
    plot_name = None
    if args.plot:
        plot_replay(cal, logs, args.plot)
        print('wrote %s (%d bytes)' % (args.plot, os.path.getsize(args.plot)))
        plot_name = os.path.relpath(args.plot, os.path.dirname(os.path.abspath(args.report or args.plot)))
    if args.report:
        with open(args.report, 'w') as stream:
            stream.write(calibration.format_report(cal, logs, plot_name=plot_name))
        print('wrote %s' % args.report)
    return 0


if __name__ == '__main__':
    sys.exit(main())
