#!/usr/bin/env python3
"""The paper's MPC tracking controller (Sec. III-E) for one drone: controller_node.py with ~controller mpc.

Kept for ``rosrun anafi_sim mpc_controller.py`` (default node name mpc_controller); mpc.launch runs
controller_node.py itself. Topics, parameters, diagnostics: see anafi_sim/nodes/controller_node.py and
anafi_sim/config/mpc.yaml.
"""
from anafi_sim.nodes.controller_node import main

if __name__ == '__main__':
    main('mpc', 'mpc_controller')
