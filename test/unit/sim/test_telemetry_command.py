"""The interface's telemetry command: an allow-list of the known tools, arguments checked, never a shell."""
import os

import pytest

from anafi_sim.interface.telemetry_command import SPHINX_TOOL, STAND_IN, allowed_argv, stand_in_paths

STAND_INS = ['/ws/devel/lib/anafi_sim/tlm_data_logger.py']


def test_the_sphinx_tool_and_its_arguments_are_passed_as_a_list():
    assert allowed_argv('tlm-data-logger -r 0 inet:127.0.0.1:9060') == [SPHINX_TOOL, '-r', '0', 'inet:127.0.0.1:9060']
    assert allowed_argv(['tlm-data-logger', 'inet:localhost:9060']) == [SPHINX_TOOL, 'inet:localhost:9060']
    # port 0: the interface puts in the port it learns from ~simulator_node (sim.launch's default command)
    assert allowed_argv('tlm-data-logger -r 0 inet:127.0.0.1:0')[-1] == 'inet:127.0.0.1:0'
    assert allowed_argv(['/opt/parrot-sphinx/usr/bin/tlm-data-logger', '-r', 10, 'inet:10.0.0.2:9060']) == \
        ['/opt/parrot-sphinx/usr/bin/tlm-data-logger', '-r', '10', 'inet:10.0.0.2:9060']


def test_the_stand_in_by_name_or_by_the_package_path(tmp_path):
    script = tmp_path / 'lib' / 'anafi_sim' / STAND_IN
    script.parent.mkdir(parents=True)
    script.write_text('#!/bin/true\n')
    real = [os.path.realpath(str(script))]
    assert allowed_argv('%s -r 0 inet:127.0.0.1:9061' % STAND_IN, real) == [real[0], '-r', '0', 'inet:127.0.0.1:9061']
    assert allowed_argv([str(script), 'inet:127.0.0.1:9061'], real)[0] == str(script)


def test_the_package_stand_in_is_found():
    found = stand_in_paths()
    assert found and all(os.path.basename(p) == STAND_IN and os.path.isfile(p) for p in found)
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
    ('/tmp/evil/tlm_data_logger.py -r 0 inet:127.0.0.1:9060', "is not the package's stand-in"),
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
        allowed_argv(command, STAND_INS)
    assert refused in str(error.value)
