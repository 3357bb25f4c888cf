"""Error classes of boom_hydraulics; each message names what is wrong and how to fix it."""

from __future__ import annotations


class BoomHydraulicsError(Exception):
    """Base class of every error this package raises on purpose."""


class ConfigError(BoomHydraulicsError):
    """A parameter file or parameter value is invalid (unknown key, wrong type, bad range)."""


class SimulationError(BoomHydraulicsError):
    """The integration cannot go on (state left the valid geometry, NaN state, step failure)."""


class BagError(BoomHydraulicsError):
    """A bag cannot be read, or lacks what is asked of it (truncated, live, no such topic)."""


class RecordingError(BoomHydraulicsError):
    """A bag cannot be written (folder exists, unknown message type, disk error)."""
