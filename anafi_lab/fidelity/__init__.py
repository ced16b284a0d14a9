"""Fidelity of the stand-in: closed-loop replays of reference logs and the held-out bounds."""
