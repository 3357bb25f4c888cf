"""boom-sim live's relay (live/relay.py): both names of the Foxglove protocol's v1 in front of
foxglove-sdk's server, which takes only its own. Against a plain SDK server (no model): the
handshake under each name, messages both ways whole and in order, and both sides closed."""

from __future__ import annotations

import json
import socket
import struct
import threading
from collections.abc import Iterator
from typing import Any

import foxglove
import pytest
from foxglove.websocket import Capability
from websockets.exceptions import ConnectionClosed, InvalidStatus
from websockets.sync.client import ClientConnection, connect

from boom_hydraulics.live.relay import FIRST_NAME, SDK_NAME, Relay, client_answer, offered, upstream_request

COUNT = 500  # messages each way (under the SDK's per-client backlog of 1024)
TIMEOUT_S = 30.0  # a guard against a hang; every wait ends on an event


class Listener:
    """The SDK server's callbacks the tests wait on."""

    def __init__(self) -> None:
        self.subscribed, self.unsubscribed, self.all_in = threading.Event(), threading.Event(), threading.Event()
        self.received: list[bytes] = []

    def on_subscribe(self, client: Any, channel: Any) -> None:
        self.subscribed.set()

    def on_unsubscribe(self, client: Any, channel: Any) -> None:  # also on a client's going away
        self.unsubscribed.set()

    def on_message_data(self, client: Any, client_channel_id: int, data: bytes) -> None:
        self.received.append(data)
        if len(self.received) == COUNT:
            self.all_in.set()


@pytest.fixture
def sdk() -> Iterator[tuple[Any, Any, Listener]]:
    context = foxglove.Context()
    channel = foxglove.Channel("/count", message_encoding="json", context=context)
    listener = Listener()
    server = foxglove.start_server(
        host="127.0.0.1",
        port=0,
        capabilities=[Capability.ClientPublish],
        server_listener=listener,
        supported_encodings=["json"],
        context=context,
    )
    yield server, channel, listener
    server.stop()


@pytest.fixture
def relay(sdk) -> Iterator[Relay]:
    relay = Relay(sdk[0].port)
    relay.start("127.0.0.1", 0)
    yield relay
    relay.stop()


def _connect(port: int, names: list[str]) -> ClientConnection:
    return connect(f"ws://127.0.0.1:{port}", subprotocols=names, open_timeout=TIMEOUT_S, max_queue=None)


def _opening(ws: ClientConnection) -> list[dict]:
    """serverInfo and advertise, the first two messages."""
    return [json.loads(ws.recv(timeout=TIMEOUT_S)) for _ in range(2)]


def test_the_sdk_alone_refuses_the_first_name(sdk):
    """Why the relay is there: foxglove-sdk's server answers the first name with HTTP 400.
    (Should a release take it, this fails, and the relay can go.)"""
    with pytest.raises(InvalidStatus) as refused:
        _connect(sdk[0].port, [FIRST_NAME])
    assert refused.value.response.status_code == 400


@pytest.mark.parametrize(
    ("names", "chosen"),
    [
        ([FIRST_NAME], FIRST_NAME),  # @foxglove/ws-protocol's clients
        ([SDK_NAME], SDK_NAME),  # foxglove-sdk's
        ([FIRST_NAME, SDK_NAME], SDK_NAME),  # the Foxglove app's
    ],
)
def test_either_name_gets_the_servers_messages_whole_and_in_order(sdk, relay, names, chosen):
    _, channel, listener = sdk
    with _connect(relay.port, names) as ws:
        assert ws.subprotocol == chosen
        info, advertise = _opening(ws)
        assert info["op"] == "serverInfo" and "clientPublish" in info["capabilities"]
        (advertised,) = advertise["channels"]
        assert advertised["topic"] == "/count"
        ws.send(json.dumps({"op": "subscribe", "subscriptions": [{"id": 7, "channelId": advertised["id"]}]}))
        assert listener.subscribed.wait(TIMEOUT_S)
        for i in range(COUNT):
            channel.log({"i": i})
        got = []
        for _ in range(COUNT):
            data = ws.recv(timeout=TIMEOUT_S)
            assert data[0] == 0x01 and struct.unpack_from("<I", data, 1)[0] == 7  # message data, our subscription
            got.append(json.loads(data[13:])["i"])
        assert got == list(range(COUNT))


def test_a_first_name_clients_messages_reach_the_server_whole_and_in_order(sdk, relay):
    _, _, listener = sdk
    with _connect(relay.port, [FIRST_NAME]) as ws:
        _opening(ws)
        channel = {"id": 3, "topic": "/in", "encoding": "json", "schemaName": "Count"}
        ws.send(json.dumps({"op": "advertise", "channels": [channel]}))
        for i in range(COUNT):
            ws.send(b"\x01" + struct.pack("<I", 3) + json.dumps({"i": i}).encode())
        assert listener.all_in.wait(TIMEOUT_S)
    assert [json.loads(data)["i"] for data in listener.received] == list(range(COUNT))


def test_a_client_offering_neither_name_gets_the_servers_refusal(relay):
    with pytest.raises(InvalidStatus) as refused:
        _connect(relay.port, ["foxglove.websocket.v2"])
    assert refused.value.response.status_code == 400


def test_a_client_that_closes_leaves_the_server_too(sdk, relay):
    _, _, listener = sdk
    with _connect(relay.port, [FIRST_NAME]) as ws:
        _, advertise = _opening(ws)
        subscription = {"id": 1, "channelId": advertise["channels"][0]["id"]}
        ws.send(json.dumps({"op": "subscribe", "subscriptions": [subscription]}))
        assert listener.subscribed.wait(TIMEOUT_S)
    assert listener.unsubscribed.wait(TIMEOUT_S)  # the server saw its client go


def test_a_server_that_stops_closes_its_clients_and_the_relay_then_stops(sdk, relay):
    server, _, _ = sdk
    with _connect(relay.port, [FIRST_NAME]) as ws:
        _opening(ws)
        server.stop()
        with pytest.raises(ConnectionClosed):
            ws.recv(timeout=TIMEOUT_S)  # the server's end of the connection came through
    relay.stop()
    with pytest.raises(ConnectionRefusedError):
        socket.create_connection(("127.0.0.1", relay.port), timeout=TIMEOUT_S)


def test_a_port_in_use_is_an_os_error(relay, sdk):
    second = Relay(sdk[0].port)
    with pytest.raises(OSError):
        second.start("127.0.0.1", relay.port)
    second.stop()


REQUEST = (
    b"GET / HTTP/1.1\r\nHost: 127.0.0.1:8765\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n"
    b"Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\nsec-websocket-protocol: foxglove.websocket.v1\r\n"
    b"Sec-WebSocket-Version: 13\r\n\r\n"
)


def test_the_first_name_alone_is_offered_upstream_as_the_sdks_and_answered_as_the_clients():
    request, name = upstream_request(REQUEST)
    assert name == FIRST_NAME
    assert offered(request) == [SDK_NAME]
    assert request == REQUEST.replace(
        b"sec-websocket-protocol: foxglove.websocket.v1", b"Sec-WebSocket-Protocol: " + SDK_NAME.encode()
    )
    answer = (
        b"HTTP/1.1 101 Switching Protocols\r\nConnection: Upgrade\r\nUpgrade: websocket\r\n"
        b"Sec-WebSocket-Protocol: foxglove.sdk.v1\r\nSec-WebSocket-Accept: s3pPLMBiTxaQ9kYGzzhZRbK+xOo=\r\n\r\n"
    )
    assert client_answer(answer, name) == answer.replace(b"foxglove.sdk.v1", b"foxglove.websocket.v1")
    refusal = b"HTTP/1.1 400 Bad Request\r\nContent-Length: 0\r\n\r\n"
    assert client_answer(refusal, name) == refusal


@pytest.mark.parametrize(
    "protocols",
    [
        [b"Sec-WebSocket-Protocol: foxglove.websocket.v1, foxglove.sdk.v1"],
        [b"Sec-WebSocket-Protocol: foxglove.websocket.v1", b"Sec-WebSocket-Protocol: foxglove.sdk.v1"],
        [b"Sec-WebSocket-Protocol: foxglove.websocket.v2"],
        [],
    ],
)
def test_any_other_offer_passes_as_it_is(protocols):
    head = b"\r\n".join([b"GET / HTTP/1.1", b"Host: x", *protocols, b"Sec-WebSocket-Version: 13"]) + b"\r\n\r\n"
    assert upstream_request(head) == (head, None)
