"""Reports: the paper tables, the calibration and fidelity reports (Markdown from computed figures)."""
