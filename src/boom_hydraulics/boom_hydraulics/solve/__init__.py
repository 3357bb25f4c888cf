"""Solving the model over time: integrators, the simulator, command profiles and the stamp rule.

The compiled path (numba) and the batched path (numpy, many parameter sets) live here too.
"""
