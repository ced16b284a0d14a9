"""The interface's telemetry command: an allow-list of full paths, arguments checked, never a shell."""
import os

import pytest

from anafi_sim.interface.telemetry_command import (KNOWN_TOOLS, SPHINX_TOOL, STAND_IN, allowed_argv, allowed_tools,
                                                   stand_in_paths)
from anafi_sim.trusted import TELEMETRY_TOOLS

STAND_INS = ['/ws/devel/lib/anafi_sim/tlm_data_logger.py']
NO_TOOLS = ([], {}, [])


def _tool(folder, name=SPHINX_TOOL, mode=0o755):
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / name
    path.write_text('#!/bin/true\n')
    path.chmod(mode)
    return str(path)


def _tools(tmp_path, sphinx=(), listed=(), stand_ins=()):
    """allowed_tools with the given Sphinx locations, a settings file listing ``listed`` (owned by this user)."""
    settings = tmp_path / 'etc'
    settings.mkdir(exist_ok=True)
    settings.chmod(0o755)
    (settings / TELEMETRY_TOOLS).write_text('# site tools\n' + ''.join(p + '\n' for p in listed))
    return allowed_tools(stand_ins=list(stand_ins), sphinx_paths=sphinx, settings_dir=str(settings))


def test_sphinx_tool_at_its_install_location_by_name_or_path(tmp_path):
    tool = _tool(tmp_path / 'opt' / 'bin')
    tools = _tools(tmp_path, sphinx=[tool])
    assert allowed_argv('tlm-data-logger -r 0 inet:127.0.0.1:9060', tools) == [tool, '-r', '0', 'inet:127.0.0.1:9060']
    assert allowed_argv([tool, '-r', 10, 'inet:10.0.0.2:9060'], tools) == [tool, '-r', '10', 'inet:10.0.0.2:9060']
    # port 0: the interface puts in the port it learns from ~simulator_node (sim.launch's default command)
    assert allowed_argv('tlm-data-logger -r 0 inet:127.0.0.1:0', tools)[-1] == 'inet:127.0.0.1:0'


def test_a_tool_listed_in_the_settings_file(tmp_path):
    tool = _tool(tmp_path / 'site', 'my-logger')
    tools = _tools(tmp_path, listed=[tool])
    assert allowed_argv([tool, 'inet:127.0.0.1:9060'], tools)[0] == tool


def test_sphinx_by_name_is_refused_when_not_installed():
    with pytest.raises(ValueError) as error:
        allowed_argv('tlm-data-logger inet:127.0.0.1:9060', NO_TOOLS)
    assert 'not installed at an allowed path' in str(error.value)


def test_the_same_file_name_elsewhere_is_refused(tmp_path):
    tool = _tool(tmp_path / 'opt' / 'bin')
    evil = _tool(tmp_path / 'EVIL')
    tools = _tools(tmp_path, sphinx=[tool])
    with pytest.raises(ValueError) as error:
        allowed_argv([evil, 'inet:127.0.0.1:1'], tools)
    assert 'not one of the allowed tools' in str(error.value)


def test_a_symlink_to_elsewhere_and_writable_files_or_folders_are_refused(tmp_path):
    evil = _tool(tmp_path / 'EVIL')
    link_dir = tmp_path / 'opt' / 'bin'
    link_dir.mkdir(parents=True)
    link = str(link_dir / SPHINX_TOOL)
    os.symlink(evil, link)
    world = _tool(tmp_path / 'world', mode=0o757)
    group_dir = tmp_path / 'group'
    group = _tool(group_dir)
    group_dir.chmod(0o775)
    allowed, refused, _ = _tools(tmp_path, sphinx=[link, world, group])
    assert allowed == []
    assert 'symbolic link' in refused[link]
    assert 'group- or world-writable' in refused[world] and 'group- or world-writable' in refused[group]
    with pytest.raises(ValueError) as error:
        allowed_argv([link, 'inet:127.0.0.1:1'], (allowed, refused, []))
    assert 'symbolic link' in str(error.value)


def test_a_settings_file_writable_by_others_is_ignored(tmp_path):
    tool = _tool(tmp_path / 'site', 'my-logger')
    settings = tmp_path / 'etc'
    settings.mkdir()
    (settings / TELEMETRY_TOOLS).write_text(tool + '\n')
    (settings / TELEMETRY_TOOLS).chmod(0o666)
    allowed, _, _ = allowed_tools(stand_ins=[], sphinx_paths=(), settings_dir=str(settings))
    assert allowed == []


def test_the_stand_in_by_name_or_by_the_package_path(tmp_path):
    script = _tool(tmp_path / 'lib' / 'anafi_sim', STAND_IN)
    tools = _tools(tmp_path, stand_ins=[script])
    assert allowed_argv('%s -r 0 inet:127.0.0.1:9061' % STAND_IN, tools) == [script, '-r', '0', 'inet:127.0.0.1:9061']
    assert allowed_argv([script, 'inet:127.0.0.1:9061'], tools)[0] == script


def test_the_package_tools_are_found_and_allowed():
    found = stand_in_paths()
    assert found and all(os.path.basename(p) in KNOWN_TOOLS and os.path.isfile(p) for p in found)
    assert allowed_argv([found[-1], '-r', '0', 'inet:127.0.0.1:9060'])[0] == found[-1]


@pytest.mark.parametrize('command, refused', [
    # a shell, any other program, a pipeline: never run
    ("sh -c 'id > /tmp/pwned'", "refused to run 'sh'"),
    ('bash', "refused to run 'bash'"),
    ('/usr/bin/python3 -c "import os; os.system(\'id\')"', 'refused to run'),
    ('tlm-data-logger -r 0 inet:127.0.0.1:9060 | sh', 'takes [-r MS] inet:HOST:PORT'),
    ('tlm-data-logger -r 0 inet:127.0.0.1:9060; id', 'inet:HOST:PORT'),
    ('$(id) -r 0 inet:127.0.0.1:9060', 'refused to run'),
    # a program that only borrows the stand-in's file name
    ('/tmp/evil/tlm_data_logger.py -r 0 inet:127.0.0.1:9060', 'not one of the allowed tools'),
    ('/tmp/evil/tlm-data-logger -r 0 inet:127.0.0.1:9060', 'not one of the allowed tools'),
    ('../tlm-data-logger inet:127.0.0.1:9060', 'refused to run'),
    # arguments outside the tools' grammar
    ('tlm-data-logger --output /etc/passwd inet:127.0.0.1:9060', 'takes [-r MS] inet:HOST:PORT'),
    ('tlm-data-logger -r -1 inet:127.0.0.1:9060', '-r takes a number'),
    ('tlm-data-logger -r nan inet:127.0.0.1:9060', '-r takes a number'),
    ('tlm-data-logger inet:-oProxyCommand=id:9060', 'the endpoint must be'),
    ('tlm-data-logger inet:127.0.0.1:70000', 'the endpoint must be'),
    ('tlm-data-logger unix:/tmp/socket', 'the endpoint must be'),
    ('tlm-data-logger', 'takes [-r MS] inet:HOST:PORT'),
    ('', 'empty'),
    ('tlm-data-logger "unterminated', 'No closing quotation'),
    ([], 'empty'),
    (['tlm-data-logger', None], 'string or a number'),
    ({'cmd': 'id'}, 'string or a list'),
])
def test_a_hostile_or_unknown_command_is_refused(command, refused):
    with pytest.raises(ValueError) as error:
        allowed_argv(command, ([SPHINX_TOOL] + STAND_INS, {}, STAND_INS))
    assert refused in str(error.value)
