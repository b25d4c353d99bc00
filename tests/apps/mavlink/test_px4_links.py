"""TcpServerLink, the SITL socket: recv's contract (None when nothing came within the timeout, the bytes that
came, b"" once the peer left) with one recv per wait, and a fresh connection after a peer leaves."""

from __future__ import annotations

import socket
import threading

from cufund.apps.mavlink.px4_links import TcpServerLink


def _within(seconds: float, fn):
    """fn() run in a thread; fails (instead of hanging the suite) if it does not return within ``seconds``."""
    out: dict = {}
    thread = threading.Thread(target=lambda: out.setdefault("value", fn()), daemon=True)
    thread.start()
    thread.join(seconds)
    assert not thread.is_alive(), f"no return within {seconds} s"
    return out["value"]


def _read(link: TcpServerLink, n: int) -> bytes:
    got = b""
    while len(got) < n:
        data = _within(10.0, lambda: link.recv(5.0))
        assert data != b"", "the link closed early"
        got += data or b""
    return got


def test_recv_times_out_reads_and_sees_the_peer_leave():
    link = TcpServerLink("127.0.0.1", 0)
    try:
        assert not link.accept(0.01) and link.recv(0.1) == b""  # nobody connected yet
        peer = socket.create_connection(("127.0.0.1", link.port))
        assert link.accept(5.0) and link.connected
        assert _within(10.0, lambda: link.recv(0.0)) is None  # nothing waiting: no wait at all
        assert _within(10.0, lambda: link.recv(0.02)) is None  # nothing within a short timeout
        assert _within(10.0, lambda: link.recv(0.5)) is None  # a longer one (the socket's timeout changes back)
        peer.sendall(b"HIL")
        assert _read(link, 3) == b"HIL"
        link.send(b"controls")
        assert peer.recv(64) == b"controls"
        peer.sendall(b"\xfd" * 300)
        assert _read(link, 300) == b"\xfd" * 300
        peer.close()
        assert _within(10.0, lambda: link.recv(5.0)) == b"" and not link.connected
        assert link.recv(0.0) == b""
        again = socket.create_connection(("127.0.0.1", link.port))  # the server keeps listening
        try:
            assert link.accept(5.0)
            again.sendall(b"x")
            assert _read(link, 1) == b"x"
            link.disconnect()
            assert again.recv(64) == b"" and not link.connected
        finally:
            again.close()
    finally:
        link.close()


def test_closing_with_the_peers_bytes_unread_still_delivers_everything_sent():
    """A socket closed with unread input sends a reset, which discards what the peer had not read yet; the link
    closes gracefully instead, so PX4 (here a plain socket) reads every HIL message sent before the end of a run."""
    link = TcpServerLink("127.0.0.1", 0)
    peer = socket.create_connection(("127.0.0.1", link.port))
    try:
        assert link.accept(5.0)
        payload = bytes(range(256)) * 64  # 16 kB, read by the peer only after the link has closed
        link.send(payload)
        peer.sendall(b"controls the link never reads")
        closer = threading.Thread(target=link.close, daemon=True)
        closer.start()
        peer.settimeout(5.0)
        got = b""
        while chunk := peer.recv(65536):
            got += chunk
        peer.close()  # ends the link's drain
        closer.join(5.0)
        assert not closer.is_alive()
        assert got == payload
    finally:
        peer.close()
        link.close()


def test_a_link_pinned_to_one_cpu_blocks_at_once():
    """Polling before blocking helps only when PX4 can run on another CPU at the same time."""
    import os

    mask = os.sched_getaffinity(0)
    link = TcpServerLink("127.0.0.1", 0)
    try:
        os.sched_setaffinity(0, {min(mask)})
        peer = socket.create_connection(("127.0.0.1", link.port))
        assert link.accept(5.0) and link.spin_s == 0.0
        peer.sendall(b"x")
        assert _read(link, 1) == b"x"
        peer.close()
    finally:
        os.sched_setaffinity(0, mask)
        link.close()
