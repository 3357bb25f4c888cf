"""The outputs of a simulation (defined with the model: :mod:`..model.outputs`)."""

from ..model.outputs import BOOLEAN_OUTPUTS, OUTPUT_NAMES, OUTPUTS, by_name

__all__ = ["BOOLEAN_OUTPUTS", "OUTPUTS", "OUTPUT_NAMES", "by_name"]
