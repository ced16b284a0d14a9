"""Experiment plots (pure Python + matplotlib Agg, no ROS, no pyplot): like the paper's Figs. 2 and 6.

Stage: evaluation output -> figures. Input: reference-log CSV files (the evaluator's export, the
column format of anafi_sim/data/reference_logs, ``anafi_sim.mission.reference_log``): positions [m] and velocities
[m/s] in the ENU world frame, attitude [rad], waypoint yaw [deg], time [ns]. Time on the plots is
seconds since the log's first sample; the measured window (s since the first sample, as in the
evaluator's summary 'window') is shaded.

- ``run_figure`` / ``plot_run``: one run: x, y, z of the drone's estimate (solid), ground truth
  (dotted) and the waypoint (dashed) over time; the xy path (when the waypoint moves in x and y,
  e.g. circles) or yaw over time; the tracking error e = |waypoint - position| against the estimate
  (the paper's metric) and ground truth, with its mean over the measured window: that panel shows the
  measured window only, its error axis scaled to the errors there (``error_limits``: the take-off's metres do
  not flatten a 0.4 m error); a failed run says FAILED and why in its title.
- ``comparison_figure`` / ``plot_comparison``: several runs overlaid (x, y, z, yaw against time
  since a per-run offset), e.g. PID and MPC to WP0 / WP1 as in Fig. 6.

Figures are built on ``matplotlib.figure.Figure`` with the Agg canvas (no global pyplot state, no
display needed), legends outside the axes (above the x, y, z panels and under the error panel), and saved
(``save``) as PNG (default, ``DEFAULT_DPI``), SVG or PDF (``FORMATS``; by the file's extension or ``fmt``),
cropped to what is drawn; SVG and PDF carry no creation date, so the same run gives the same file.
"""
import math
import os

import numpy as np
from matplotlib import rc_context
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from anafi_sim.mission.reference_log import read_log, tracking_error
from anafi_sim.numeric import parse_number, range_problem
from anafi_sim.run_files import FIGURE_DPI as DEFAULT_DPI, FIGURE_FORMATS as FORMATS

DEFAULT_FORMAT = 'png'
#: metadata that would make two renderings of one figure differ (a date), left out
_NO_DATE = {'svg': {'Date': None}, 'pdf': {'CreationDate': None}, 'png': {}}
ERROR_MIN_SPAN = 0.05
"""m; the error axis shows at least this much (a perfect run does not get a 1e-16 m scale)."""
COLORS = {'estimate': '#1f77b4', 'truth': '#2ca02c', 'waypoint': '#d62728'}
RUN_COLORS = ('#1f77b4', '#9467bd', '#ff7f0e', '#808000', '#2ca02c', '#d62728', '#8c564b', '#17becf')


def load(path):
    """The ``ReferenceLog`` of a reference-log CSV (ValueError / IOError when unreadable)."""
    return read_log(path)


def has_truth(log):
    """True when the log has some finite ground-truth position."""
    return bool(np.isfinite(log.columns['x_sphinx']).any())


def moves_in_plane(log, window=None, min_extent=0.5):
    """True when the waypoint spans at least ``min_extent`` m in both x and y (e.g. a circle) within
    ``window`` (t0, t1) [s since the first sample; None = the whole log]; the span is the 2nd to 98th
    percentile, so a single step into the window does not count as motion."""
    wp = log.waypoint()
    ok = np.isfinite(wp[:, 0]) & np.isfinite(wp[:, 1]) & window_mask(log.t, window)
    if ok.sum() < 2:
        return False
    span = [float(np.percentile(wp[ok, i], 98) - np.percentile(wp[ok, i], 2)) for i in (0, 1)]
    return bool(span[0] >= min_extent and span[1] >= min_extent)


def window_mask(t, window):
    """Boolean mask of t inside window (t0, t1); all True when window is None."""
    t = np.asarray(t)
    if window is None:
        return np.ones(len(t), dtype=bool)
    return (t >= window[0]) & (t <= window[1])


def _shade(ax, window):
    if window is not None:
        ax.axvspan(window[0], window[1], color='0.9', zorder=0, lw=0)


def _min_span(ax, values, span):
    """Show at least ``span`` around the data (a constant signal gets no 1e-16 axis scale)."""
    values = np.asarray(values, dtype=np.float64)
    values = values[np.isfinite(values)]
    if len(values) and np.ptp(values) < span:
        mid = 0.5 * (values.max() + values.min())
        ax.set_ylim(mid - 0.5 * span, mid + 0.5 * span)


def _decimate(n, max_points=1500):
    """Index step so that at most ``max_points`` points are drawn per line (keeps PNGs small)."""
    return max(1, int(math.ceil(n / float(max_points))))


def error_limits(t, errors, window):
    """(x limits, y limits) of the error panel: the measured ``window`` (t0, t1) [s] (the whole log when None or
    when no sample falls in it) and 0 .. 1.1 x the largest finite error of ``errors`` (arrays over ``t``) in
    it, at least ``ERROR_MIN_SPAN``."""
    t = np.asarray(t, dtype=np.float64)
    m = window_mask(t, window)
    if window is None or not m.any():
        m = np.ones(len(t), dtype=bool)
        x = (float(t[0]), float(t[-1])) if len(t) else (0.0, 1.0)
    else:
        x = (float(window[0]), float(window[1]))
    if x[1] <= x[0]:
        x = (x[0] - 0.5, x[0] + 0.5)
    peak = 0.0
    for e in errors:
        e = np.asarray(e, dtype=np.float64)[m]
        e = e[np.isfinite(e)]
        if len(e):
            peak = max(peak, float(e.max()))
    return x, (0.0, max(1.1 * peak, ERROR_MIN_SPAN))


def _error_panel(bottom, log, window, truth, k):
    """The tracking error over the measured window (vs the estimate, and vs ground truth when ``truth``), e_mu
    over it; the axes' limits from ``error_limits``, the legend under the panel."""
    t = log.t
    _shade(bottom, window)
    e_est = tracking_error(log, 'anafi').e
    bottom.plot(t[::k], e_est[::k], '-', color=COLORS['estimate'], lw=1.2, label='vs estimate')
    m = window_mask(t, window)
    shown = [e_est]
    if truth:
        e_tr = tracking_error(log, 'sphinx').e
        shown.append(e_tr)
        bottom.plot(t[::k], e_tr[::k], ':', color=COLORS['truth'], lw=1.2, label='vs ground truth')
    valid = m & np.isfinite(e_est)
    if valid.any():
        mu = float(np.mean(e_est[valid]))
        x0, x1 = (window if window is not None else (t[0], t[-1]))
        bottom.hlines(mu, x0, x1, colors='k', linestyles='-.', lw=1.0, label='e_mu %.2f m' % mu)
    xlim, ylim = error_limits(t, shown, window)
    bottom.set_xlim(*xlim)
    bottom.set_ylim(*ylim)
    bottom.set_xlabel('time [s]' + (' (measured window)' if window is not None else ''))
    bottom.set_ylabel('e [m]')
    bottom.grid(True, lw=0.3)
    bottom.legend(loc='upper center', bbox_to_anchor=(0.5, -0.32), ncol=3, fontsize=7, frameon=False)


def _wind_arrow(top, wind):
    """Where the air moves (the steady wind of ``wind``: wind_x, wind_y [m/s]) as an arrow in the corner of the
    xy panel (axes fraction, x east), with its speed; nothing without wind."""
    wx, wy = float(wind.get('wind_x', 0.0)), float(wind.get('wind_y', 0.0))
    speed = float(np.hypot(wx, wy))
    if speed > 0.0:
        ux, uy = wx / speed, wy / speed
        top.annotate('', xy=(0.88 + 0.08 * ux, 0.14 + 0.08 * uy), xytext=(0.88 - 0.08 * ux, 0.14 - 0.08 * uy),
                     xycoords='axes fraction', arrowprops={'arrowstyle': '->', 'color': 'tab:purple', 'lw': 2})
        top.text(0.88, 0.01, 'wind %.1f m/s' % speed, transform=top.transAxes, ha='center', va='bottom',
                 fontsize=7, color='tab:purple')


def figure_title(title='', wind_line='', failed=None):
    """The title of a run's figure: ``title``, 'FAILED: <reason>' when ``failed`` (a reason, True or '' for none
    given; None = the run did not fail) and the wind's line, one per line."""
    lines = [title] if title else []
    if failed is not None and failed is not False:
        reason = '' if failed is True else ' '.join(str(failed).split())
        if len(reason) > 90:
            reason = reason[:87] + '...'
        lines.append('FAILED' + (': ' + reason if reason else ''))
    if wind_line:
        lines.append(wind_line)
    return '\n'.join(lines)


def run_figure(log, window=None, title='', show_truth=True, wind=None, failed=None):
    """Figure of one run (see the module doc); ``window`` = (t0, t1) s since the first sample or None;
    ``wind``: the run's simulator settings (wind_x, wind_y, gust_std_horizontal, wind_compensation) -> an arrow
    on the xy path and a line under the title (none without wind); ``failed``: the reason of a failed run (True:
    none given): FAILED in the title, in red."""
    text = ''
    if wind:
        from anafi_sim.sim.conditions_profile import wind_text
        text = wind_text(wind)
    heading = figure_title(title, text, failed)
    fig = Figure(figsize=(9.0, 6.0))
    FigureCanvasAgg(fig)
    gs = fig.add_gridspec(3, 2, width_ratios=(1.35, 1.0), hspace=0.12, wspace=0.28,
                          left=0.08, right=0.98, top=0.92 - 0.035 * heading.count('\n') - (0.04 if heading else 0.0),
                          bottom=0.12)
    t = log.t
    k = _decimate(len(t))
    truth = show_truth and has_truth(log)
    axes = []
    for row, axis in enumerate(('x', 'y', 'z')):
        ax = fig.add_subplot(gs[row, 0], sharex=axes[0] if axes else None)
        _shade(ax, window)
        ax.plot(t[::k], log.columns['wp_' + axis][::k], '--', color=COLORS['waypoint'], lw=1.2, label='waypoint')
        ax.plot(t[::k], log.columns[axis + '_anafi'][::k], '-', color=COLORS['estimate'], lw=1.2,
                label='drone (estimate)')
        if truth:
            ax.plot(t[::k], log.columns[axis + '_sphinx'][::k], ':', color=COLORS['truth'], lw=1.2,
                    label='ground truth')
        _min_span(ax, np.concatenate([log.columns['wp_' + axis], log.columns[axis + '_anafi']]), 1.0)
        ax.set_ylabel('%s [m]' % axis)
        ax.grid(True, lw=0.3)
        if row < 2:
            ax.tick_params(labelbottom=False)
        axes.append(ax)
    axes[0].legend(loc='lower left', bbox_to_anchor=(0.0, 1.02), ncol=3, fontsize=7, frameon=False,
                   borderaxespad=0.0)
    axes[-1].set_xlabel('time [s]')

    top = fig.add_subplot(gs[0:2, 1])
    if moves_in_plane(log, window):
        m = window_mask(t, window)
        if m.sum() < 2:
            m = np.ones(len(t), dtype=bool)
        kk = _decimate(int(m.sum()))
        top.plot(log.columns['wp_x'][m][::kk], log.columns['wp_y'][m][::kk], '--', color=COLORS['waypoint'],
                 lw=1.2, label='waypoint')
        top.plot(log.columns['x_anafi'][m][::kk], log.columns['y_anafi'][m][::kk], '-', color=COLORS['estimate'],
                 lw=1.2, label='drone (estimate)')
        if truth:
            top.plot(log.columns['x_sphinx'][m][::kk], log.columns['y_sphinx'][m][::kk], ':',
                     color=COLORS['truth'], lw=1.2, label='ground truth')
        top.set_aspect('equal', adjustable='datalim')
        top.set_xlabel('x [m]', labelpad=1)
        top.set_ylabel('y [m]')
        top.set_title('xy path%s' % (' (measured window)' if window is not None else ''), fontsize=9)
    else:
        _shade(top, window)
        top.plot(t[::k], log.columns['wp_yaw'][::k], '--', color=COLORS['waypoint'], lw=1.2, label='waypoint')
        top.plot(t[::k], np.degrees(log.columns['yaw_anafi'][::k]), '-', color=COLORS['estimate'], lw=1.2,
                 label='drone (estimate)')
        _min_span(top, np.concatenate([log.columns['wp_yaw'], np.degrees(log.columns['yaw_anafi'])]), 20.0)
        top.set_ylabel('yaw [deg]')
        top.set_title('yaw', fontsize=9)
        top.tick_params(labelbottom=False)
    top.grid(True, lw=0.3)

    _error_panel(fig.add_subplot(gs[2, 1]), log, window, truth, k)
    if text:
        _wind_arrow(top, wind)
    if heading:
        fig.suptitle(heading, fontsize=10 if heading.count('\n') == 0 else 9,
                     color='#b00000' if failed is not None and failed is not False else 'black')
    return fig


def comparison_figure(runs, title=''):
    """Figure overlaying runs: ``runs`` = [(label, log, t_offset [s])]; x, y, z, yaw against t - t_offset."""
    fig = Figure(figsize=(9.0, 5.5))
    FigureCanvasAgg(fig)
    axes = [fig.add_subplot(2, 2, i + 1) for i in range(4)]
    fig.subplots_adjust(left=0.08, right=0.98, top=0.9, bottom=0.16, hspace=0.3, wspace=0.25)
    names = (('x', 'x [m]'), ('y', 'y [m]'), ('z', 'z [m]'), ('yaw', 'yaw [deg]'))
    for i, (label, log, offset) in enumerate(runs):
        color = RUN_COLORS[i % len(RUN_COLORS)]
        t = log.t - float(offset)
        k = _decimate(len(t))
        for ax, (axis, _) in zip(axes, names):
            values = log.columns[axis + '_anafi']
            if axis == 'yaw':
                values = np.degrees(np.unwrap(values)) if len(values) else values
            ax.plot(t[::k], values[::k], '-', color=color, lw=1.2, label=label)
            if i == 0 or axis == 'yaw':
                wp = log.columns['wp_' + axis]
                ax.plot(t[::k], wp[::k], '--', color='0.4' if axis != 'yaw' else color, lw=0.8)
    for ax, (_, ylabel) in zip(axes, names):
        ax.set_ylabel(ylabel)
        ax.grid(True, lw=0.3)
        ax.set_xlabel('time [s]')
    fig.legend(*axes[0].get_legend_handles_labels(), loc='lower center', bbox_to_anchor=(0.5, 0.0),
               ncol=min(4, max(1, len(runs))), fontsize=7, frameon=False)
    if title:
        fig.suptitle(title, fontsize=10)
    return fig


def figure_format(path, fmt=None):
    """The format to save ``path`` in: ``fmt`` when given, else the file's extension, else PNG; ValueError for
    one not in ``FORMATS``."""
    if not fmt:
        ext = os.path.splitext(path)[1].lstrip('.').lower()
        fmt = ext if ext in FORMATS else DEFAULT_FORMAT
    fmt = str(fmt).lower()
    if fmt not in FORMATS:
        raise ValueError('figure format %r: one of %s' % (fmt, ', '.join(FORMATS)))
    return fmt


def check_dpi(dpi):
    """``dpi`` as a float when it is a number in ``PARAMETER_RANGES['plot_dpi']``, else ValueError."""
    value = parse_number(dpi)
    problem = 'is not a number' if value is None else range_problem('plot_dpi', value)
    if problem:
        raise ValueError('dpi %r: %s' % (dpi, problem))
    return value


def save(fig, path, dpi=DEFAULT_DPI, fmt=None):
    """Save ``fig`` at ``path`` (directories created) as ``figure_format(path, fmt)``, cropped to what is drawn
    (the legends outside the axes included), ``dpi`` for PNG (and the raster parts of SVG / PDF); returns the
    path."""
    fmt = figure_format(path, fmt)
    dpi = check_dpi(dpi)
    directory = os.path.dirname(os.path.abspath(path))
    if not os.path.isdir(directory):
        os.makedirs(directory)
    with rc_context({'svg.hashsalt': 'anafi_sim'}):      # SVG ids from the content, not random
        fig.savefig(path, dpi=dpi, format=fmt, bbox_inches='tight', pad_inches=0.05, metadata=_NO_DATE[fmt])
    return path


def summary_window(summary):
    """(t0, t1) of an evaluator summary dict's 'window' or None."""
    if not isinstance(summary, dict):
        return None
    w = summary.get('window')
    if isinstance(w, (list, tuple)) and len(w) == 2 and all(isinstance(v, (int, float)) for v in w) \
            and all(math.isfinite(v) for v in w) and w[1] >= w[0]:
        return (float(w[0]), float(w[1]))
    return None


def plot_run(csv_path, out_path, window=None, title='', summary=None, dpi=DEFAULT_DPI, wind=None, fmt=None,
             failed=None):
    """Read ``csv_path``, draw ``run_figure`` (``wind``, ``failed``: see there) and save it to ``out_path``
    (``save``: ``fmt`` or the path's extension); ``window`` defaults to the summary's. Returns the path."""
    log = load(csv_path)
    if len(log) == 0:
        raise ValueError('%s has no samples to plot' % csv_path)
    if window is None:
        window = summary_window(summary)
    if not title and isinstance(summary, dict):
        title = str(summary.get('name') or '')
    return save(run_figure(log, window=window, title=title, wind=wind, failed=failed), out_path, dpi, fmt)


def plot_comparison(runs, out_path, title='', dpi=DEFAULT_DPI, fmt=None):
    """``runs`` = [(label, csv_path, t_offset)]: read each CSV, overlay (``comparison_figure``), save."""
    loaded = [(label, load(path), offset) for label, path, offset in runs]
    return save(comparison_figure(loaded, title=title), out_path, dpi, fmt)
