"""ROS glue shared by the nodes (with the nodes, nodes/, and their scripts, scripts/, the only places that import rospy).

Stage: node wiring only (parameters, /diagnostics, start-up); no math, no models.
"""
