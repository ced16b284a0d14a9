"""bench_interface.py's telemetry: ground-truth samples of a simulated flight, rounded as the telemetry prints them."""
import math

from anafi_sim.sim.drone_model import AnafiModel, load_model_params


def flight_samples(n, seed=1):
    """``n`` varied ground-truth samples, 10 ms apart, of the model flying changing PCMDs."""
    model = AnafiModel(load_model_params(), seed=seed)
    model.reset(x=1.0, y=-2.0, z=5.0, yaw=0.3, flying=True)
    dt, t, out = 0.005, 0.0, []
    k = 0
    while len(out) < n:
        if k % 10 == 0:  # 20 Hz PCMD, slowly varying
            model.set_command(int(30 * math.sin(0.7 * t)), int(25 * math.cos(0.5 * t)),
                              int(20 * math.sin(0.3 * t)), int(15 * math.sin(0.9 * t)), t)
            model.set_gimbal_pitch(0.3 + 0.2 * math.sin(0.2 * t))
        model.step(dt, t)
        t += dt
        k += 1
        if k % 2 == 0:
            out.append(model.truth_sample(t))
    return out


def rounded(value):
    """A value as the interface sees it after ``format_sample`` (9 significant digits)."""
    return float('%.9g' % value)
