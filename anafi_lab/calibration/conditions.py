"""Flight conditions and the firmware's wind handling, identified from reference logs (real flights).

Stage: calibration. A real flight has no ground truth: everything here comes from the drone's own estimate
(position, velocity, attitude), the waypoint and the calibrated plant (``anafi_sim/config/anafi_model.yaml``:
attitude loop, drag). Three steps, each rerunnable on new logs (``anafi_lab/cli/calibrate_conditions.py``):

1. ``commands``: the piloting commands the controller sent, recomputed from the log (the paper's PID
   framework at 30 Hz sampled at 10 Hz, or the paper's MPC at 10 Hz, on the logged estimate and waypoint from
   the log's first sample, quantised to PCMD percents as the bridge does).
2. ``firmware_contribution``: the tilt the drone held minus the tilt the commands explain (the commands
   through the calibrated attitude loop: delay + first order), as a world horizontal acceleration
   ``g tan(tilt)``, against the wind's acceleration ``d`` that the log shows (the measured acceleration, a
   Savitzky-Golay derivative of the velocity estimate, minus the held tilt's acceleration plus the calibrated
   drag on the ground speed). ``fit_wind_handling`` fits the firmware's gain K on the hover windows
   (contribution = -K d) and compares candidate structures (``candidates``).
3. ``estimate_conditions``: the steady wind vector (the calibrated drag inverted on the mean of ``d``), the
   gust level (the std of the wind that the held tilt implies, smoothed over ``GUST_SMOOTHING``) and its
   correlation time, and the estimate's noise (position: the rms of the position estimate minus its own
   velocity integrated, high-passed over ``NOISE_WINDOW``; velocity: the rms of the velocity's second
   difference / sqrt(6), white-noise equivalent).

Hover windows: before the waypoint step, and from ``SETTLE`` s after it, where the commanded motion is small
(the controller only holds the point).
"""
import collections
import math

import numpy as np
from scipy.signal import savgol_filter

from anafi_lab.paper import CONTROLLERS
from anafi_lab.calibration.commands import reconstruct_mpc_commands, reconstruct_pid_commands

GRAVITY = 9.81
ACCEL_WINDOW = 9          # samples of the Savitzky-Golay derivative (0.45 s at 20 Hz)
SETTLE = 4.0              # s after the waypoint step before the hover window starts again
EDGE = 0.5                # s dropped at each end of a window (filter edges)
GUST_SMOOTHING = 1.0      # s, moving mean of the tilt-implied wind before its std (cuts the attitude noise)
NOISE_WINDOW = 2.0        # s, high-pass of the position-minus-integrated-velocity residual
TAU_GRID = (0.0, 0.1, 0.2, 0.3, 0.5, 0.75, 1.0, 1.5, 2.0, 3.0)   # s, estimator time constants compared

def controller_of(log):
    """'pid' or 'mpc' from the log's name (``..._pid`` / ``..._mpc``); ValueError otherwise."""
    name = log.name
    for controller in CONTROLLERS:
        if name.endswith('_' + controller):
            return controller
    raise ValueError('%s: the log name does not say the controller (..._pid or ..._mpc)' % name)


def commands(log, controller=None, mapping=None):
    """``commands.CommandTrace`` of the commands the paper's controller (``controller`` or the log's name)
    computed from the logged estimate and waypoint, from the first sample on (the real logs have their waypoint
    from the start): the calibration's one reconstruction (``anafi_lab.calibration.commands``). PID: the
    framework at 30 Hz, sampled at 10 Hz; MPC: one solve every 0.1 s (eq. 15: no memory), roll/pitch at the
    logged yaw. Quantised to whole PCMD percents (the bridge)."""
    controller = controller or controller_of(log)
    if controller == 'pid':
        return reconstruct_pid_commands(log, mapping=mapping, from_start=True)
    if controller == 'mpc':
        return reconstruct_mpc_commands(log, mapping=mapping)
    raise ValueError("controller must be 'pid' or 'mpc', got %r" % (controller,))


def _lowpass(t, u, tau, initial):
    """Exact first order of time constant ``tau`` (0: none) of the zero-order-held ``u`` on the grid ``t``."""
    if tau <= 0.0:
        return np.array(u, dtype=np.float64)
    y = np.empty(len(u))
    y[0] = initial
    for i in range(1, len(u)):
        c = 1.0 - math.exp(-(t[i] - t[i - 1]) / tau)
        y[i] = y[i - 1] + c * (u[i] - y[i - 1])
    return y


def tilt_acceleration(roll, pitch, yaw, gravity=GRAVITY):
    """World horizontal acceleration (ax, ay) [m/s^2] of the thrust that holds the altitude at this attitude."""
    cr, sr = np.cos(roll), np.sin(roll)
    cp, sp = np.cos(pitch), np.sin(pitch)
    cy, sy = np.cos(yaw), np.sin(yaw)
    zx = cy * sp * cr + sy * sr
    zy = sy * sp * cr - cy * sr
    zz = cp * cr
    return gravity * zx / zz, gravity * zy / zz


def drag(vx, vy, model):
    """Calibrated horizontal drag acceleration magnitude factor k(|v|) = drag_linear + drag_quadratic |v|."""
    return model['drag_linear'] + model['drag_quadratic'] * np.hypot(vx, vy)


def wind_speed_for_force(force, model):
    """The wind speed [m/s] whose drag on a drone at rest is ``force`` [m/s^2] (calibrated drag inverted)."""
    a, b = model['drag_quadratic'], model['drag_linear']
    if a <= 0.0:
        return force / b
    return (-b + math.sqrt(b * b + 4.0 * a * force)) / (2.0 * a)


Contribution = collections.namedtuple('Contribution', 't yaw held_x held_y command_x command_y firmware_x '
                                                      'firmware_y wind_x wind_y vx vy hover step')
Contribution.__doc__ = ('The firmware\'s contribution in one log on a uniform 20 Hz grid t [s]: world horizontal '
                        'accelerations [m/s^2] of the held tilt, of the commands through the attitude loop, their '
                        'difference (firmware), the wind\'s acceleration d the log shows, the velocity estimate, '
                        'the hover mask, the waypoint step time [s] (None: no step).')


def waypoint_step(log):
    """Log time [s] of the first waypoint change, None when the waypoint never changes."""
    wp = log.waypoint()
    known = np.all(np.isfinite(wp), axis=1)
    if not known.any():
        return None
    first = int(np.argmax(known))
    changed = known & np.any(wp != wp[first], axis=1)
    return float(log.t[int(np.argmax(changed))]) if changed.any() else None


def firmware_contribution(log, model, controller=None, rate=20.0):
    """``Contribution`` of ``log`` with the calibrated ``model`` dict (anafi_model.yaml)."""
    trace = commands(log, controller)
    t = np.arange(log.t[0], log.t[-1], 1.0 / rate)
    yaw = np.interp(t, log.t, np.unwrap(log.yaw_anafi))
    roll = np.interp(t, log.t, log.roll_anafi)
    pitch = np.interp(t, log.t, log.pitch_anafi)
    vx = np.interp(t, log.t, log.vx_anafi)
    vy = np.interp(t, log.t, log.vy_anafi)
    held_x, held_y = tilt_acceleration(roll, pitch, yaw, model['gravity'])
    index = np.searchsorted(trace.t, t - model['attitude_delay'], side='right') - 1
    ok = index >= 0
    cmd_roll = np.where(ok, trace.roll[np.maximum(index, 0)], 0.0)
    cmd_pitch = np.where(ok, trace.pitch[np.maximum(index, 0)], 0.0)
    tau = model['attitude_time_constant']
    cmd_roll = _lowpass(t, cmd_roll, tau, cmd_roll[0])
    cmd_pitch = _lowpass(t, cmd_pitch, tau, cmd_pitch[0])
    command_x, command_y = tilt_acceleration(cmd_roll, cmd_pitch, yaw, model['gravity'])
    w = ACCEL_WINDOW
    ax = savgol_filter(vx, w, 2, deriv=1, delta=1.0 / rate)
    ay = savgol_filter(vy, w, 2, deriv=1, delta=1.0 / rate)
    vxs = savgol_filter(vx, w, 2)
    vys = savgol_filter(vy, w, 2)
    k = drag(vxs, vys, model)
    wind_x = ax - savgol_filter(held_x, w, 2) + k * vxs
    wind_y = ay - savgol_filter(held_y, w, 2) + k * vys
    step = waypoint_step(log)
    hover = (t >= t[0] + EDGE) & (t <= t[-1] - EDGE)
    for values in (held_x, held_y, command_x, command_y, wind_x, wind_y):
        hover &= np.isfinite(values)
    if step is not None:
        hover &= (t < step - EDGE) | (t >= step + SETTLE)
    return Contribution(t, yaw, held_x, held_y, command_x, command_y, held_x - command_x, held_y - command_y,
                        wind_x, wind_y, vx, vy, hover, step)


# ------------------------------------------------------------------------------------------- wind handling
WindHandlingFit = collections.namedtuple('WindHandlingFit', 'gain gain_stderr time_constant per_log candidates '
                                                            'turns samples')
WindHandlingFit.__doc__ = ('gain K (firmware contribution = -K d, least squares over the hover windows) and its '
                           'standard error, the estimator time constant chosen by the closed-loop replay '
                           '(None here: the open-loop data cannot pick it, see candidates), per log '
                           '{name: dict}, candidates [(name, rms, verdict)], turns [{name, before, after}] '
                           '(world and body-frame contributions before/after a yaw turn), hover samples.')


def _turn_check(c):
    """World and body-frame mean firmware contribution before the step and in the late hover window, with
    the mean yaw of each (a yaw turn between them separates a world-frame from a body-frame structure)."""
    if c.step is None:
        return None
    out = {}
    for label, mask in (('before', c.hover & (c.t < c.step)), ('after', c.hover & (c.t > c.step))):
        if not mask.any():
            return None
        fx, fy, yaw = c.firmware_x[mask], c.firmware_y[mask], c.yaw[mask]
        bx = np.cos(yaw) * fx + np.sin(yaw) * fy
        by = -np.sin(yaw) * fx + np.cos(yaw) * fy
        out[label] = {'world': (float(fx.mean()), float(fy.mean())), 'body': (float(bx.mean()), float(by.mean())),
                      'yaw': float(yaw.mean())}
    return out


def fit_wind_handling(contributions):
    """``WindHandlingFit`` from {name: Contribution} (``firmware_contribution`` of every log)."""
    f, d = [], []
    per_log = collections.OrderedDict()
    turns = []
    for name, c in contributions.items():
        m = c.hover
        fl = np.concatenate([c.firmware_x[m], c.firmware_y[m]])
        dl = np.concatenate([c.wind_x[m], c.wind_y[m]])
        f.append(fl)
        d.append(dl)
        gain = float(-np.dot(fl, dl) / np.dot(dl, dl)) if np.dot(dl, dl) > 0 else float('nan')
        held = np.hypot(c.held_x[m], c.held_y[m])
        cmd = np.hypot(c.command_x[m], c.command_y[m])
        per_log[name] = {'gain': gain, 'held': float(held.mean()), 'commanded': float(cmd.mean()),
                         'firmware': (float(c.firmware_x[m].mean()), float(c.firmware_y[m].mean())),
                         'wind_force': (float(c.wind_x[m].mean()), float(c.wind_y[m].mean())),
                         'samples': int(m.sum())}
        check = _turn_check(c)
        if check is not None and abs(check['after']['yaw'] - check['before']['yaw']) > 2.0:
            check['name'] = name
            turns.append(check)
    f = np.concatenate(f)
    d = np.concatenate(d)
    gain = float(-np.dot(f, d) / np.dot(d, d))
    resid = f + gain * d
    stderr = float(math.sqrt(np.mean(resid ** 2) / np.dot(d, d)))
    return WindHandlingFit(gain, stderr, None, per_log, candidates(contributions, gain, turns), turns, len(f) // 2)


def _rms(values):
    values = np.concatenate(values)
    return float(math.sqrt(np.mean(values ** 2)))


def candidates(contributions, gain, turns, taus=TAU_GRID):
    """[(candidate, rms [m/s^2] of the firmware contribution it leaves unexplained on the hover windows,
    verdict)] for the structures the data can tell apart."""
    out = []
    none = [np.concatenate([c.firmware_x[c.hover], c.firmware_y[c.hover]]) for c in contributions.values()]
    out.append(('no firmware contribution (the commands explain the tilt)', _rms(none),
                'rejected: the drone holds its tilt into the wind under near-zero commands'))
    constant = [np.concatenate([c.firmware_x[c.hover] - c.firmware_x[c.hover].mean(),
                                c.firmware_y[c.hover] - c.firmware_y[c.hover].mean()])
                for c in contributions.values()]
    out.append(('a constant world tilt per log (steady wind, no gust tracking)', _rms(constant),
                'the floor of what an estimator slower than the gusts leaves'))
    for tau in taus:
        parts = []
        for c in contributions.values():
            for fw, dw in ((c.firmware_x, c.wind_x), (c.firmware_y, c.wind_y)):
                est = _lowpass(c.t, -gain * dw, tau, float(np.mean(-gain * dw[c.hover])))
                parts.append((fw - est)[c.hover])
        out.append(('world-frame wind estimator, K %.2f, tau %.2f s' % (gain, tau), _rms(parts),
                    'open-loop: the derivative noise of d dominates (see text)'))
    for check in turns:
        b, a = check['before'], check['after']
        world = math.hypot(a['world'][0] - b['world'][0], a['world'][1] - b['world'][1])
        body = math.hypot(a['body'][0] - b['body'][0], a['body'][1] - b['body'][1])
        out.append(('%s: world-frame contribution kept through the yaw turn' % check['name'], world,
                    'difference after - before [m/s^2] (a world-frame estimator keeps it)'))
        out.append(('%s: body-frame contribution kept through the yaw turn' % check['name'], body,
                    'difference after - before [m/s^2] (a body-frame integrator keeps this one)'))
    return out


# -------------------------------------------------------------------------------------------- conditions
Conditions = collections.namedtuple('Conditions', 'name wind wind_speed wind_force gust_std gust_time_constant '
                                                  'position_noise velocity_noise tilt_mean tilt_std samples')
Conditions.__doc__ = ('Flight conditions of one log: wind (x, y) [m/s, world ENU, where the air moves to], its '
                      'speed, the mean wind acceleration on the drone (x, y) [m/s^2], gust std [m/s] (per '
                      'horizontal axis) and correlation time [s], estimate noise: position [m], velocity [m/s], '
                      'the held tilt in the hover windows: mean, std [rad], hover samples.')


def _moving_mean(values, n):
    if n <= 1:
        return values
    kernel = np.ones(n) / n
    return np.convolve(values, kernel, mode='same')


def correlation_time(values, rate):
    """Time [s] at which the autocorrelation of ``values`` falls below 1/e."""
    v = values - values.mean()
    if not np.any(v):
        return 0.0
    ac = np.correlate(v, v, 'full')[len(v) - 1:] / np.dot(v, v)
    below = np.nonzero(ac < math.exp(-1.0))[0]
    return float(below[0]) / rate if below.size else float(len(v)) / rate


def estimate_conditions(log, model, contribution=None, rate=20.0):
    """``Conditions`` of ``log`` (``contribution``: its ``firmware_contribution``, computed when None)."""
    c = contribution if contribution is not None else firmware_contribution(log, model, rate=rate)
    m = c.hover
    fx, fy = float(c.wind_x[m].mean()), float(c.wind_y[m].mean())
    force = math.hypot(fx, fy)
    speed = wind_speed_for_force(force, model)
    # the air moves where the drag pushes the drone
    wind = (speed * fx / force, speed * fy / force) if force > 0 else (0.0, 0.0)
    # gusts: the wind the held tilt (minus the commands) implies, sample by sample, smoothed
    n = max(1, int(round(GUST_SMOOTHING * rate)))
    gusts, taus = [], []
    for f_axis in (c.firmware_x, c.firmware_y):
        implied = _moving_mean(f_axis, n)
        segments = _segments(m)
        for a, b in segments:
            if b - a < 2 * n:
                continue
            seg = implied[a + n // 2:b - n // 2]
            k = model['drag_linear'] + 2.0 * model['drag_quadratic'] * speed     # d(force)/d(wind) at the steady wind
            gusts.append((seg - seg.mean()) / k)
            taus.append(correlation_time(seg, rate))
    gust = float(np.sqrt(np.mean(np.concatenate(gusts) ** 2))) if gusts else 0.0
    gust_tau = float(np.median(taus)) if taus else 0.0
    # estimate noise
    pos_noise, vel_noise = _estimate_noise(log, m, c.t, rate)
    held = np.hypot(np.interp(c.t, log.t, log.roll_anafi), np.interp(c.t, log.t, log.pitch_anafi))[m]
    return Conditions(log.name, wind, speed, (fx, fy), gust, gust_tau, pos_noise, vel_noise, float(held.mean()),
                      float(held.std()), int(m.sum()))


def _segments(mask):
    """[(start, end)] index ranges where ``mask`` holds."""
    out, start = [], None
    for i, v in enumerate(mask):
        if v and start is None:
            start = i
        elif not v and start is not None:
            out.append((start, i))
            start = None
    if start is not None:
        out.append((start, len(mask)))
    return out


def _estimate_noise(log, mask, t, rate):
    """(position noise [m], velocity noise [m/s]) of the estimate on the hover windows (module doc)."""
    n = max(3, int(round(NOISE_WINDOW * rate)))
    pos, vel = [], []
    for axis in ('x', 'y'):
        p = np.interp(t, log.t, log.columns['%s_anafi' % axis])
        v = np.interp(t, log.t, log.columns['v%s_anafi' % axis])
        for a, b in _segments(mask):
            if b - a < 2 * n:
                continue
            ps, vs = p[a:b], v[a:b]
            integrated = ps[0] + np.concatenate([[0.0], np.cumsum(0.5 * (vs[1:] + vs[:-1]) / rate)])
            r = ps - integrated
            r = r - _moving_mean(r, n)
            pos.append(r[n:-n])
            vel.append(np.diff(vs, 2) / math.sqrt(6.0))
    p = float(np.sqrt(np.mean(np.concatenate(pos) ** 2))) if pos else float('nan')
    v = float(np.sqrt(np.mean(np.concatenate(vel) ** 2))) if vel else float('nan')
    return p, v


def combine(conditions):
    """One set of conditions from several logs' (``Conditions``): the mean wind vector, the rms gust std, the
    median correlation time and the rms noises. {key: value}."""
    c = list(conditions)
    wx = float(np.mean([x.wind[0] for x in c]))
    wy = float(np.mean([x.wind[1] for x in c]))
    return collections.OrderedDict((
        ('wind_x', wx), ('wind_y', wy), ('wind_speed', math.hypot(wx, wy)),
        ('gust_std_horizontal', float(math.sqrt(np.mean([x.gust_std ** 2 for x in c])))),
        ('gust_time_constant', float(np.median([x.gust_time_constant for x in c]))),
        ('position_noise', float(math.sqrt(np.mean([x.position_noise ** 2 for x in c])))),
        ('velocity_noise', float(math.sqrt(np.mean([x.velocity_noise ** 2 for x in c])))),
        ('tilt_mean', float(np.mean([x.tilt_mean for x in c]))),
    ))


# ------------------------------------------------------------------------------------ closed-loop replays
HOLD_WINDOW = 4.0         # s, the hold error: mean e over the log's last seconds
REPLAY_STATS = ('e_mu', 'e_max', 'tilt_mean', 'e_hold')


def log_figures(log):
    """{e_mu, e_max [m]: the paper's e = |wp - p_anafi| (3-D, garbage excluded); tilt_mean [rad]: the mean
    of hypot(roll, pitch) of the estimate; e_hold [m]: mean e over the last ``HOLD_WINDOW`` s} of a log."""
    from anafi_sim.mission.reference_log import tracking_error
    te = tracking_error(log, 'anafi', exclude_garbage=True)
    e = np.linalg.norm(log.waypoint()[:, :3] - log.position('anafi'), axis=1)
    late = log.t >= log.t[-1] - HOLD_WINDOW
    ok = np.isfinite(e)
    tilt = np.hypot(log.roll_anafi, log.pitch_anafi)
    return collections.OrderedDict((('e_mu', float(te.stats.mean)), ('e_max', float(te.stats.max)),
                                    ('tilt_mean', float(np.nanmean(tilt))),
                                    ('e_hold', float(np.mean(e[late & ok])) if (late & ok).any() else float('nan'))))


def replay_real(log, settings, seed=0, model_params=None):
    """Closed-loop replay of a real log with the fidelity method (``anafi_lab.engine.replay``: the
    log's waypoint stream to its controller on the stand-in, resampled at the log's times) under the
    simulator ``settings`` (wind, gusts, wind handling); no initial state (a real log has no ground truth:
    the drone starts settled at its hover point) and no stall replay. (figures of the replay (``log_figures``)
    or None, error text)."""
    from anafi_lab.engine import replay as fidelity
    plan = fidelity.replay_plan(log, initial_state=False, stalls=False)
    variant = None
    if model_params is not None:
        variant = fidelity.Variant('conditions', 'conditions', model_params, None, None, None, None)
    rep = fidelity.run_replay(plan, variant, seed=seed, settings=settings)
    if not rep.ok:
        return None, rep.error
    return log_figures(rep.standin), ''


# ---------------------------------------------------------------------------------- the closed-loop fit
TAU_W_GRID = (0.1, 0.25, 0.5, 1.0, 2.0)  # s, wind_compensation_time_constant candidates
GUST_GRID = (0.5, 1.0, 1.5, 2.0)         # m/s, gust_std_horizontal candidates
SCORED = ('e_mu', 'tilt_mean', 'e_hold')  # the cells the fit scores (e_max is the step's size in every log)
BAND = 0.25                              # the +-25 % band of the replays


def profile_settings(wind, gust_std, gust_time_constant, gain, time_constant):
    """The simulator settings (sim.yaml keys) of a set of conditions."""
    return collections.OrderedDict((
        ('wind_x', round(float(wind[0]), 3)), ('wind_y', round(float(wind[1]), 3)), ('wind_z', 0.0),
        ('gust_std_horizontal', round(float(gust_std), 3)), ('gust_std_vertical', 0.0),
        ('gust_time_constant', round(float(gust_time_constant), 3)),
        ('wind_compensation', round(float(gain), 3)), ('wind_compensation_time_constant', float(time_constant)),
    ))


def _replay_job(args):
    path, settings, seed = args
    from anafi_sim.mission.reference_log import read_log
    figures, error = replay_real(read_log(path), settings, seed=seed)
    return figures, error


def replay_grid(logs, settings_list, seeds, workers=1):
    """{(index in settings_list, log name): [figures per seed]} of closed-loop replays (None: a failed run)."""
    jobs, keys = [], []
    for i, settings in enumerate(settings_list):
        for log in logs:
            for seed in seeds:
                jobs.append((log.path, dict(settings), seed))
                keys.append((i, log.name))
    if workers > 1:
        import multiprocessing
        with multiprocessing.get_context('spawn').Pool(workers) as pool:
            results = pool.map(_replay_job, jobs, chunksize=1)
    else:
        results = [_replay_job(job) for job in jobs]
    out = collections.OrderedDict()
    for key, (figures, error) in zip(keys, results):
        out.setdefault(key, []).append(figures)
    return out


def store_text(settings_list, seeds, grid, command):
    """YAML of the closed-loop replays (``replay_grid``) with the settings and seeds that made them."""
    import yaml
    data = {'command': command, 'settings': [dict(s) for s in settings_list], 'seeds': list(seeds),
            'replays': [{'settings': i, 'log': name, 'figures': [dict(f) if f is not None else None for f in runs]}
                        for (i, name), runs in grid.items()]}
    return yaml.safe_dump(data, default_flow_style=False, sort_keys=False)


def grid_from_store(data):
    """The ``replay_grid`` result of a ``store_text`` YAML (already parsed)."""
    out = collections.OrderedDict()
    for entry in data['replays']:
        out[(int(entry['settings']), entry['log'])] = [
            collections.OrderedDict(f) if f is not None else None for f in entry['figures']]
    return out


def seed_means(runs):
    """{stat: (mean, min, max)} over the seeds' figures (failed runs skipped); None when none ran."""
    ok = [r for r in runs if r is not None]
    if not ok:
        return None
    return collections.OrderedDict((k, (float(np.mean([r[k] for r in ok])), float(min(r[k] for r in ok)),
                                        float(max(r[k] for r in ok)))) for k in REPLAY_STATS)


def score(grid, index, references, stats=SCORED):
    """(mean |ln(replay / log)| over ``stats`` x logs, cells within +-BAND, cells) of one grid entry."""
    logs_ = [name for (i, name) in grid if i == index]
    errs, inside, total = [], 0, 0
    for name in logs_:
        means = seed_means(grid[(index, name)])
        for stat in stats:
            total += 1
            if means is None:
                errs.append(float('inf'))
                continue
            ratio = means[stat][0] / references[name][stat]
            errs.append(abs(math.log(ratio)))
            inside += abs(ratio - 1.0) <= BAND
    return float(np.mean(errs)) if errs else float('inf'), inside, total


# ------------------------------------------------------------------------------------------- the report
def profile_text(settings, combined, handling, command):
    """The conditions profile YAML: simulator settings (sim.yaml keys) with their provenance."""
    comments = {
        'wind_x': 'm/s, world ENU (where the air moves to): the drag-equivalent steady wind of the real logs',
        'wind_y': 'm/s (combined: mean wind vector of the four logs, %.2f m/s)' % combined['wind_speed'],
        'wind_z': 'm/s, not identified (none)',
        'gust_std_horizontal': 'm/s, closed-loop fit (the tilt alone indicates %.2f m/s)'
                               % combined['gust_std_horizontal'],
        'gust_std_vertical': 'm/s, not identified (none)',
        'gust_time_constant': 's, correlation time of the tilt-implied wind',
        'wind_compensation': '-, K: -firmware contribution / wind push, hover windows (+-%.3f)' % handling.gain_stderr,
        'wind_compensation_time_constant': 's, the wind estimate\'s first order: closed-loop fit',
    }
    lines = ['# Flight conditions "real_flights": the paper\'s outdoor flights (anafi_sim/data/reference_logs/real).',
             '# Generated by %s - do not edit by hand, rerun it.' % command,
             '# Simulator settings (anafi_sim/config/sim.yaml keys): the wind, the gusts and the firmware\'s wind',
             '# handling identified from the real logs (docs/calibration.md, "Real flights"). The real estimate\'s',
             '# noise (position %.4f m, velocity %.4f m/s) is below the quantisation the model already has: not'
             % (combined['position_noise'], combined['velocity_noise']),
             '# added. Used by experiment.py --conditions real_flights and conditions:=real_flights of the launch',
             '# files.']
    for key, value in settings.items():
        lines.append('%s: %r  # %s' % (key, value, comments.get(key, '')))
    return '\n'.join(lines) + '\n'
