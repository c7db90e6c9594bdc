"""Readers and writers of robot logs; one entry point :func:`read_log`.

Formats: canonical wide CSV (``.csv``, ``.csv.gz``), any CSV or ``.npz`` through a
channel map, MCAP with impactcli's JSON joint-sample schema, MCAP with ROS 2
``sensor_msgs/msg/JointState``.
"""
