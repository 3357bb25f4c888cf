"""boom_hydraulics: simulator of the hydraulic boom-lifting drive of a crane-manipulator.

One sub-package per concern; only :mod:`boom_hydraulics.ros` imports rclpy (a test holds
this), so the node, the headless tools, tests and studies all drive the same core:

- :mod:`.model`: parameters and params files, the elements (geometry, mechanics,
  hydraulics, friction, end stops) and the two models, paper and physical;
- :mod:`.solve`: integrators, the simulator, valve command profiles and the stamp rule,
  the compiled and the batched paths;
- :mod:`.bags`: writing, reading and recovering rosbag2/MCAP bags, without ROS;
- :mod:`.analysis`: run metrics, plots, the paper's studies;
- :mod:`.sweeps`: design sweeps: sampling, batches, storage, executors, recommendation,
  and the run of a whole sweep;
- :mod:`.resim`: re-simulation of a recorded run with other parameters;
- :mod:`.ros`: the node, its parameters and messages, replay and the demo;
- :mod:`.cli`: the command-line tools' arguments, one module each;
- :mod:`.programs`: what every command-line program shares (one-line errors, exit codes);
- :mod:`.entry_points`: the programs' console scripts, each behind a Ctrl-C guard while it loads.

The floors (top to bottom: entry_points; cli; ros; sweeps | resim; analysis; bags | solve; model;
files | programs; errors) are checked by import-linter (``.importlinter``, ``make lint``).
"""

__version__ = "0.1.0"
