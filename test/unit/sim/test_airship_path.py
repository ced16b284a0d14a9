"""Airship path of the multi-robot scene: analytic position/velocity, altitude band, heading."""
import math

import numpy as np
import pytest

from anafi_sim.gazebo.airship_path import AirshipPath


@pytest.mark.parametrize('shape', ['figure_eight', 'circle'])
def test_velocity_is_the_derivative_of_the_position(shape):
    path = AirshipPath(shape=shape, size=20.0, period=120.0, altitude=10.0, z_amplitude=1.0, z_period=60.0,
                       center=(15.0, -3.0), phase=0.4)
    h = 1e-4
    for t in np.linspace(0.0, 240.0, 37):
        s = path.state(t)
        numeric = (np.array(path.state(t + h).position) - np.array(path.state(t - h).position)) / (2 * h)
        assert np.allclose(s.velocity, numeric, atol=1e-6)
        yaw_numeric = math.atan2(math.sin(path.state(t + h).yaw - path.state(t - h).yaw),
                                 math.cos(path.state(t + h).yaw - path.state(t - h).yaw)) / (2 * h)
        assert s.yaw_rate == pytest.approx(yaw_numeric, abs=1e-5)


@pytest.mark.parametrize('shape', ['figure_eight', 'circle'])
def test_path_stays_in_the_altitude_band_and_is_periodic(shape):
    path = AirshipPath(shape=shape, altitude=10.0, z_amplitude=1.5, period=120.0, z_period=60.0)
    zs = [path.state(t).position[2] for t in np.linspace(0.0, 120.0, 241)]
    assert min(zs) >= 8.0 and max(zs) <= 12.0
    assert max(zs) - min(zs) == pytest.approx(3.0, abs=0.01)
    assert np.allclose(path.state(7.0).position, path.state(127.0).position, atol=1e-9)


def test_circle_hand_checked():
    path = AirshipPath(shape='circle', size=10.0, period=40.0, altitude=9.0, z_amplitude=0.0, center=(1.0, 2.0))
    s = path.state(10.0)  # a quarter lap from (11, 2): at (1, 12), flying towards -x
    assert s.position == pytest.approx((1.0, 12.0, 9.0), abs=1e-9)
    speed = 2 * math.pi * 10.0 / 40.0
    assert s.velocity == pytest.approx((-speed, 0.0, 0.0), abs=1e-9)
    assert s.yaw == pytest.approx(math.pi)
    assert s.yaw_rate == pytest.approx(2 * math.pi / 40.0)


def test_figure_eight_crosses_the_centre_twice_per_lap():
    path = AirshipPath(shape='figure_eight', size=20.0, period=100.0, z_amplitude=0.0, center=(0.0, 0.0))
    assert path.state(0.0).position[:2] == pytest.approx((0.0, 0.0), abs=1e-9)
    assert path.state(50.0).position[:2] == pytest.approx((0.0, 0.0), abs=1e-9)
    assert path.state(25.0).position[:2] == pytest.approx((20.0, 0.0), abs=1e-9)
    speeds = [np.linalg.norm(path.state(t).velocity[:2]) for t in np.linspace(0, 100, 201)]
    assert max(speeds) < 2.0  # slow: a blimp, at most ~1.8 m/s here


@pytest.mark.parametrize('kwargs', [
    {'shape': 'square'}, {'size': 0.0}, {'period': -1.0}, {'z_period': float('nan')},
    {'altitude': 1.0, 'z_amplitude': 2.0},
])
def test_bad_parameters_are_rejected(kwargs):
    with pytest.raises(ValueError):
        AirshipPath(**kwargs)
