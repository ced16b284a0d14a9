"""Helpers shared by the rostest nodes in this folder (imported next to them)."""
import time
import xmlrpc.client

import rosgraph
import rosnode


def wait_for(predicate, timeout, step=0.05):
    """Poll ``predicate`` every ``step`` s of wall time until it is true or ``timeout`` s passed; its last value."""
    deadline = time.time() + timeout
    while time.time() < deadline:
        if predicate():
            return True
        time.sleep(step)
    return predicate()


def node_pid(name, caller='/rostest_helpers'):
    """Process id of the ROS node ``name``, or None when it is not registered or does not answer."""
    uri = rosnode.get_api_uri(rosgraph.Master(caller), name, skip_cache=True)
    if not uri:
        return None
    try:
        code, _, pid = xmlrpc.client.ServerProxy(uri).getPid(caller)
    except (OSError, xmlrpc.client.Error):
        return None
    return pid if code == 1 else None
