"""The file side of :class:`cufund.logs.McapLogger`: compresses chunks and writes records on a background thread.

zstd/lz4 compression, the CRC and the file writes release the GIL, so they run beside the simulation on another
core instead of in its loop. Jobs go through a bounded queue (at most ``max_pending`` chunks wait: memory stays
bounded; a producer that outruns the disk waits). Records are written in the order they were submitted.
"""

from __future__ import annotations

import os
import queue
import struct
import threading
import zlib
from typing import IO, Any

from mcap.opcode import Opcode
from mcap.records import ChunkIndex

__all__ = ["ChunkWriter"]

_STOP = object()


class ChunkWriter:
    """Writes raw records and chunks to ``file`` in submission order, on a thread when ``background``."""

    def __init__(self, file: IO[bytes], compression: str, *, background: bool = True, max_pending: int = 8):
        self.file = file
        self.position = file.tell()
        """Where the next record goes (kept here: ``file.tell()`` would be one more hand-over of the GIL)."""
        self.compression = compression
        self._compress = _compressor(compression)
        self.chunk_indexes: list[ChunkIndex] = []
        self._error: BaseException | None = None
        self._pid = os.getpid()
        self._queue: queue.Queue[Any] | None = None
        self._thread: threading.Thread | None = None
        if background:
            self._queue = queue.Queue(maxsize=max_pending)
            self._thread = threading.Thread(target=self._run, name="cufund-mcap-writer", daemon=True)
            self._thread.start()

    def write(self, data: bytes) -> None:
        """Appends already-serialised records."""
        self._submit((self._write, (data,)))

    def chunk(self, raw: bytes, start: int, end: int, indexes: list[tuple[int, bytes]]) -> None:
        """Appends a Chunk of the uncompressed records ``raw`` (log times ``start``..``end``) followed by its
        Message Index records (``indexes``: channel id and the packed (log time, offset) entries)."""
        self._submit((self._write_chunk, (raw, start, end, indexes)))

    def close(self) -> None:
        """Waits for every submitted job; re-raises the first error a job had."""
        if self._thread is not None and self._queue is not None and os.getpid() == self._pid:
            self._queue.put(_STOP)
            self._thread.join()
            self._thread = None
        self._raise()

    def _submit(self, job: tuple[Any, tuple[Any, ...]]) -> None:
        if os.getpid() != self._pid:  # a forked child has the queue but not the thread: it would wait forever
            raise RuntimeError("an McapLogger cannot write from a forked child process; open one there")
        self._raise()
        if self._queue is None:
            job[0](*job[1])
        else:
            self._queue.put(job)

    def _raise(self) -> None:
        if self._error is not None:
            error, self._error = self._error, None
            raise OSError(f"writing the log failed: {error}") from error

    def _run(self) -> None:
        assert self._queue is not None
        while True:
            job = self._queue.get()
            if job is _STOP:
                return
            if self._error is None:
                try:
                    job[0](*job[1])
                except BaseException as exc:  # noqa: BLE001 - handed to the producer thread
                    self._error = exc

    def _write(self, data: bytes) -> None:
        self.file.write(data)
        self.position += len(data)

    def _write_chunk(self, raw: bytes, start: int, end: int, indexes: list[tuple[int, bytes]]) -> None:
        # one file write per chunk: each call that releases the GIL is a hand-over with the simulation's thread
        data = self._compress(raw) if self._compress else raw
        compression = self.compression.encode()
        chunk_start = self.position
        header = struct.pack("<BQQQQII", Opcode.CHUNK, 8 * 3 + 4 + 4 + len(compression) + 8 + len(data), start, end,
                             len(raw), zlib.crc32(raw), len(compression)) + compression + struct.pack("<Q", len(data))
        chunk_length = len(header) + len(data)
        parts = [header, data]
        offsets, position = {}, chunk_start + chunk_length
        for channel_id, entries in indexes:
            offsets[channel_id] = position
            parts += [struct.pack("<BQHI", Opcode.MESSAGE_INDEX, 6 + len(entries), channel_id, len(entries)), entries]
            position += 15 + len(entries)
        self._write(b"".join(parts))
        self.chunk_indexes.append(ChunkIndex(
            message_start_time=start, message_end_time=end, chunk_start_offset=chunk_start,
            chunk_length=chunk_length, message_index_offsets=offsets,
            message_index_length=position - chunk_start - chunk_length, compression=self.compression,
            compressed_size=len(data), uncompressed_size=len(raw)))


def _compressor(name: str) -> Any:
    if name == "zstd":
        import zstandard

        return zstandard.ZstdCompressor(level=1).compress
    if name == "lz4":
        import lz4.frame

        return lz4.frame.compress
    return None
