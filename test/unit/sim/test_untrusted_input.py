"""Files and text from outside the package: safe paths, file parameters, the bounded YAML loader, clipped logs."""
import os

import pytest
import yaml

from anafi_sim import trusted
from anafi_sim.safe_yaml import load_yaml, load_yaml_text
from anafi_sim.sim.drone_model import DEFAULT_MODEL_FILE, model_file_path
from anafi_sim.untrusted import clip

SECRET = 'the-secret-line-of-the-file'


def _settings(tmp_path, name, lines, mode=0o644):
    folder = tmp_path / 'etc'
    folder.mkdir(exist_ok=True)
    path = folder / name
    path.write_text(''.join(line + '\n' for line in lines))
    path.chmod(mode)
    return str(folder)


def test_safe_paths_need_trusted_owners_and_no_writable_folder(tmp_path):
    folder = tmp_path / 'a'
    folder.mkdir()
    path = folder / 'f'
    path.write_text('x')
    assert trusted.unsafe_reason(str(path)) is None      # /tmp above it: sticky and root-owned
    assert 'owned by uid' in trusted.unsafe_reason(str(path), owners=(12345,))
    folder.chmod(0o777)
    assert 'group- or world-writable' in trusted.unsafe_reason(str(path))
    folder.chmod(0o755)
    path.chmod(0o664)
    assert 'group- or world-writable' in trusted.unsafe_reason(str(path))


def test_the_settings_file_is_read_only_when_safe(tmp_path):
    good = _settings(tmp_path, trusted.DATA_FOLDERS, ['# comment', '/srv/models  # site models', 'relative/ignored'])
    assert trusted.settings_list(trusted.DATA_FOLDERS, owners=(os.getuid(),), directory=good) == ['/srv/models']
    bad = _settings(tmp_path, trusted.DATA_FOLDERS, ['/srv/models'], mode=0o666)
    assert trusted.settings_list(trusted.DATA_FOLDERS, owners=(os.getuid(),), directory=bad) == []
    assert trusted.settings_list(trusted.DATA_FOLDERS, directory=str(tmp_path / 'missing')) == []


def test_model_file_only_from_the_config_folders(tmp_path):
    assert model_file_path('anafi_model.yaml') == os.path.realpath(DEFAULT_MODEL_FILE)
    assert model_file_path(DEFAULT_MODEL_FILE) == os.path.realpath(DEFAULT_MODEL_FILE)
    outside = tmp_path / 'model.yaml'
    outside.write_text(SECRET + ': 1\n')
    for value in (str(outside), '/etc/passwd', '../../package.xml', '../' * 20 + 'etc/shadow'):
        with pytest.raises(ValueError) as error:
            model_file_path(value)
        assert 'refused' in str(error.value) and SECRET not in str(error.value)
    # a folder named in the root-owned settings file
    settings = _settings(tmp_path, trusted.DATA_FOLDERS, [str(tmp_path)])
    assert model_file_path(str(outside), settings_dir=settings) == os.path.realpath(str(outside))


def test_a_symlink_out_of_the_allowed_folders_is_refused(tmp_path):
    allowed = tmp_path / 'allowed'
    allowed.mkdir()
    link = allowed / 'model.yaml'
    os.symlink('/etc/passwd', str(link))
    with pytest.raises(ValueError, match='refused'):
        trusted.file_parameter(str(link), [str(allowed)], 'model_file')


def test_yaml_errors_never_quote_the_file(tmp_path):
    path = tmp_path / 'bad.yaml'
    path.write_text('a: 1\n%s: [unclosed\n' % SECRET)
    with pytest.raises(ValueError) as error:
        load_yaml(str(path))
    text = str(error.value)
    assert 'not valid YAML at line' in text and SECRET not in text and '\n' not in text


def test_an_alias_bomb_is_refused_before_it_is_built():
    lines = ['a0: &a0 [x, x, x, x, x, x, x, x, x, x]']
    for i in range(1, 12):
        lines.append('a%d: &a%d [%s]' % (i, i, ', '.join(['*a%d' % (i - 1)] * 10)))
    with pytest.raises(ValueError, match='aliases are expanded'):
        load_yaml_text('\n'.join(lines), 'bomb')
    with pytest.raises(ValueError, match='aliases are expanded'):
        load_yaml_text('a: &a [*a]', 'cycle')       # a recursive alias: infinite once expanded


def test_size_bound_and_ordinary_documents():
    with pytest.raises(ValueError, match='larger than'):
        load_yaml_text('a: ' + 'x' * 2000, 'big', max_bytes=1000)
    text = 'base: &b {x: 1, y: [1, 2]}\nother: *b\nn: 3.5\n'
    assert load_yaml_text(text) == yaml.safe_load(text)
    assert load_yaml_text('') is None
    with pytest.raises(ValueError):
        load_yaml_text('!!python/object/apply:os.system ["id"]', 'hostile')


def test_clip_keeps_a_few_hundred_characters_on_one_line():
    text = clip('x' * 10 ** 6)
    assert len(text) < 400 and text.endswith('more characters)')
    assert '\n' not in clip('a\nforged log line')
    assert clip('start') == "'start'"


def test_telemetry_binds_loopback_unless_remote_is_allowed():
    from anafi_sim.telemetry.server import checked_bind_host
    for host in ('127.0.0.1', '127.0.0.2', '::1', 'localhost'):
        assert checked_bind_host(host) == host
    for host in ('0.0.0.0', '192.168.1.10', '::', 'example.com'):
        with pytest.raises(ValueError):
            checked_bind_host(host)
    assert checked_bind_host('0.0.0.0', allow_remote=True) == '0.0.0.0'
    assert checked_bind_host('sphinx-pc.local', allow_remote=True) == 'sphinx-pc.local'
    with pytest.raises(ValueError, match='IP address'):
        checked_bind_host('$(id)', allow_remote=True)


def test_a_conditions_parameter_names_a_profile_only_in_the_allowed_folders(tmp_path):
    from anafi_sim.sim.conditions_profile import load_conditions, parameter_folders
    home = tmp_path / 'home'
    home.mkdir()
    profile = home / 'wind.yaml'
    profile.write_text('{}\n')
    assert load_conditions(str(profile)) == {}            # the lab's own command line: any path
    with pytest.raises(ValueError, match='refused'):
        load_conditions(str(profile), [str(tmp_path / 'elsewhere')])
    assert load_conditions(str(profile), parameter_folders()) == {}     # under the temp folder
