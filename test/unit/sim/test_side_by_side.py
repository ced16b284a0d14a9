"""The rostests run beside other runs on the machine (docs/benchmarks.md, Tests): no fixed port, no fixed path.

- every telemetry_port a rostest sets is 0 (the simulator binds a free port and announces it; the interface
  and the tests read it from ~telemetry_bound_port);
- no rostest script names a literal telemetry endpoint (inet:HOST:PORT with digits) or binds a literal port;
- no rostest, rostest script or launch file names a path under /tmp (tests: tempfile folders of their own,
  fleet.launch out_dir:=""; launch files: ~/.ros or an argument).
"""
import glob
import os
import re
import xml.etree.ElementTree as ET

import pytest

from conftest import ROOT

TEST_FILES = sorted(glob.glob(os.path.join(ROOT, 'test', 'ros', '*.test')))
TEST_SCRIPTS = sorted(glob.glob(os.path.join(ROOT, 'test', 'ros', '*.py')))
LAUNCH_FILES = sorted(glob.glob(os.path.join(ROOT, 'anafi_sim', 'launch', '*.launch')))
LITERAL_ENDPOINT = re.compile(r'inet:[\w.\-]+:\d+')
REFUSED_ATTACK = re.compile(r'refus|reject|hostile|evil|--exec', re.I)
#: a path under /tmp itself (not /var/tmp, the parent a tempfile.mkdtemp may be given)
FIXED_TMP = re.compile(r'(?<![\w.])/tmp\b')
LITERAL_BIND = re.compile(r"""bind\(\(\s*['"][\w.]*['"]\s*,\s*[1-9]\d*\s*\)\)""")


def _name(path):
    return os.path.relpath(path, ROOT)


def test_the_files_are_found():
    assert len(TEST_FILES) > 10 and len(TEST_SCRIPTS) > 10 and len(LAUNCH_FILES) > 10


@pytest.mark.parametrize('path', TEST_FILES, ids=_name)
def test_rostests_take_telemetry_port_zero(path):
    root = ET.parse(path).getroot()
    for element in root.iter():
        if element.get('name') == 'telemetry_port' and element.tag in ('arg', 'param'):
            assert element.get('value') == '0', '%s sets telemetry_port %s: 0 takes a free port' % (
                _name(path), element.get('value'))


@pytest.mark.parametrize('path', TEST_SCRIPTS, ids=_name)
def test_rostest_scripts_name_no_literal_port(path):
    with open(path) as f:      # an attack's command that is refused before it runs connects nowhere
        text = ''.join(line for line in f if not REFUSED_ATTACK.search(line))
    assert not LITERAL_ENDPOINT.findall(text), _name(path)
    assert not LITERAL_BIND.findall(text), _name(path)


@pytest.mark.parametrize('path', TEST_FILES + TEST_SCRIPTS + LAUNCH_FILES, ids=_name)
def test_no_fixed_tmp_path(path):
    with open(path) as f:
        lines = [(n, line) for n, line in enumerate(f, 1) if FIXED_TMP.search(line)]
    assert not lines, '%s names /tmp: %s' % (_name(path), lines)
