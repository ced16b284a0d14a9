"""The second-commander guard names a sender by the publisher its connection was made to (the master's URI),
not by the callerid its header claims."""
from anafi_sim.ros.commander_watch import commander_label

ME, MY_URI, OTHER_URI = '/anafi/mpc_controller', 'http://127.0.0.1:40001/', 'http://127.0.0.1:40002/'


def test_own_commands_are_known_by_the_uri():
    assert commander_label(ME, MY_URI, MY_URI, ME) is None
    assert commander_label('/someone_else', MY_URI, MY_URI, ME) is None     # our own process, whatever it claims


def test_a_forged_callerid_is_a_second_commander():
    label = commander_label(ME, OTHER_URI, MY_URI, ME)
    assert label is not None and OTHER_URI in label and 'claims to be' in label
    assert commander_label('', OTHER_URI, MY_URI, ME) is not None
    assert commander_label('/pid', OTHER_URI, MY_URI, ME) == '/pid'


def test_without_a_known_connection_the_header_is_all_there_is():
    assert commander_label('/pid', None, MY_URI, ME) == '/pid'
    assert commander_label('/pid', 'unknown', MY_URI, ME) == '/pid'
    assert commander_label(ME, None, MY_URI, ME) is None


def test_a_hosted_instance_knows_a_claim_of_its_host_s_name():
    host = '/fleet_drones'      # the name a hosted controller's commands carry on the wire
    label = commander_label(host, OTHER_URI, MY_URI, (ME, host))
    assert label == '%s (claims to be %s)' % (OTHER_URI, host)
    assert commander_label(host, MY_URI, MY_URI, (ME, host)) is None
    assert commander_label(host, None, MY_URI, (ME, host)) is None
    assert commander_label('/pid', OTHER_URI, MY_URI, (ME, None)) == '/pid'
