#!/usr/bin/env python3
"""The paper's MPC tracking controller (Sec. III-E) for one drone: controller_node.py with ~controller mpc.

Kept for ``rosrun anafi_sim mpc_controller.py`` (default node name mpc_controller); mpc.launch runs
controller_node.py itself. Topics, parameters, diagnostics: see controller_node.py and
anafi_sim/config/mpc.yaml.
"""
import os
import runpy

if __name__ == '__main__':
    runpy.run_path(os.path.join(os.path.dirname(os.path.abspath(__file__)), 'controller_node.py'))['main'](
        'mpc', 'mpc_controller')
