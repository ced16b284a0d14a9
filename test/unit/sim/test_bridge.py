"""anafi_sim.sim.bridge: the anafi_ros PilotingCommand -> PCMD mapping, quantisation and signs."""
import math

import pytest

from anafi_sim.sim.bridge import MAX_TILT_DEG, PilotingMapping


def test_paper_firmware_settings():
    assert MAX_TILT_DEG == pytest.approx(30.64, abs=0.005)


def test_percent_quantisation_truncates_towards_zero():
    m = PilotingMapping()
    # 15.32 deg = 49.99.. % of 30.64 deg -> 49 (int() truncates, as the bridge does)
    assert m.to_pcmd(0.4999 * MAX_TILT_DEG, 0.0, 0.0, 0.0)[0] == 49
    assert m.to_pcmd(-0.4999 * MAX_TILT_DEG, 0.0, 0.0, 0.0)[0] == -49
    assert m.to_pcmd(0.3, 0.0, 0.0, 0.0)[0] == 0          # below one percent
    assert m.to_pcmd(0.0, 0.0, 0.0, 1.0) == (0, 0, 0, 50)  # 1 m/s of 2 m/s


def test_clamped_to_plus_minus_100():
    m = PilotingMapping()
    assert m.to_pcmd(90.0, -90.0, 1000.0, -10.0) == (100, -100, -100, -100)


def test_yaw_sign_is_flipped_by_the_bridge():
    m = PilotingMapping()
    # positive ROS yaw rate (counter-clockwise) -> negative PCMD yaw (PCMD + = clockwise)
    assert m.to_pcmd(0, 0, 90.0, 0)[2] == -50
    # and back: the firmware setpoint is counter-clockwise positive again
    _, _, yaw_rate, _ = m.command_to_setpoints(0, 0, 90.0, 0)
    assert yaw_rate == pytest.approx(math.radians(90.0))


def test_setpoints_are_quantised_angles_in_radians():
    m = PilotingMapping()
    roll, pitch, yaw_rate, gaz = m.command_to_setpoints(10.0, -5.0, 0.0, 0.7)
    step = math.radians(MAX_TILT_DEG) / 100.0
    assert roll == pytest.approx(32 * step)     # 10/30.64 = 32.6 % -> 32 %
    assert pitch == pytest.approx(-16 * step)   # -5/30.64 = -16.3 % -> -16 %
    assert gaz == pytest.approx(0.7)            # 35 % of 2 m/s


def test_non_finite_commands_map_to_zero():
    m = PilotingMapping()
    assert m.to_pcmd(float('nan'), float('inf'), float('-inf'), float('nan')) == (0, 0, 0, 0)


@pytest.mark.parametrize('kwargs', [dict(max_tilt_deg=0.0), dict(max_vertical_speed=-1.0),
                                    dict(max_yaw_rate_deg=float('nan'))])
def test_bad_settings_refused(kwargs):
    with pytest.raises(ValueError):
        PilotingMapping(**kwargs)
