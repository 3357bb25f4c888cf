"""``boom-sim live``: the Foxglove WebSocket server of a live run, until Ctrl-C.

The server is the ``foxglove-sdk`` package's (the protocol's v1 message set): it advertises
:data:`.channels.OUTLETS`, takes client channels (``clientPublish``, JSON or CDR) for the
steering topics of :mod:`.steering`, and serves the model parameters (``parameters``,
``parametersSubscribe``). It listens on this machine's loopback, on a free port; clients
reach it through a :class:`.relay.Relay` on the address asked for, which serves the
protocol under both its names (``foxglove.sdk.v1``, the SDK's, and ``foxglove.websocket.v1``,
its first, which the SDK's server alone refuses). The run ticks in a
thread of its own; the main thread waits for it, so that a Ctrl-C (or SIGTERM) lands there,
ends the ticks between two of them, stops the server and finishes the bag. From the first
signal on, another one cannot cut that short: it is told to wait. Exit statuses: 0 stopped
(the bag finished), 1 the recording failed (the bag is left for boom-bag-recover), 2 bad
arguments or an address that cannot be served.
"""

from __future__ import annotations

import signal
import sys
import threading
from pathlib import Path
from typing import Any

import foxglove
from foxglove import Parameter, StatusLevel
from foxglove.websocket import Capability, ChannelView, Client, ClientChannel

from ..errors import ConfigError
from ..model.parameters import Parameters
from ..programs import stop_handled
from .channels import DESCRIPTION, TF_STATIC, Outlet, open_channels
from .relay import Relay
from .run import LiveRun
from .steering import ENCODINGS, Steer, SteeringError, steer_of

PROG = "boom-sim live"
_LEVELS = (StatusLevel.Info, StatusLevel.Warning, StatusLevel.Error)
_LATCHED = {DESCRIPTION.topic, TF_STATIC.topic}


class Listener:
    """The server's callbacks (foxglove.websocket.ServerListener), handed to the run. They
    come from the server's threads; none of them may raise into it."""

    def __init__(self, run: LiveRun, server: list[Any]) -> None:
        self.run = run
        self.server = server  # [the WebSocketServer], once started
        self.steers: dict[tuple[int, int], Steer] = {}

    def on_subscribe(self, client: Client, channel: ChannelView) -> None:
        if channel.topic in _LATCHED:
            self.run.resend_latched(channel.topic)

    def on_unsubscribe(self, client: Client, channel: ChannelView) -> None:
        return None

    def on_client_advertise(self, client: Client, channel: ClientChannel) -> None:
        try:
            self.steers[(client.id, channel.id)] = steer_of(channel.topic, channel.encoding, channel.schema_name)
        except SteeringError as exc:
            self.run.notice(1, f"channel {channel.topic}", str(exc))

    def on_client_unadvertise(self, client: Client, client_channel_id: int) -> None:
        self.steers.pop((client.id, client_channel_id), None)

    def on_message_data(self, client: Client, client_channel_id: int, data: bytes) -> None:
        steer = self.steers.get((client.id, client_channel_id))
        if steer is None:
            return
        try:
            self.run.on_message(steer, data)
        except SteeringError as exc:
            self.run.notice(1, steer.topic, str(exc))
        except Exception as exc:  # a bug: said in one line, and the server goes on
            self.run.notice(2, steer.topic, f"{steer.topic}: message not taken ({exc!r})")

    def on_get_parameters(
        self, client: Client, param_names: list[str], request_id: str | None = None
    ) -> list[Parameter]:
        return self.run.get_parameters(param_names)

    def on_set_parameters(
        self, client: Client, parameters: list[Parameter], request_id: str | None = None
    ) -> list[Parameter]:
        values = self.run.set_parameters(parameters)
        if self.server:  # the clients that subscribed to them see the values, changed or not
            self.server[0].publish_parameter_values(values)
        return values

    def on_parameters_subscribe(self, param_names: list[str]) -> None:
        return None

    def on_parameters_unsubscribe(self, param_names: list[str]) -> None:
        return None


def _end_on_signals(stopping: threading.Event) -> None:
    """Once running: the first Ctrl-C or SIGTERM ends the ticks (between two of them); any
    later one cannot cut finishing the bag short, and is told so."""

    def end(_signum: int, _frame: Any) -> None:
        if stopping.is_set():
            print(f"{PROG}: still finishing; it ends by itself", file=sys.stderr, flush=True)
        stopping.set()

    for signum in (signal.SIGINT, signal.SIGTERM):
        signal.signal(signum, end)


def _tick_loop(run: LiveRun, stopping: threading.Event, stopped: threading.Event) -> None:
    """Tick until ``stopping``; an unexpected error stops the simulation, not the server."""
    try:
        while not stopping.is_set():
            run.clock.wait(stopping)
            if stopping.is_set():
                break
            try:
                run.tick()
            except Exception as exc:  # reported like a blow-up; the server goes on serving
                run.fail(f"tick failed: {exc!r}")
    finally:
        stopped.set()


def serve(
    params: Parameters,
    *,
    host: str = "127.0.0.1",
    port: int = 8765,
    real_time_factor: float = 1.0,
    command_timeout_s: float = 0.0,
    max_catch_up_s: float = 0.2,
    record: Path | None = None,
    jit: bool | None = None,
) -> int:
    """Serve a live run of ``params`` until Ctrl-C or SIGTERM; the exit status (module docstring)."""
    if record is not None and record.exists():
        raise ConfigError(f"--record {record} exists already; name a new bag folder")
    sys.setswitchinterval(0.0005)  # the tick thread gets the GIL soon after its deadline (as the node's)
    context = foxglove.Context()
    channels = open_channels(context)
    server: list[Any] = []

    def sink(outlet: Outlet, data: bytes, log_ns: int) -> None:
        channels[outlet].log(data, log_time=log_ns)

    def notify(level: int, kind: str, text: str) -> None:
        if server:
            server[0].publish_status(text, _LEVELS[level], kind)

    stopping, stopped = threading.Event(), threading.Event()
    run: LiveRun | None = None
    relay: Relay | None = None
    ticks: threading.Thread | None = None
    try:
        pace = {"real_time_factor": real_time_factor, "max_catch_up_s": max_catch_up_s}
        run = LiveRun(params, sink, notify, command_timeout_s=command_timeout_s, jit=jit, **pace)
        server.append(_start_server(run, server, context))
        relay = _start_relay(server[0].port, host, port)
        run.start(record)
        ticks = threading.Thread(target=_tick_loop, args=(run, stopping, stopped), name="boom_live_ticks", daemon=True)
        ticks.start()
        print(
            f"{PROG}: serving ws://{host}:{relay.port} (Foxglove: Open connection, Foxglove WebSocket); "
            f"real-time factor {real_time_factor:g}{'; recording to ' + str(record) if record else ''}; "
            "Ctrl-C ends it",
            flush=True,
        )
        _end_on_signals(stopping)  # from here on a signal ends the ticks, and the main thread finishes
        stopped.wait()
    except KeyboardInterrupt:  # a signal while starting (the SDK, the model's compiling or loading)
        stop_handled()  # (its way to end: what comes after it is not the stop)
        _end_on_signals(stopping)
    finally:
        stopping.set()
        if ticks is not None:
            ticks.join()  # the tick in progress ends, whole, before the bag is finished
        if server:
            server[0].stop()  # (it closes its connections, the relay's too)
        if relay is not None:
            relay.stop()
    return _finish(run)


def _start_server(run: LiveRun, server: list[Any], context: foxglove.Context) -> Any:
    """The SDK's WebSocket server on a free port of the loopback, for the relay."""
    try:
        return foxglove.start_server(
            name=PROG,
            host="127.0.0.1",
            port=0,
            capabilities=[Capability.ClientPublish, Capability.Parameters],
            server_listener=Listener(run, server),
            supported_encodings=list(ENCODINGS),
            context=context,
        )
    except RuntimeError as exc:
        raise ConfigError(f"cannot start the Foxglove server on the loopback ({exc})") from None


def _start_relay(upstream_port: int, host: str, port: int) -> Relay:
    """The relay on ``host``:``port`` (0: any free port); ConfigError if it cannot listen there."""
    relay = Relay(upstream_port)
    try:
        relay.start(host, port)
    except OSError as exc:
        relay.stop()
        raise ConfigError(
            f"cannot serve on {host}:{port} ({exc.strerror or exc}); choose another --port (0: any free port) or --host"
        ) from None
    return relay


def _finish(run: LiveRun | None) -> int:
    """Finish the bag and say where it is; 1 if the recording failed (left for boom-bag-recover)."""
    finished = run.finish() if run is not None else None  # a bag begun, even under a signal, is finished
    if run is None or not run.started:
        print(f"{PROG}: stopped while starting" + ("" if finished else "; nothing was recorded"), file=sys.stderr)
    if finished is None:
        return 0
    folder, counts, error = finished
    if error is not None:  # (it says how to recover the bag)
        print(f"{PROG}: error: recording failed: {error}", file=sys.stderr, flush=True)
        return 1
    print(f"{PROG}: bag {folder} ({counts})", flush=True)
    return 0
