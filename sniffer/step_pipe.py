"""Objects through a pipe with their arrays' memory written as it is, for the decoding process.

:mod:`multiprocessing`'s ``Connection.send`` pickles an object into one bytes object (a copy of
every array in it), and ``recv`` reads that into a buffer (a copy), and the arrays out of it
(another copy). Here the object is pickled with protocol 5, its arrays left out of the pickle
(``buffer_callback``), and each array's memory is written to the pipe as it lies; the reader
reads each one straight into a ``bytearray`` of its own (``os.readv``), and the arrays are
made on those, writable, without a copy: most of what the decoding steps send is arrays.

On the wire, a message is: the number of parts ``n`` (8 bytes, little-endian), the ``n`` parts'
sizes (8 bytes each), then the parts: the pickle, then the arrays' memory in the order pickle
gave them. POSIX only, as the decoding process is (it exists where ``os.fork`` does).
"""

from __future__ import annotations

import os
import pickle
import struct

_SIZE = struct.Struct("<Q")


def send_item(fd: int, item: object) -> None:
    """Write ``item`` to the pipe ``fd`` (see the module docstring). Pickled first: an object
    that does not pickle raises before anything is written. ``OSError`` if the reader is gone."""
    buffers: list[pickle.PickleBuffer] = []
    head = pickle.dumps(item, protocol=5, buffer_callback=buffers.append)
    views = [buffer.raw() for buffer in buffers]
    sizes = [len(head), *(view.nbytes for view in views)]
    _write_all(fd, [struct.pack(f"<{len(sizes) + 1}Q", len(sizes), *sizes), head, *views])


def receive_item(fd: int) -> object:
    """The next item written by :func:`send_item` to the pipe ``fd``; ``EOFError`` where the
    pipe ends before one is whole."""
    (parts,) = _SIZE.unpack(_read_exactly(fd, _SIZE.size))
    sizes = struct.unpack(f"<{parts}Q", _read_exactly(fd, _SIZE.size * parts))
    head = _read_exactly(fd, sizes[0])
    buffers = [_read_exactly(fd, size) for size in sizes[1:]]
    return pickle.loads(head, buffers=buffers)


def _write_all(fd: int, parts: list[bytes | memoryview]) -> None:
    for part in parts:
        view = memoryview(part)
        while view.nbytes:
            view = view[os.write(fd, view) :]


def _read_exactly(fd: int, size: int) -> bytearray:
    into = bytearray(size)
    view, done = memoryview(into), 0
    while done < size:
        read = os.readv(fd, [view[done:]])
        if read == 0:
            raise EOFError(f"the pipe ended {size - done} bytes short of a part of {size}")
        done += read
    return into
