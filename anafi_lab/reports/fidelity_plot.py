"""One figure per replayed log (matplotlib Agg, no ROS): Sphinx against the stand-in's variants."""
import math
import os

import numpy as np


def plot_replay(path, log, series, title=None, dpi=80):
    """One figure per log: Sphinx (black) and each stand-in variant (``series``: [(label, record['series'])]):
    the main axis position (estimate solid, truth dotted) with the waypoint, the tracking error against the
    estimate, the truth pitch and roll, the truth vertical speed; time = log time [s]."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    t = log.t
    fig = Figure(figsize=(9.0, 9.0))
    FigureCanvasAgg(fig)
    axes = [fig.add_subplot(5, 1, i + 1) for i in range(5)]
    wp = log.waypoint()
    span = np.nanmax(wp[:, :3], axis=0) - np.nanmin(wp[:, :3], axis=0)
    moving = bool(np.any(wp[:, 3:6] != 0.0))
    colors = ('#1f77b4', '#d62728', '#2ca02c', '#ff7f0e', '#9467bd', '#8c564b')

    def err(xyz_wp, xyz):
        return np.sqrt(np.sum((xyz_wp - xyz) ** 2, axis=1))
    if moving:       # position along the motion minus the waypoint: the lag
        axis = int(np.argmax(span))
        name = 'xyz'[axis]
        axes[0].plot(t, log.columns['%s_anafi' % name] - wp[:, axis], 'k-', lw=1.2, label='Sphinx estimate')
        axes[0].plot(t, log.columns['%s_sphinx' % name] - wp[:, axis], 'k:', lw=1.2, label='Sphinx truth')
        for (label, s), c in zip(series, colors):
            axes[0].plot(t, np.asarray(s['%s_anafi' % name]) - wp[:, axis], '-', color=c, lw=1, label=label)
            axes[0].plot(t, np.asarray(s['%s_sphinx' % name]) - wp[:, axis], ':', color=c, lw=1)
        axes[0].set_ylabel('%s - wp_%s [m]' % (name, name))
    else:
        for axis, ls in ((0, '-'), (2, '--')):
            name = 'xyz'[axis]
            axes[0].plot(t, log.columns['%s_anafi' % name], 'k' + ls, lw=1.2, label='Sphinx %s' % name)
            for (label, s), c in zip(series, colors):
                axes[0].plot(t, s['%s_anafi' % name], ls, color=c, lw=1, label='%s %s' % (label, name))
        axes[0].plot(t, wp[:, 0], color='0.6', lw=0.8, label='wp x')
        axes[0].plot(t, wp[:, 2], '--', color='0.6', lw=0.8, label='wp z')
        axes[0].set_ylabel('x, z (estimate) [m]')
    p_log = log.position('anafi')
    axes[1].plot(t, err(wp[:, :3], p_log), 'k-', lw=1.2, label='Sphinx')
    for (label, s), c in zip(series, colors):
        p = np.column_stack([s['x_anafi'], s['y_anafi'], s['z_anafi']])
        axes[1].plot(t, err(wp[:, :3], p), '-', color=c, lw=1, label=label)
    axes[1].set_ylabel('e vs estimate [m]')
    for ax, name, unit, scale in ((axes[2], 'pitch', 'deg', 180.0 / math.pi), (axes[3], 'roll', 'deg', 180.0 / math.pi),
                                  (axes[4], 'vz', 'm/s', 1.0)):
        col = '%s_sphinx' % name
        ax.plot(t, log.columns[col] * scale, 'k-', lw=1.2, label='Sphinx')
        for (label, s), c in zip(series, colors):
            ax.plot(t, np.asarray(s[col], dtype=np.float64) * scale, '-', color=c, lw=1, label=label)
        ax.set_ylabel('truth %s [%s]' % (name, unit))
    for ax in axes:
        ax.grid(True, alpha=0.3)
        ax.tick_params(labelsize=8)
        ax.yaxis.label.set_size(8)
    axes[0].legend(fontsize=7, ncol=3, loc='best')
    axes[1].legend(fontsize=7, ncol=3, loc='best')
    axes[-1].set_xlabel('log time [s]')
    fig.suptitle(title or log.name, fontsize=10)
    fig.tight_layout(rect=(0, 0, 1, 0.97))
    directory = os.path.dirname(path)
    if directory and not os.path.isdir(directory):
        os.makedirs(directory, exist_ok=True)
    fig.savefig(path, dpi=dpi)
    return path
