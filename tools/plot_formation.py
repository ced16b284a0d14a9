#!/usr/bin/env python3
"""Plot a recorded airship-formation run (airship_formation.launch): the three tracks and their errors.

Reads, in RUN_DIR (the launch's out_dir): each drone's evaluator CSV ``<drone>.csv`` (reference-log columns:
ground truth x/y/z_sphinx, the waypoint wp_x/y/z; anafi_sim.mission.reference_log) and, when present,
``airship.bag`` (/airship/odom). Figure: top, the xy tracks (the drones' estimates, the paper's metric, or
with --source sphinx ground truth; solid) with their waypoints (dashed) and the airship's path; bottom,
e = |waypoint - drone| [m] over time per drone, from the
moment its first waypoint arrived (``--skip`` s more leave the approach out of the statistics printed and
written next to the figure as RUN_DIR/formation_summary.yaml).

    python tools/plot_formation.py RUN_DIR [-o docs/airship_formation.png] [--skip 20] [--source anafi|sphinx]
"""
import argparse
import os
import sys

import matplotlib
matplotlib.use('Agg')
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import yaml  # noqa: E402

from anafi_sim.mission.reference_log import read_log  # noqa: E402

COLOURS = {'left': 'tab:blue', 'right': 'tab:orange', 'behind': 'tab:green'}


def airship_track(path):
    """(t [s ROS time], x, y, z) arrays of /airship/odom in a bag, or None."""
    if not os.path.isfile(path):
        return None
    import rosbag
    t, xyz = [], []
    with rosbag.Bag(path) as bag:
        for _, msg, stamp in bag.read_messages(topics=['/airship/odom']):
            p = msg.pose.pose.position
            t.append(msg.header.stamp.to_sec() or stamp.to_sec())
            xyz.append((p.x, p.y, p.z))
    if not t:
        return None
    xyz = np.asarray(xyz)
    return np.asarray(t), xyz[:, 0], xyz[:, 1], xyz[:, 2]


def drone_track(path, source='anafi'):
    """(t [s ROS time], drone xyz (n, 3), waypoint xyz (n, 3)) of the rows with both, from an evaluator CSV;
    ``source`` anafi = the drone's estimate (the paper's metric), sphinx = ground truth."""
    log = read_log(path)
    c = log.columns
    truth = np.column_stack([c['x_%s' % source], c['y_%s' % source], c['z_%s' % source]])
    wp = np.column_stack([c['wp_x'], c['wp_y'], c['wp_z']])
    ok = np.all(np.isfinite(truth), axis=1) & np.all(np.isfinite(wp), axis=1)
    return log.time[ok], truth[ok], wp[ok]


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument('run_dir')
    ap.add_argument('-o', '--output', default=None, help='PNG (default RUN_DIR/airship_formation.png)')
    ap.add_argument('--skip', type=float, default=20.0, help='s after the first waypoint left out of the stats')
    ap.add_argument('--drones', nargs='+', default=['left', 'right', 'behind'])
    ap.add_argument('--source', default='anafi', choices=('anafi', 'sphinx'),
                    help='drone position: anafi = its estimate (the paper\'s metric, default), sphinx = ground truth')
    args = ap.parse_args(argv)
    tracks = {}
    for name in args.drones:
        path = os.path.join(args.run_dir, name + '.csv')
        if not os.path.isfile(path):
            sys.stderr.write('no %s\n' % path)
            return 1
        tracks[name] = drone_track(path, args.source)
    t0 = min(tr[0][0] for tr in tracks.values() if len(tr[0]))
    ship = airship_track(os.path.join(args.run_dir, 'airship.bag'))
    fig, (ax, ax_e) = plt.subplots(2, 1, figsize=(9, 10), gridspec_kw={'height_ratios': [3, 2]})
    if ship is not None:
        keep = ship[0] >= t0
        ax.plot(ship[1][keep], ship[2][keep], color='0.5', lw=3, alpha=0.5, label='airship')
    summary = {}
    what = 'estimate' if args.source == 'anafi' else 'ground truth'
    for name, (t, truth, wp) in tracks.items():
        colour = COLOURS.get(name)
        ax.plot(truth[:, 0], truth[:, 1], color=colour, lw=1.5, label='%s (%s)' % (name, what))
        ax.plot(wp[:, 0], wp[:, 1], color=colour, lw=1, ls='--', label='%s waypoint' % name)
        ax.plot(truth[-1, 0], truth[-1, 1], 'o', color=colour)
        e = np.linalg.norm(wp - truth, axis=1)
        ax_e.plot(t - t0, e, color=colour, lw=1, label=name)
        m = t >= t[0] + args.skip
        if np.any(m):
            summary[name] = {'position': what, 'e_max': round(float(e[m].max()), 3), 'e_mu': round(float(e[m].mean()), 3),
                             'e_sigma': round(float(e[m].std()), 3), 'samples': int(m.sum()),
                             'window_s': round(float(t[m][-1] - t[m][0]), 1)}
    if ship is not None:
        ax.plot(ship[1][-1], ship[2][-1], 's', color='0.4', ms=9)
    ax.set_xlabel('x [m] (world ENU)')
    ax.set_ylabel('y [m]')
    ax.set_aspect('equal', adjustable='datalim')
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8, loc='best')
    ax.set_title('Three Anafis follow the airship in formation (left / right / behind, MPC each)')
    ax_e.set_xlabel('time [s] since the first waypoint')
    ax_e.set_ylabel('e = |waypoint - %s| [m]' % what)
    ax_e.grid(True, alpha=0.3)
    ax_e.legend(fontsize=8)
    if args.skip > 0:
        ax_e.axvspan(0, args.skip, color='0.9', zorder=0)
    fig.tight_layout()
    out = args.output or os.path.join(args.run_dir, 'airship_formation.png')
    fig.savefig(out, dpi=90)
    with open(os.path.join(args.run_dir, 'formation_summary.yaml'), 'w') as f:
        yaml.safe_dump(summary, f, default_flow_style=False)
    print('written %s' % out)
    for name, s in summary.items():
        print('%-7s e_max %.2f m, e_mu %.2f m, e_sigma %.2f m over %.0f s' % (name, s['e_max'], s['e_mu'],
                                                                              s['e_sigma'], s['window_s']))
    return 0


if __name__ == '__main__':
    sys.exit(main())
