"""Untrusted text (from a topic, a parameter or a file) made fit for a log line (pure Python).

Anyone who reaches the ROS master can publish or set a parameter, so a node never logs such text whole:
``clip`` keeps at most ``LOG_CHARS`` characters (a repr, so control characters and line breaks cannot forge
further log lines) and says how much was left out. Nodes log such lines throttled (once a second per call
site), so a flood of messages cannot fill the disk either.
"""

#: characters of untrusted text kept in a log line
LOG_CHARS = 300


def clip(value, limit=LOG_CHARS):
    """``repr`` of ``value`` (text as is: its repr) cut to ``limit`` characters, with the size left out."""
    if isinstance(value, bytes):
        value = value.decode('utf-8', 'replace')
    text = repr(value)
    if len(text) <= limit:
        return text
    return '%s... (%d more characters)' % (text[:limit], len(text) - limit)
