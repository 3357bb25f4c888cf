"""Both names of the Foxglove protocol's v1 on one port: a relay in front of the SDK's server.

The protocol's v1 goes by two subprotocol names: ``foxglove.websocket.v1``, its first
(``@foxglove/ws-protocol`` and the clients built on it, foxglove_bridge 0.8 and the apps of
its time), and ``foxglove.sdk.v1``, the ``foxglove-sdk``'s (current Foxglove apps,
foxglove_bridge 3). The messages are the same under both. The SDK's server (0.30) knows
only its own name and answers a client that offers only the first with HTTP 400; it takes
no option for it.

:class:`Relay` listens where the user asked and passes each connection on to the SDK's
server on this machine's loopback. Of a connection it reads only the HTTP upgrade request
and the server's answer: where the client offers ``foxglove.websocket.v1`` but not
``foxglove.sdk.v1``, it offers the SDK's name upstream in its place and, in the server's
``101`` answer, names the client's one again. Every other request and answer passes as it
is (so a client that offers neither name still gets the SDK's 400). From the upgrade on it
copies the bytes both ways as they come, each way in order: the frames, pings and the
closing handshake pass end to end, and the end of either side's stream ends the other's.
"""

from __future__ import annotations

import asyncio
import contextlib
import socket
import threading

#: The protocol's v1 under the SDK's name, the only one its server accepts.
SDK_NAME = "foxglove.sdk.v1"
#: The protocol's v1 under its first name (what @foxglove/ws-protocol's clients offer).
FIRST_NAME = "foxglove.websocket.v1"
#: The subprotocol names served, the SDK's first.
NAMES = (SDK_NAME, FIRST_NAME)

_HEADER = b"sec-websocket-protocol"
_END = b"\r\n\r\n"
_HEAD_LIMIT = 64 * 1024  # an upgrade request or answer longer than this is not a WebSocket's; also a read's buffer
_CHUNK = 256 * 1024  # bytes passed on at most in one write
_LINGER_S = 5.0  # once one side's stream ended, how long the other's may go on (a closing handshake's time)
_STOP_S = 5.0  # at stop, how long open connections have to end before they are cut


def offered(head: bytes) -> list[str]:
    """The subprotocol names an upgrade request offers, in order (every Sec-WebSocket-Protocol line)."""
    names: list[str] = []
    for line in head.split(b"\r\n")[1:]:
        name, colon, value = line.partition(b":")
        if colon and name.strip().lower() == _HEADER:
            names += [part.strip() for part in value.decode("latin-1").split(",") if part.strip()]
    return names


def upstream_request(head: bytes) -> tuple[bytes, str | None]:
    """The request to pass to the SDK's server, and the name to give the client back in the
    answer (None: the answer as it is). ``head`` is the request up to its blank line."""
    names = offered(head)
    if SDK_NAME in names or FIRST_NAME not in names:
        return head, None
    return _with_protocol(head, SDK_NAME), FIRST_NAME


def client_answer(head: bytes, name: str | None) -> bytes:
    """The server's answer for the client: a ``101`` names ``name`` as the subprotocol (if not None)."""
    status = head.split(b"\r\n", 1)[0].split()
    if name is None or len(status) < 2 or status[1] != b"101":
        return head
    return _with_protocol(head, name)


def _with_protocol(head: bytes, name: str) -> bytes:
    """``head`` (a request or an answer, up to its blank line) with one Sec-WebSocket-Protocol
    line naming ``name`` where its own were (after the first line if it had none)."""
    lines = head[: -len(_END)].split(b"\r\n")
    kept = [lines[0]]
    placed = False
    for line in lines[1:]:
        if line.partition(b":")[0].strip().lower() != _HEADER:
            kept.append(line)
        elif not placed:
            kept.append(b"Sec-WebSocket-Protocol: " + name.encode("latin-1"))
            placed = True
    if not placed:
        kept.insert(1, b"Sec-WebSocket-Protocol: " + name.encode("latin-1"))
    return b"\r\n".join(kept) + _END


async def _pipe(reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
    """Bytes from ``reader`` to ``writer`` as they come, until its end, which is passed on."""
    while data := await reader.read(_CHUNK):
        writer.write(data)
        await writer.drain()  # a slow reader on the other side slows this side down: nothing piles up here
    if writer.can_write_eof():
        writer.write_eof()


async def _closed(writer: asyncio.StreamWriter | None) -> None:
    if writer is None:
        return
    writer.close()
    with contextlib.suppress(OSError):
        await writer.wait_closed()


class Relay:
    """Serves both names of the protocol on ``host``:``port`` in front of the SDK's server on
    ``127.0.0.1``:``upstream_port`` (module docstring); its own thread runs the connections."""

    def __init__(self, upstream_port: int) -> None:
        self.upstream_port = upstream_port
        self.port = 0  # the port it listens on, once started
        self._loop = asyncio.new_event_loop()
        self._thread = threading.Thread(target=self._loop.run_forever, name="boom_live_relay", daemon=True)
        self._server: asyncio.Server | None = None
        self._connections: set[asyncio.Task[None]] = set()

    def start(self, host: str, port: int) -> None:
        """Listen on ``host``:``port`` (0: any free port, then in :attr:`port`); OSError if it cannot."""
        family, _, _, _, address = socket.getaddrinfo(host, port, type=socket.SOCK_STREAM, flags=socket.AI_PASSIVE)[0]
        listener = socket.create_server(address, family=family)  # the name's first address
        self.port = listener.getsockname()[1]
        self._thread.start()
        serving = self._serve(listener)
        asyncio.run_coroutine_threadsafe(serving, self._loop).result()

    async def _serve(self, listener: socket.socket) -> None:
        self._server = await asyncio.start_server(self._relay, sock=listener, limit=_HEAD_LIMIT)

    def stop(self) -> None:
        """Stop listening; a connection still open after :data:`_STOP_S` is cut. Call it after
        the SDK's server stopped, which closes its ends of the connections."""
        if self._thread.is_alive():
            asyncio.run_coroutine_threadsafe(self._stop(), self._loop).result()
            self._loop.call_soon_threadsafe(self._loop.stop)
            self._thread.join()
        self._loop.close()

    async def _stop(self) -> None:
        if self._server is not None:
            self._server.close()
            await self._server.wait_closed()
        if self._connections:
            _, going_on = await asyncio.wait(self._connections, timeout=_STOP_S)
            for task in going_on:
                task.cancel()
            await asyncio.gather(*going_on, return_exceptions=True)

    async def _relay(self, client_reader: asyncio.StreamReader, client_writer: asyncio.StreamWriter) -> None:
        task = asyncio.current_task()
        assert task is not None
        self._connections.add(task)
        upstream_writer: asyncio.StreamWriter | None = None
        try:
            request, name = upstream_request(await client_reader.readuntil(_END))
            upstream_reader, upstream_writer = await asyncio.open_connection(
                "127.0.0.1", self.upstream_port, limit=_HEAD_LIMIT
            )
            upstream_writer.write(request)
            await upstream_writer.drain()
            client_writer.write(client_answer(await upstream_reader.readuntil(_END), name))
            await client_writer.drain()
            await self._both_ways(client_reader, client_writer, upstream_reader, upstream_writer)
        except (OSError, asyncio.IncompleteReadError, asyncio.LimitOverrunError):
            pass  # a side that went away, or a request that is no upgrade: the connection ends
        finally:
            await _closed(upstream_writer)
            await _closed(client_writer)
            self._connections.discard(task)

    @staticmethod
    async def _both_ways(
        client_reader: asyncio.StreamReader,
        client_writer: asyncio.StreamWriter,
        upstream_reader: asyncio.StreamReader,
        upstream_writer: asyncio.StreamWriter,
    ) -> None:
        """Pipe both ways until both ends; one that fails, or lingers after the other ended, is cut."""
        ways = {
            asyncio.ensure_future(_pipe(client_reader, upstream_writer)),
            asyncio.ensure_future(_pipe(upstream_reader, client_writer)),
        }
        try:
            done, going_on = await asyncio.wait(ways, return_when=asyncio.FIRST_COMPLETED)
            if going_on and not any(way.exception() for way in done):
                done, going_on = await asyncio.wait(going_on, timeout=_LINGER_S)
        finally:
            for way in ways:
                way.cancel()
            await asyncio.gather(*ways, return_exceptions=True)
