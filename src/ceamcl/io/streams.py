"""Input files that may be streams: sniffed from a kept buffer, read whole or refused clearly.

A log given as ``<(bzcat log.bz2)`` or a FIFO is a pipe: it can be read once, has no known
length and may never end. :func:`sniff` reads the first bytes of such a stream into a buffer
that is kept (per path, for this process), and :func:`open_input` hands back a reader that
serves those bytes again before the rest of the stream, so format sniffing costs nothing.

Bounds (docs/robustness.md):

* a non-regular file is opened without blocking; when no byte arrives for
  :func:`wait_seconds` (10 s, ``CEAMCL_STREAM_WAIT_S``) the read is refused: a FIFO with no
  writer is an error, not a hang;
* it may deliver at most the budget's ``stream_bytes`` (:mod:`ceamcl.budget`); ``/dev/zero``
  or an endless generator is refused when that is reached (or sooner, at the line-length
  bound, by the text readers).

Regular files are opened as usual (their size is known, and readers stream them).
"""

from __future__ import annotations

import io
import os
import select
import stat

from ceamcl import budget
from ceamcl.errors import CeamclError

__all__ = ["StreamError", "is_stream", "open_input", "read_all", "sniff", "wait_seconds"]

DEFAULT_WAIT_S = 10.0
_kept: dict[str, _SniffedStream] = {}


class StreamError(CeamclError, ValueError):
    """A stream cannot be read: nothing arrives, or it goes on beyond the bound."""


def wait_seconds() -> float:
    """How long a stream may stay silent before it is refused (``CEAMCL_STREAM_WAIT_S``)."""
    try:
        value = float(os.environ.get("CEAMCL_STREAM_WAIT_S", DEFAULT_WAIT_S))
    except ValueError:
        return DEFAULT_WAIT_S
    return value if value > 0 else DEFAULT_WAIT_S


def is_stream(path: str | os.PathLike[str]) -> bool:
    """Whether ``path`` exists and is not a regular file or folder (a pipe, FIFO, device)."""
    try:
        mode = os.stat(path).st_mode
    except OSError:
        return False
    return not (stat.S_ISREG(mode) or stat.S_ISDIR(mode))


class _SniffedStream(io.RawIOBase):
    """A non-blocking file descriptor read with a wait bound and a byte bound, whose first
    bytes (``head``) are kept and served again after a rewind."""

    def __init__(self, path: str, what: str) -> None:
        super().__init__()
        self.path, self.what = path, what
        self.fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK)
        self.head = b""
        self.pos = 0  # position within head while replaying it
        self.delivered = 0
        self.started = False
        self.limit = budget.current().stream_bytes

    def readable(self) -> bool:
        return True

    def _wait(self) -> None:
        poller = select.poll()
        poller.register(self.fd, select.POLLIN | select.POLLHUP | select.POLLERR)
        if not poller.poll(wait_seconds() * 1000.0):
            raise StreamError(
                f"{self.path}: no data arrived for {wait_seconds():g} s (a pipe or FIFO with "
                f"no writer?); expected a {self.what}"
            )

    def _read_fd(self, n: int) -> bytes:
        if not self.started:  # a FIFO with no writer reads as EOF: wait for one (or data)
            self._wait()
            self.started = True
        while True:
            try:
                data = os.read(self.fd, n)
            except BlockingIOError:
                self._wait()
                continue
            if data:
                self.delivered += len(data)
                if self.delivered > self.limit:
                    raise StreamError(
                        f"{self.path}: the stream goes on beyond {budget.format_bytes(self.limit)}"
                        " (the stream bound of the memory budget; raise it with --memory-budget)"
                    )
            return data

    def fill_head(self, n: int) -> bytes:
        while len(self.head) < n:
            data = self._read_fd(n - len(self.head))
            if not data:
                break
            self.head += data
        return self.head[:n]

    def readinto(self, b: bytearray | memoryview) -> int:  # type: ignore[override]
        if self.pos < len(self.head):
            chunk = self.head[self.pos : self.pos + len(b)]
            self.pos += len(chunk)
            b[: len(chunk)] = chunk
            return len(chunk)
        data = self._read_fd(len(b))
        b[: len(data)] = data
        return len(data)

    def close(self) -> None:
        if not self.closed:
            os.close(self.fd)
        super().close()


def sniff(path: str | os.PathLike[str], n: int, what: str = "file") -> bytes:
    """The first ``n`` bytes of ``path`` (fewer if it is shorter), without consuming a stream.

    Raises :class:`OSError` as ``open`` does (missing file, permissions).
    """
    key = str(path)
    if not is_stream(key):
        with open(key, "rb") as fh:
            return fh.read(n)
    stream = _kept.get(key)
    if stream is None:
        stream = _SniffedStream(key, what)
        _kept[key] = stream
    return stream.fill_head(n)


def open_input(path: str | os.PathLike[str], what: str = "file") -> io.BufferedIOBase:
    """A binary reader over ``path``: a regular file, or a stream replayed from its kept head."""
    key = str(path)
    if not is_stream(key):
        return open(key, "rb")
    stream = _kept.pop(key, None) or _SniffedStream(key, what)
    stream.pos = 0
    return io.BufferedReader(stream, buffer_size=1 << 16)


def read_all(path: str | os.PathLike[str], limit: int, what: str = "file") -> bytes:
    """The whole content of ``path`` (file or stream) if it holds at most ``limit`` bytes."""
    with open_input(path, what) as fh:
        data = fh.read(limit + 1)
    if len(data) > limit:
        raise StreamError(
            f"{path}: larger than {budget.format_bytes(limit)}, the bound for a {what}"
        )
    return data
