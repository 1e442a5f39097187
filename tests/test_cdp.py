"""The stdlib WebSocket client (RFC 6455) against a tiny in-test server, and a real CDP session."""

from __future__ import annotations

import base64
import hashlib
import socket
import struct
import threading
from pathlib import Path

import pytest

from pipeline.tracking import cdp, rfc6455, ui_browser

GUID = b"258EAFA5-E914-47DA-95CA-C5AB0DC85B11"


def server_frame(payload: bytes, opcode: int = 0x1, fin: bool = True) -> bytes:
    """An unmasked server frame, written from RFC 6455 section 5.2 (not with the client code)."""
    first = (0x80 if fin else 0) | opcode
    if len(payload) < 126:
        return bytes([first, len(payload)]) + payload
    if len(payload) < 65536:
        return bytes([first, 126]) + len(payload).to_bytes(2, "big") + payload
    return bytes([first, 127]) + len(payload).to_bytes(8, "big") + payload


def read_client_frame(conn: socket.socket) -> tuple[int, int, bytes]:
    """Read one client frame; return its first byte, its mask bit and the unmasked payload."""
    file = conn.makefile("rb")
    first, second = file.read(2)
    size = second & 0x7F
    if size == 126:
        size = int.from_bytes(file.read(2), "big")
    elif size == 127:
        size = int.from_bytes(file.read(8), "big")
    key = file.read(4) if second & 0x80 else b"\0\0\0\0"
    data = file.read(size)
    return first, second & 0x80, bytes(b ^ key[i % 4] for i, b in enumerate(data))


class Server:
    """Accept one connection on 127.0.0.1, answer the handshake, run ``script(conn, seen)``."""

    def __init__(self, script, status: str = "101 Switching Protocols") -> None:
        self.listener = socket.create_server(("127.0.0.1", 0))
        self.port = self.listener.getsockname()[1]
        self.script, self.status, self.seen = script, status, {}
        self.thread = threading.Thread(target=self._serve, daemon=True)
        self.thread.start()

    def _serve(self) -> None:
        conn, _ = self.listener.accept()
        with conn:
            request = b""
            while b"\r\n\r\n" not in request:
                request += conn.recv(4096)
            lines = request.decode().split("\r\n")
            self.seen["request_line"] = lines[0]
            key = next(
                v for k, _, v in (x.partition(": ") for x in lines) if k == "Sec-WebSocket-Key"
            )
            accept = base64.b64encode(hashlib.sha1(key.encode() + GUID).digest()).decode()
            conn.sendall(
                f"HTTP/1.1 {self.status}\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n"
                f"Sec-WebSocket-Accept: {accept}\r\n\r\n".encode()
            )
            self.script(conn, self.seen)

    def join(self) -> None:
        self.thread.join(timeout=10)
        self.listener.close()


def test_client_frames_are_masked_with_the_right_length_class():
    key = b"\x01\x02\x03\x04"
    frame = rfc6455.encode_frame(b"Hi", mask=key)
    assert frame == bytes([0x81, 0x82]) + key + bytes([ord("H") ^ 1, ord("i") ^ 2])
    medium = rfc6455.encode_frame(b"a" * 300, mask=key)
    assert medium[1] == 0x80 | 126 and struct.unpack("!H", medium[2:4]) == (300,)
    large = rfc6455.encode_frame(b"a" * 70000, mask=key)
    assert large[1] == 0x80 | 127 and struct.unpack("!Q", large[2:10]) == (70000,)
    assert len(large) == 2 + 8 + 4 + 70000 and large[14:18] == bytes(
        [97 ^ 1, 97 ^ 2, 97 ^ 3, 97 ^ 4]
    )
    assert rfc6455.encode_frame(b"x", mask=b"") == b"\x81\x01x"  # a server frame is not masked


def test_messages_of_each_length_class_and_fragmented_ones_are_read():
    medium, large = "é" * 150, "{" + "x" * 200_000 + "}"  # 300 bytes; 64-bit length

    def script(conn: socket.socket, seen: dict) -> None:
        conn.sendall(server_frame(b'{"id": 1}'))
        conn.sendall(server_frame(medium.encode()))
        conn.sendall(server_frame(large.encode()))
        conn.sendall(server_frame(b'{"method": "Page.', fin=False))
        conn.sendall(server_frame(b"ping!", opcode=0x9))  # a control frame between fragments
        conn.sendall(server_frame(b"loadEventFired", opcode=0x0, fin=False))
        conn.sendall(server_frame(b'"}', opcode=0x0))
        seen["pong"] = read_client_frame(conn)
        seen["text"] = read_client_frame(conn)
        conn.sendall(server_frame(struct.pack("!H", 1001), opcode=0x8))

    server = Server(script)
    ws = rfc6455.connect("127.0.0.1", server.port, "/devtools/page/ABC", timeout_s=5)
    assert ws.receive() == '{"id": 1}'
    assert ws.receive() == medium
    assert ws.receive() == large
    assert ws.receive() == '{"method": "Page.loadEventFired"}'
    ws.send('{"id": 2, "method": "Runtime.evaluate"}')
    with pytest.raises(rfc6455.WebSocketError, match=r"closed the connection \(code 1001\)"):
        ws.receive()
    ws.close()
    server.join()
    assert server.seen["request_line"] == "GET /devtools/page/ABC HTTP/1.1"
    assert server.seen["pong"] == (0x8A, 0x80, b"ping!")
    assert server.seen["text"] == (0x81, 0x80, b'{"id": 2, "method": "Runtime.evaluate"}')


def test_a_refused_handshake_and_a_silent_server_are_errors():
    server = Server(lambda conn, seen: None, status="403 Forbidden")
    with pytest.raises(rfc6455.WebSocketError, match="refused the handshake: HTTP/1.1 403"):
        rfc6455.connect("127.0.0.1", server.port, "/", timeout_s=5)
    server.join()
    done = threading.Event()
    server = Server(lambda conn, seen: done.wait(5))
    ws = rfc6455.connect("127.0.0.1", server.port, "/", timeout_s=0.3)
    with pytest.raises(TimeoutError):
        ws.receive()
    done.set()
    ws.close()
    server.join()


def test_a_stray_continuation_frame_is_a_protocol_error():
    server = Server(lambda conn, seen: conn.sendall(server_frame(b"tail", opcode=0x0)))
    ws = rfc6455.connect("127.0.0.1", server.port, "/", timeout_s=5)
    with pytest.raises(rfc6455.WebSocketError, match="unexpected frame"):
        ws.receive()
    ws.close()
    server.join()


@pytest.mark.slow
def test_a_session_clicks_waits_and_captures_in_real_chromium(tmp_path: Path):
    chromium = ui_browser.find_chromium()
    if chromium is None:
        pytest.skip("no Chromium: apt-get install -y chromium, or set CHROMIUM=/path")
    page = (
        "data:text/html,<body style='margin:0;background:%23c33'><button id=b "
        "onclick=\"setTimeout(()=>document.body.insertAdjacentHTML('beforeend',"
        "'<p id=done>clicked</p>'),300)\">go</button></body>"
    )
    with cdp.Session(chromium, (1000, 800), timeout_s=30) as session:
        assert session.navigate(page)
        assert session.evaluate("1 + 2") == 3
        assert not session.wait_for("document.getElementById('done')", 0.5)
        session.evaluate("document.getElementById('b').click()")
        assert session.wait_for("document.getElementById('done')", 10)
        assert '<p id="done">clicked</p>' in session.html()
        shot = tmp_path / "shot.png"
        session.screenshot(shot)
        with pytest.raises(cdp.CdpError, match="JavaScript error: ReferenceError"):
            session.evaluate("no_such_name")
    png = shot.read_bytes()
    assert png.startswith(b"\x89PNG") and struct.unpack(">II", png[16:24]) == (1000, 800)
