"""ROS glue shared by the nodes (the one place besides scripts/ that imports rospy).

Stage: node wiring only (parameters, /diagnostics, start-up); no math, no models.
"""
