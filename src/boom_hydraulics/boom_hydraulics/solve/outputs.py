"""The outputs of a simulation (defined with the model: :mod:`..model.outputs`)."""

from ..model.outputs import BOOLEAN_OUTPUTS, OUTPUT_NAMES, OUTPUTS, PUBLISHED_NAMES, by_name, published

__all__ = ["BOOLEAN_OUTPUTS", "OUTPUTS", "OUTPUT_NAMES", "PUBLISHED_NAMES", "by_name", "published"]
