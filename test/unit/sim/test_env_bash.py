"""env.bash (written by tools/setup.sh): `source env.bash --extend` keeps a workspace sourced before it (the
paper authors', docs/compat.md), a plain `source env.bash` replaces it."""
import os
import subprocess

import pytest
from conftest import ROOT

ENV = os.path.join(ROOT, 'env.bash')


def prefix_path_after(tmp_path, source_args, caller_args=''):
    other = tmp_path / 'their_ws' / 'devel'
    other.mkdir(parents=True)
    (other / '.catkin').write_text('')
    script = 'set -- %s; export CMAKE_PREFIX_PATH="%s:${CMAKE_PREFIX_PATH:-}"; source "%s" %s; ' \
             'echo "$CMAKE_PREFIX_PATH"' % (caller_args, other, ENV, source_args)
    clean = dict((k, os.environ[k]) for k in ('HOME', 'LANG') if k in os.environ)   # a new shell, nothing sourced
    clean['PATH'] = '/usr/local/bin:/usr/bin:/bin'
    out = subprocess.run(['bash', '-c', script], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                         universal_newlines=True, check=True, env=clean).stdout
    return str(other), out.strip().split(':')


@pytest.mark.skipif(not os.path.isfile(ENV), reason='no env.bash: run make setup')
def test_extend_keeps_the_other_workspace(tmp_path):
    other, paths = prefix_path_after(tmp_path, '--extend')
    assert other in paths
    assert paths[0] == os.path.join(ROOT, '.ws', 'devel')      # ours first: our anafi_control wins


@pytest.mark.skipif(not os.path.isfile(ENV), reason='no env.bash: run make setup')
def test_plain_source_replaces_it(tmp_path):
    other, paths = prefix_path_after(tmp_path, '')
    assert other not in paths
