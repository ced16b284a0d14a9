"""anafi_lab: the offline laboratory of anafi_sim (in-process engine, batches and sweeps, calibration, fidelity replays, reports). No rospy; nothing in anafi_sim imports it."""
