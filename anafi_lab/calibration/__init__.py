"""Calibration of the simulated Anafi against reference logs (the fits and the replay figure)."""
