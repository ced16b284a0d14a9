"""The trajectory generator's 'switch NAME' reads scenario files only inside the scenario folders."""
import os

import pytest

from anafi_sim.mission.trajectory import SCENARIO_DIR, load_scenario, scenario_in_folders


def test_names_and_paths_inside_the_folders_are_read(tmp_path):
    own = tmp_path / 'mine'
    own.mkdir()
    (own / 'hover.yaml').write_text(open(os.path.join(SCENARIO_DIR, 'static_wp0.yaml')).read())
    folders = [str(own), SCENARIO_DIR]
    assert scenario_in_folders('hover', folders) == os.path.realpath(str(own / 'hover.yaml'))
    assert load_scenario(scenario_in_folders(str(own / 'hover.yaml'), folders)).name == 'static_wp0'
    shipped = scenario_in_folders(os.path.join(SCENARIO_DIR, 'circle_r2_v1.yaml'), folders)
    assert load_scenario(shipped).name == 'circle_r2_v1'


@pytest.mark.parametrize('request_text', [
    '/etc/passwd', '/etc/hostname.yaml', '../../../../etc/passwd', 'x/../../../../../etc/shadow',
    os.path.join(SCENARIO_DIR, '..', 'sim.yaml'), os.path.join(SCENARIO_DIR, 'README.md'),
])
def test_files_outside_the_folders_are_refused_unread(request_text, tmp_path):
    with pytest.raises(ValueError) as error:
        scenario_in_folders(request_text, [str(tmp_path), SCENARIO_DIR])
    assert str(error.value).startswith('refused:') and 'root:' not in str(error.value)


def test_a_link_out_of_a_folder_is_refused(tmp_path):
    (tmp_path / 'evil.yaml').symlink_to('/etc/passwd')
    with pytest.raises(ValueError, match='refused'):
        scenario_in_folders('evil', [str(tmp_path)])


def test_the_refusal_names_each_folder_once(tmp_path):
    with pytest.raises(ValueError) as error:
        scenario_in_folders('/etc/passwd', [str(tmp_path), SCENARIO_DIR, str(tmp_path), SCENARIO_DIR])
    assert str(error.value).count(os.path.realpath(SCENARIO_DIR)) == 1
