"""``boom-sim live``: a headless run shown and steered live in Foxglove, without ROS.

A Foxglove WebSocket server (the ``foxglove-sdk`` package's, behind :mod:`.relay`, which serves
the protocol under both its subprotocol names) publishes the node's topics as
CDR with their ROS 2 schemas, takes valve commands and target angles on client-published
channels and model parameters through the protocol's parameters capability, and records
the bag the node would. No rclpy: the model core, its stepping and the bags' encoders only.
"""
