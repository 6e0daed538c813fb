"""Is a `--scheduler` address a Dask scheduler? Asked in seconds, before Dask's client is.

Dask's client trusts the peer: pointed at a web server it waits for a handshake that never comes
(past its own timeout, minutes), and pointed at a port that answers other bytes it reads them as
a frame length and tries to allocate exabytes. A Dask scheduler writes its handshake as soon as
a client connects: an 8-byte little-endian total length, then the frame count and each frame's
length (`distributed.comm.tcp`), a few dozen bytes. `probe_scheduler` connects, reads that
header within `PROBE_TIMEOUT_S` and checks it is one (a total up to `MAX_HANDSHAKE_BYTES`, one
to `MAX_FRAMES` frames whose lengths add up), refusing anything else in one line.
"""

from __future__ import annotations

import socket
import struct

from paintcell.core.errors import PaintcellError

__all__ = ["MAX_FRAMES", "MAX_HANDSHAKE_BYTES", "PROBE_TIMEOUT_S", "SchedulerProbeError",
           "probe_scheduler"]

#: Seconds to connect, and again to receive the scheduler's handshake header.
PROBE_TIMEOUT_S = 5.0
#: Largest handshake message accepted [bytes] (Dask's is ~60).
MAX_HANDSHAKE_BYTES = 1 << 20
#: Most frames a handshake message may have.
MAX_FRAMES = 64


class SchedulerProbeError(PaintcellError):
    """The address does not answer as a Dask scheduler."""


def _host_port(address: str) -> tuple[str, int] | None:
    """(host, port) of a tcp:// or bare host:port address; None for other protocols."""
    rest = address.removeprefix("tcp://")
    if "://" in rest:
        return None
    host, sep, port = rest.rpartition(":")
    if not sep or not port.isdigit() or not 0 < int(port) < 65536:
        raise SchedulerProbeError(f"--scheduler {address!r} is not host:port; write it as "
                                  "tcp://HOST:8786")
    return host.strip("[]") or "127.0.0.1", int(port)


def _recv(sock: socket.socket, n: int) -> bytes:
    data = b""
    while len(data) < n:
        chunk = sock.recv(n - len(data))
        if not chunk:
            break
        data += chunk
    return data


def probe_scheduler(address: str, timeout_s: float = PROBE_TIMEOUT_S) -> None:
    """Return when `address` answers with a Dask handshake header; else SchedulerProbeError
    naming the address, what it answered, and the fix."""
    hp = _host_port(address)
    if hp is None:
        return    # tls://, inproc://, ucx://: Dask's own client checks those
    fix = "give the address of a running Dask scheduler (dask scheduler; port 8786)"
    try:
        sock = socket.create_connection(hp, timeout=timeout_s)
    except OSError as exc:
        raise SchedulerProbeError(f"cannot reach the Dask scheduler at {address} "
                                  f"({exc.strerror or type(exc).__name__}); {fix}") from None
    with sock:
        sock.settimeout(timeout_s)
        try:
            head = _recv(sock, 16)
        except TimeoutError:
            raise SchedulerProbeError(f"{address} sent no Dask handshake within {timeout_s:g} s "
                                      f"(a web server or another service?); {fix}") from None
        except OSError as exc:
            raise SchedulerProbeError(f"{address} dropped the connection "
                                      f"({exc.strerror or type(exc).__name__}); {fix}") from None
        if len(head) < 16:
            raise SchedulerProbeError(f"{address} closed the connection after {len(head)} bytes "
                                      f"without a Dask handshake; {fix}")
        total, frames = struct.unpack("<QQ", head)
        if not (16 <= total + 8 <= MAX_HANDSHAKE_BYTES and 1 <= frames <= MAX_FRAMES
                and total >= 8 * (frames + 1)):
            text = head.decode("ascii", "replace")
            shown = repr(text) if text.isprintable() else f"bytes {head.hex(' ')}"
            raise SchedulerProbeError(f"{address} answers {shown}…, not Dask's protocol; {fix}")
