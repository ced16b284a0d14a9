"""The simulated Anafi (stand-in for Sphinx + firmware + the anafi_ros bridge): dynamics, state estimate, PCMD mapping, pacing."""
