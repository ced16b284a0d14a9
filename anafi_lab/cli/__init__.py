"""Command-line entry points of the lab (installed as anafi_sim scripts)."""
