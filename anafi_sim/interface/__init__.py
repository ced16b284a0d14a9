"""The paper's Interface: telemetry samples -> ground truth, and the supervised telemetry process."""
