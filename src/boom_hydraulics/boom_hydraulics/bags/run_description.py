"""The run description: what a bag of boom_sim carries so that its run can be simulated again.

The node writes it into the bag's custom data (the MCAP metadata record
``boom_hydraulics`` and metadata.yaml's ``custom_data``), boom-resim writes it into the
bag it makes and reads it back to re-simulate. Custom data are strings; the keys and
their text are fixed, so that every bag recorded so far keeps re-simulating:

- ``parameters``: the parameters as YAML, in the schema's order (a bag of an earlier model
  may hold names this version no longer has);
- ``clock_origin_ns``: the stamp of simulated time 0 on the node's clock (0 with
  publish_clock, whose stamps are simulated time), a decimal integer;
- ``publish_rate_hz`` and ``command_timeout_s``: Python float ``repr``;
- ``node``: the recording node's fully qualified name (bags of the node);
- ``events_topic``: the topic of the node's run events (bags.run_events), all of which the
  bag holds (bags of the node since it records them; boom-resim's copy them);
- ``clock`` and ``real_time_factor``: the clock the node followed (``system``, ``published``
  or ``followed``: its ClockMode) and its real-time factor at the start (Python float repr);
  with ``system`` at a factor other than 1 a state is stamped with the time it was published;
- ``resimulated_from``: the bag a boom-resim bag was re-simulated from.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import yaml

from ..model.parameters import Parameters, as_dict


@dataclass(frozen=True)
class RunDescription:
    """A recorded run's parameters, time origin, publish rate and command timeout."""

    parameters: dict[str, Any]  # name -> value, as recorded
    clock_origin_ns: int
    publish_rate_hz: float
    command_timeout_s: float
    node: str | None = None
    resimulated_from: str | None = None
    events_topic: str | None = None
    clock: str | None = None
    real_time_factor: float | None = None

    @classmethod
    def of(
        cls,
        params: Parameters,
        clock_origin_ns: int,
        publish_rate_hz: float,
        command_timeout_s: float,
        *,
        node: str | None = None,
        resimulated_from: str | None = None,
        events_topic: str | None = None,
        clock: str | None = None,
        real_time_factor: float | None = None,
    ) -> RunDescription:
        """The description of a run with ``params``."""
        return cls(
            as_dict(params),
            clock_origin_ns,
            publish_rate_hz,
            command_timeout_s,
            node,
            resimulated_from,
            events_topic,
            clock,
            real_time_factor,
        )

    def to_custom_data(self) -> dict[str, str]:
        """The bag's custom data (the keys and texts above, in this order)."""
        custom = {
            "parameters": yaml.safe_dump(self.parameters, sort_keys=False),
            "clock_origin_ns": str(self.clock_origin_ns),
            "publish_rate_hz": repr(self.publish_rate_hz),
            "command_timeout_s": repr(self.command_timeout_s),
        }
        if self.node is not None:
            custom["node"] = self.node
        if self.resimulated_from is not None:
            custom["resimulated_from"] = self.resimulated_from
        if self.events_topic is not None:
            custom["events_topic"] = self.events_topic
        if self.clock is not None:
            custom["clock"] = self.clock
        if self.real_time_factor is not None:
            custom["real_time_factor"] = repr(self.real_time_factor)
        return custom

    @classmethod
    def from_custom_data(cls, custom: Mapping[str, str]) -> RunDescription:
        """The description in a bag's custom data. Raises KeyError (a key missing), ValueError
        (a number that does not read as one) or yaml.YAMLError (parameters that do not parse)."""
        return cls(
            parameters=yaml.safe_load(custom["parameters"]),
            clock_origin_ns=int(custom["clock_origin_ns"]),
            publish_rate_hz=float(custom["publish_rate_hz"]),
            command_timeout_s=float(custom["command_timeout_s"]),
            node=custom.get("node"),
            resimulated_from=custom.get("resimulated_from"),
            events_topic=custom.get("events_topic"),
            clock=custom.get("clock"),
            real_time_factor=float(custom["real_time_factor"]) if "real_time_factor" in custom else None,
        )

    @staticmethod
    def origin_in(custom: Mapping[str, str]) -> int | None:
        """The time origin alone, from custom data that may hold nothing else (None without it)."""
        return int(custom["clock_origin_ns"]) if "clock_origin_ns" in custom else None
