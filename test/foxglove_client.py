"""A Foxglove WebSocket client for the tests: the published protocol (docs of foxglove/ws-protocol,
v1 messages) over a plain WebSocket, as the Foxglove app speaks it, and the server process it talks to."""

from __future__ import annotations

import json
import select
import signal
import struct
import subprocess
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from rosbags.typesys import Stores, get_types_from_msg, get_typestore
from websockets.sync.client import connect

#: What the Foxglove app offers: the protocol's v1 under its first name and the SDK's name for it.
SUBPROTOCOLS = ["foxglove.websocket.v1", "foxglove.sdk.v1"]
#: What @foxglove/ws-protocol's clients offer (``new WebSocket(url, [FoxgloveClient.SUPPORTED_SUBPROTOCOL])``,
#: which is "foxglove.websocket.v1"): the first name alone, ``Sec-WebSocket-Protocol: foxglove.websocket.v1``.
WS_PROTOCOL_OFFER = ["foxglove.websocket.v1"]
ROOT = Path(__file__).resolve().parent.parent


class LiveServer:
    """``boom-sim live`` in a process of its own, on a free port it prints."""

    def __init__(self, *args: str, start_timeout_s: float = 240.0) -> None:
        command = ["boom-sim", "live", "--config", str(ROOT / "config" / "default.yaml"), "--port", "0", *args]
        self.proc = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=ROOT)
        line = self._first_line(start_timeout_s)
        assert "serving ws://127.0.0.1:" in line, line + self.proc.stderr.read()
        self.port = int(line.split("ws://127.0.0.1:")[1].split()[0])

    def _first_line(self, timeout_s: float) -> str:
        """The first line it prints (it compiles or loads the model first), or what it said
        when it ended; ``timeout_s`` guards against a hang."""
        ready, _, _ = select.select([self.proc.stdout], [], [], timeout_s)
        if not ready:
            self.proc.kill()
            raise AssertionError(f"boom-sim live did not start within {timeout_s:g} s")
        return self.proc.stdout.readline()

    def interrupt(self) -> None:
        self.proc.send_signal(signal.SIGINT)

    def wait(self, timeout_s: float = 120.0) -> tuple[int, str, str]:
        out, err = self.proc.communicate(timeout=timeout_s)
        return self.proc.returncode, out, err

    def stop(self) -> None:
        if self.proc.poll() is None:
            self.interrupt()
            try:
                self.proc.communicate(timeout=60)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.communicate()


class FoxgloveClient:
    """One connection (a context manager): server info, advertised channels, subscriptions,
    client channels, parameters."""

    def __init__(self, port: int, subprotocols: list[str] = SUBPROTOCOLS) -> None:
        # an unbounded queue: with a bounded one, a subscribed client stops reading when it is full,
        # never reads the server's close frame, and each close waited out its 10 s timeout
        self._connection = connect(f"ws://127.0.0.1:{port}", subprotocols=subprotocols, open_timeout=30, max_queue=None)
        self.ws = self._connection.__enter__()
        self.info = self._json(lambda m: m["op"] == "serverInfo")
        self.channels: dict[str, dict] = {}
        advertised = self._json(lambda m: m["op"] == "advertise")
        self.channels = {c["topic"]: c for c in advertised["channels"]}
        self.subscriptions: dict[int, str] = {}
        self.texts: list[dict] = []  # status and parameter messages, in order
        self._types: dict[str, Any] = {}

    def __enter__(self) -> FoxgloveClient:
        return self

    def __exit__(self, *exc: object) -> None:
        self._connection.__exit__(None, None, None)

    def _recv(self, timeout_s: float) -> str | bytes:
        return self.ws.recv(timeout=timeout_s)

    def _json(self, predicate: Callable[[dict], bool], timeout_s: float = 30.0) -> dict:
        deadline = time.monotonic() + timeout_s
        while True:
            message = self._recv(max(0.0, deadline - time.monotonic()))
            if isinstance(message, str):
                decoded = json.loads(message)
                if predicate(decoded):
                    return decoded
                self.texts.append(decoded)

    # --- subscribing -------------------------------------------------------------------
    def subscribe(self, *topics: str) -> None:
        subscriptions = []
        for topic in topics:
            sid = len(self.subscriptions) + 1
            self.subscriptions[sid] = topic
            subscriptions.append({"id": sid, "channelId": self.channels[topic]["id"]})
        self.ws.send(json.dumps({"op": "subscribe", "subscriptions": subscriptions}))

    def decoder(self, topic: str) -> Callable[[bytes], Any]:
        """A CDR decoder built from the channel's own advertised ros2msg schema (as the app builds one)."""
        channel = self.channels[topic]
        assert (channel["encoding"], channel["schemaEncoding"]) == ("cdr", "ros2msg")
        name = channel["schemaName"]
        if name not in self._types:
            store = get_typestore(Stores.EMPTY)
            store.register(_types_of_schema(name, channel["schema"]))
            self._types[name] = store
        store = self._types[name]
        return lambda data: store.deserialize_cdr(data, name)

    def next_message(self, topic: str, timeout_s: float = 30.0) -> tuple[int, Any]:
        """(receive time ns, decoded message) of the next message on ``topic``; texts in between are kept."""
        deadline = time.monotonic() + timeout_s
        decode = self.decoder(topic)
        while True:
            message = self._recv(max(0.0, deadline - time.monotonic()))
            if isinstance(message, str):
                self.texts.append(json.loads(message))
                continue
            assert message[0] == 0x01  # Message Data
            sid, receive_ns = struct.unpack_from("<IQ", message, 1)
            if self.subscriptions.get(sid) == topic:
                return receive_ns, decode(message[13:])

    def until(self, topic: str, predicate: Callable[[Any], bool], timeout_s: float = 60.0) -> Any:
        """The first message on ``topic`` that satisfies ``predicate`` (a guard: ``timeout_s``)."""
        deadline = time.monotonic() + timeout_s
        while True:
            _, msg = self.next_message(topic, max(0.0, deadline - time.monotonic()))
            if predicate(msg):
                return msg

    # --- publishing --------------------------------------------------------------------
    def advertise(self, channel_id: int, topic: str, encoding: str, schema_name: str) -> None:
        channel = {"id": channel_id, "topic": topic, "encoding": encoding, "schemaName": schema_name}
        self.ws.send(json.dumps({"op": "advertise", "channels": [channel]}))

    def publish(self, channel_id: int, payload: bytes | dict) -> None:
        data = json.dumps(payload).encode() if isinstance(payload, dict) else payload
        self.ws.send(b"\x01" + struct.pack("<I", channel_id) + data)

    # --- parameters --------------------------------------------------------------------
    def set_parameters(self, request_id: str, **values: Any) -> dict:
        parameters = [{"name": name, "value": value} for name, value in values.items()]
        self.ws.send(json.dumps({"op": "setParameters", "parameters": parameters, "id": request_id}))
        return self._json(lambda m: m["op"] == "parameterValues" and m.get("id") == request_id)

    def get_parameters(self, request_id: str, *names: str) -> dict:
        self.ws.send(json.dumps({"op": "getParameters", "parameterNames": list(names), "id": request_id}))
        return self._json(lambda m: m["op"] == "parameterValues" and m.get("id") == request_id)

    def status(self, predicate: Callable[[dict], bool], timeout_s: float = 30.0) -> dict:
        """A status message (seen already or the next) that satisfies ``predicate``."""
        for text in self.texts:
            if text["op"] == "status" and predicate(text):
                return text
        return self._json(lambda m: m["op"] == "status" and predicate(m), timeout_s)


def _types_of_schema(name: str, schema: str) -> dict:
    """The types of a ros2msg schema: the main definition, then each ``MSG: pkg/Type`` after a delimiter."""
    parts = schema.split("=" * 80 + "\n")
    types = get_types_from_msg(parts[0], name)
    for part in parts[1:]:
        header, _, body = part.partition("\n")
        nested = header.removeprefix("MSG: ").strip()
        package, _, type_name = nested.rpartition("/")
        full = nested if "/msg/" in nested else f"{package}/msg/{type_name}"
        types.update(get_types_from_msg(body, full))
    return types
