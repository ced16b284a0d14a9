"""Calibration of the simulated Anafi against reference logs: ``fit`` (the fits), ``report`` (YAML, summary and
Markdown texts), ``plot`` (the replay figure); anafi_sim/scripts/calibrate_model.py wires them to files."""
