"""A minimal WebSocket client (RFC 6455) over the standard library, for Chromium's DevTools.

Enough for the DevTools protocol on 127.0.0.1: the opening handshake, masked client text frames,
server frames of the three length classes (7-bit, 16-bit and 64-bit), messages fragmented into
continuation frames, pings answered with pongs and a close frame ending the connection. No TLS,
no extensions, no subprotocols. Kept here so that ``thermal ui-check`` needs no extra package.
"""

from __future__ import annotations

import base64
import hashlib
import os
import socket
import struct

GUID = "258EAFA5-E914-47DA-95CA-C5AB0DC85B11"  # RFC 6455, section 1.3
OP_CONTINUATION, OP_TEXT, OP_BINARY, OP_CLOSE, OP_PING, OP_PONG = 0x0, 0x1, 0x2, 0x8, 0x9, 0xA
DATA_OPCODES = (OP_CONTINUATION, OP_TEXT, OP_BINARY)
MAX_MESSAGE_BYTES = 512 * 1024 * 1024  # a full-page screenshot is tens of MB of base64 at most


class WebSocketError(RuntimeError):
    """The peer broke the protocol or closed the connection."""


def encode_frame(
    payload: bytes, opcode: int = OP_TEXT, mask: bytes | None = None, fin: bool = True
) -> bytes:
    """Return one frame; masked (as a client must send it) unless ``mask`` is ``b""``.

    Parameters
    ----------
    payload : bytes
        Application data.
    opcode : int
        Frame type, e.g. :data:`OP_TEXT`.
    mask : bytes, optional
        The 4-byte masking key; random when None; ``b""`` for an unmasked (server) frame.
    fin : bool
        Whether this is the last frame of its message.

    Returns
    -------
    bytes
        Header, extended length (16-bit from 126 bytes, 64-bit from 65536), key and payload.
    """
    mask = os.urandom(4) if mask is None else mask
    head = bytes([(0x80 if fin else 0) | opcode])
    bit = 0x80 if mask else 0
    size = len(payload)
    if size < 126:
        head += bytes([bit | size])
    elif size < 1 << 16:
        head += bytes([bit | 126]) + struct.pack("!H", size)
    else:
        head += bytes([bit | 127]) + struct.pack("!Q", size)
    return head + mask + apply_mask(payload, mask) if mask else head + payload


def apply_mask(data: bytes, mask: bytes) -> bytes:
    """XOR ``data`` with the repeated 4-byte ``mask`` (masking and unmasking are the same)."""
    if not data:
        return b""
    key = int.from_bytes((mask * (len(data) // 4 + 1))[: len(data)], "big")
    return (int.from_bytes(data, "big") ^ key).to_bytes(len(data), "big")


class WebSocket:
    """A client connection; ``sock`` must be connected and its handshake done (see :func:`connect`).

    Parameters
    ----------
    sock : socket.socket
        The connected socket; its timeout bounds each read, in seconds.
    buffered : bytes
        Bytes already read past the handshake's header.
    """

    def __init__(self, sock: socket.socket, buffered: bytes = b"") -> None:
        self.sock = sock
        self._buffer = bytearray(buffered)

    def _read(self, count: int) -> bytes:
        while len(self._buffer) < count:
            chunk = self.sock.recv(max(65536, count - len(self._buffer)))
            if not chunk:
                raise WebSocketError("the connection was closed in the middle of a frame")
            self._buffer += chunk
        data = bytes(self._buffer[:count])
        del self._buffer[:count]
        return data

    def read_frame(self) -> tuple[bool, int, bytes]:
        """Read one frame; return its FIN bit, opcode and (unmasked) payload."""
        first, second = self._read(2)
        size = second & 0x7F
        if size == 126:
            (size,) = struct.unpack("!H", self._read(2))
        elif size == 127:
            (size,) = struct.unpack("!Q", self._read(8))
        if size > MAX_MESSAGE_BYTES:
            raise WebSocketError(f"a frame of {size} bytes is larger than {MAX_MESSAGE_BYTES}")
        mask = self._read(4) if second & 0x80 else b""
        payload = self._read(size)
        return bool(first & 0x80), first & 0x0F, apply_mask(payload, mask) if mask else payload

    def send(self, text: str, opcode: int = OP_TEXT) -> None:
        """Send ``text`` (UTF-8) as one masked frame."""
        self.sock.sendall(encode_frame(text.encode("utf-8"), opcode))

    def receive(self) -> str:
        """Return the next text message, joined from its continuation frames.

        Pings are answered; a close frame raises :class:`WebSocketError`; a read longer than
        the socket's timeout raises :class:`TimeoutError`.
        """
        parts: list[bytes] = []
        while True:
            fin, opcode, payload = self.read_frame()
            if opcode == OP_PING:
                self.sock.sendall(encode_frame(payload, OP_PONG))
            elif opcode == OP_CLOSE:
                code = struct.unpack("!H", payload[:2])[0] if len(payload) >= 2 else None
                raise WebSocketError(f"the server closed the connection (code {code})")
            elif opcode == OP_PONG:
                continue
            elif (opcode == OP_CONTINUATION) != bool(parts) or opcode not in DATA_OPCODES:
                raise WebSocketError(f"unexpected frame (opcode {opcode:#x})")
            else:
                parts.append(payload)
                if fin:
                    return b"".join(parts).decode("utf-8")

    def close(self) -> None:
        """Send a close frame (best effort) and close the socket."""
        try:
            self.sock.sendall(encode_frame(struct.pack("!H", 1000), OP_CLOSE))
        except OSError:
            pass
        self.sock.close()


def connect(host: str, port: int, path: str, timeout_s: float = 30.0) -> WebSocket:
    """Open ``ws://host:port/path``: TCP connection and opening handshake.

    Parameters
    ----------
    host, port, path : str, int, str
        The endpoint, e.g. ``127.0.0.1``, ``9222``, ``/devtools/page/<id>``.
    timeout_s : float
        Timeout of the connection and of each later read, in seconds.

    Returns
    -------
    WebSocket
        The open connection.

    Raises
    ------
    WebSocketError
        If the server does not switch protocols with the expected accept key.
    """
    sock = socket.create_connection((host, port), timeout=timeout_s)
    key = base64.b64encode(os.urandom(16)).decode("ascii")
    request = (
        f"GET {path} HTTP/1.1\r\nHost: {host}:{port}\r\nUpgrade: websocket\r\n"
        f"Connection: Upgrade\r\nSec-WebSocket-Key: {key}\r\nSec-WebSocket-Version: 13\r\n\r\n"
    )
    sock.sendall(request.encode("ascii"))
    data = b""
    while b"\r\n\r\n" not in data:
        chunk = sock.recv(4096)
        if not chunk or len(data) > 65536:
            sock.close()
            raise WebSocketError(f"no handshake answer from ws://{host}:{port}{path}: {data!r}")
        data += chunk
    header, rest = data.split(b"\r\n\r\n", 1)
    lines = header.decode("latin-1").split("\r\n")
    fields = {k.strip().lower(): v.strip() for k, _, v in (line.partition(":") for line in lines)}
    accept = base64.b64encode(hashlib.sha1((key + GUID).encode("ascii")).digest()).decode()
    if " 101 " not in f"{lines[0]} " or fields.get("sec-websocket-accept") != accept:
        sock.close()
        raise WebSocketError(f"ws://{host}:{port}{path} refused the handshake: {lines[0]}")
    return WebSocket(sock, rest)
