"""Calibration: fitting model parameters so that a re-simulation of a recorded bag matches its
recorded signals (the library side of ``boom-calibrate``; see :mod:`.fit`)."""
