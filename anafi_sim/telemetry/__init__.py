"""Sphinx ground-truth telemetry: the tlm-data-logger text protocol, our TCP server and CLI stand-in."""
