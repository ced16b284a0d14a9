"""Stage: controller -> piloting command. One drone, one commander: the rule for a second one (pure, no ROS).

A drone obeys every piloting command it receives, from anyone: two controllers on one command topic
interleave their commands (each undoing the other's), and the drone flies neither. ``CommanderGuard`` is
the rule a commanding node applies, fed with the commands it hears on its own command topic from OTHER
nodes (``on_command(caller, t)``, t [s] of a monotonic clock):

* Detection: a command from another node -> ``check(t)`` says ``DOWN``: the node sends no command (the
  firmware's hover brake stops and holds the drone, as for any SILENT failsafe), reports ERROR naming the
  other node, and counts (``episodes``: times it stood down, ``foreign_commands``).
* Policy "one commander; stand down until the other is gone": the guard stays down while another node was
  heard within ``quiet_time`` s OR is still ``present`` (the node tells: the other node still runs and
  still publishes the topic, ``set_present``). What follows:

  - a controller started on a drone that another node already commands hears those commands before its
    own first one (it listens ``listen_time`` s after its first ``check`` before it may command: ``LISTEN``)
    and never commands (ERROR); the one that was commanding goes on;
  - an operator who takes over (a teleop publishing the command topic) gets the drone: our controller
    yields at once and resumes ``quiet_time`` s after the operator's node is gone;
  - two of our controllers that start commanding at the same moment both stand down: the drone brakes and
    stays braked until one of them is stopped.
* ``check(t)`` says ``RESUMED`` once per episode, at the first cycle after it: the node resets its
  controller (no integral or cumulative error carried over from before).
"""

CLEAR, DOWN, RESUMED, LISTEN = 'clear', 'down', 'resumed', 'listen'


class CommanderGuard(object):
    def __init__(self, quiet_time=2.0, listen_time=1.0):
        if not quiet_time > 0:
            raise ValueError('quiet_time must be > 0 s, got %r' % (quiet_time,))
        if not listen_time >= 0:
            raise ValueError('listen_time must be >= 0 s, got %r' % (listen_time,))
        self.quiet_time = float(quiet_time)
        self.listen_time = float(listen_time)
        self._listen_until = None
        self.heard = {}          # other node -> last time [s] a command of it was heard
        self.present = {}        # other node -> True while it still runs and publishes the topic
        self.episodes = 0
        self.foreign_commands = 0
        self._down = False

    def on_command(self, caller, t):
        """A command from node ``caller`` (not this one) heard at ``t``."""
        self.foreign_commands += 1
        self.heard[caller] = t
        self.present[caller] = True

    def set_present(self, caller, present):
        """Whether node ``caller`` still runs and still publishes the command topic (checked by the node)."""
        if caller in self.heard:
            self.present[caller] = bool(present)

    def others(self, t):
        """The other commanders that keep this node down at ``t`` (sorted names)."""
        return sorted(c for c, last in self.heard.items()
                      if t - last < self.quiet_time or self.present.get(c, False))

    def check(self, t):
        """``LISTEN`` (the first ``listen_time`` s: send no command yet, not an error), ``DOWN`` (send no
        command), ``RESUMED`` (the first cycle after an episode: reset the controller, then command) or
        ``CLEAR``; counts the episodes and forgets the nodes that are gone."""
        if self._listen_until is None:
            self._listen_until = t + self.listen_time
        if self.others(t):
            if not self._down:
                self.episodes += 1
            self._down = True
            return DOWN
        if self._down:
            self._down = False
            self.heard.clear()
            self.present.clear()
            return RESUMED
        return LISTEN if t < self._listen_until else CLEAR

    @property
    def down(self):
        """The last ``check`` said DOWN."""
        return self._down
