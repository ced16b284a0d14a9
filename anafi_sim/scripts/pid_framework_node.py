#!/usr/bin/env python3
"""The paper's PID framework in ONE process: controller_node.py with ~controller pid.

Kept for ``rosrun anafi_sim pid_framework_node.py`` (default node name pid_framework); pid.launch (mode
single) runs controller_node.py itself. The same loops as the distributed framework (pid_relative_state.py
+ six pid_controller.py + pid_command.py), cycles at 30 Hz, commands at 10 Hz. Topics, parameters,
diagnostics: see anafi_sim/nodes/controller_node.py and anafi_sim/config/pid.yaml.
"""
from anafi_sim.nodes.controller_node import main

if __name__ == '__main__':
    main('pid', 'pid_framework')
