"""boom_hydraulics: simulator of the hydraulic boom-lifting drive of a crane-manipulator.

The model core (everything but :mod:`boom_hydraulics.node`) imports no rclpy, so the
ROS node, the headless CLI, tests and parameter studies all drive the same code.
"""

__version__ = "0.1.0"
