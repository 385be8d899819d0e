"""Check HDF5's global heap collections ourselves, before the HDF5 library reads them.

Variable-length strings (everything a run file writes once at creation: start time, configuration,
JSON fields, the string attributes) live in global heap collections (HDF5 file format
specification, "Global Heap"): a 16-byte header (signature ``GCOL``, version 1, three reserved
bytes, the collection's size in bytes, header included, at least 4096) followed by objects, each a
16-byte header (index: 2 bytes, reference count: 2, reserved: 4, size: 8, for 8-byte lengths) and
its data padded to a multiple of 8 bytes; object 0 is the free space, its size counting its header
and not padded. The objects tile the collection exactly; a tail too short for an object header is
free space too.

A collection has no checksum, and the library walks its objects by their sizes: HDF5 2.0.0 (the
one h5py 3.16 ships) refuses an object running past the collection's end, but a free space of size
0 makes its walk stand still, so zeroed or flipped bytes there make it loop for ever inside one
call (``H5HG__cache_heap_deserialize``), in C, where neither a timeout nor Ctrl-C can reach it
(older versions also followed sizes out of the collection). :func:`check_global_heaps` walks every
collection the same way in Python first and raises :class:`HeapDamageError` (one line) wherever the
collection does not check out: signature, version, size (at least 4096, a multiple of 8, inside the
file), objects that do not tile it (a free space smaller than an object header or not a multiple of
8, an object running past its end), an object index used twice.

The library reads a collection only through a reference to one of its objects (a "heap ID": 4
bytes of length, the collection's address, a 4-byte index), held by variable-length data: the value
of a string attribute (in its object's header) or of a string dataset (its raw data). So
:func:`check_global_heaps` lists every object through HDF5 (which reads no variable-length data to
do so: object headers, checksummed), reads the heap IDs of its attributes from its object header
(parsed here: header versions 1 and 2, attribute messages 1 to 3) and those of a string dataset
from the file, and checks each collection they name. That does not depend on the file's size:
about 15 ms (median, 5 ms at best, on a loaded 2-core machine) for a 0.9 GB run file with 43,500
camera frames as for a 1 MB one, against 30-70 ms for the metadata walk that follows and about
0.6 s for ``RunReader`` with its summary. A file this does not cover (attributes in dense storage,
shared messages, references, compound or array types, string datasets chunked or compact: none in
a run file; or an object header this parser trips on) is checked exhaustively instead: every
collection found by its signature in every byte that is no dataset's raw data (the chunks, located
through HDF5's checksummed chunk indexes): about 0.3-0.5 s for that 0.9 GB file.

Imports only h5py (and the standard library).
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import BinaryIO

import h5py

SIGNATURE = b"GCOL"
VERSION = 1
MIN_COLLECTION_BYTES = 4096
"""The specification's minimum (and default) collection size; HDF5 reads this much first."""
_READ_BYTES = 1 << 20


class HeapDamageError(Exception):
    """A global heap collection the HDF5 library must not be given (one-line message)."""


def check_global_heaps(f: h5py.File, fh: BinaryIO, size_bytes: int, *,
                       exhaustive: bool = False) -> int:
    """Check every global heap collection of the open file ``f`` that HDF5 could read (``fh``
    reads the same file, of ``size_bytes`` bytes); returns how many were checked and raises
    :class:`HeapDamageError` on the first one that does not check out. Reads no variable-length
    data through HDF5. ``exhaustive``: find the collections by their signature (the fallback)."""
    sizes = f.id.get_create_plist().get_sizes()
    size_of_offsets, size_of_lengths = int(sizes[0]), int(sizes[1])
    try:
        if exhaustive:
            raise _NotCoveredError("asked for")
        references = _heap_references(f, fh, size_of_offsets, size_of_lengths)
    except (_NotCoveredError, IndexError, ValueError):  # not parsed here: find every collection
        return _check_every_collection(f, fh, size_bytes, size_of_lengths)
    for address, holder in sorted(references.items()):
        fh.seek(address)
        if fh.read(len(SIGNATURE)) != SIGNATURE:
            raise HeapDamageError(f"{holder} refers to a global heap collection at byte "
                                  f"{address:,}, where there is none")
        check_collection(fh, address, size_bytes, size_of_lengths)
    return len(references)


def check_collection(fh: BinaryIO, at: int, size_bytes: int, size_of_lengths: int = 8) -> int:
    """Check the collection whose signature is at byte ``at``; returns its size in bytes."""
    where = f"global heap collection at byte {at:,}"
    header = 8 + size_of_lengths
    fh.seek(at)
    head = fh.read(header)
    if len(head) < header:
        raise HeapDamageError(f"{where}: cut short by the end of the file")
    if head[4] != VERSION:
        raise HeapDamageError(f"{where}: version {head[4]}, not {VERSION}")
    size = int.from_bytes(head[8:header], "little")
    if size < MIN_COLLECTION_BYTES or size % 8:
        raise HeapDamageError(f"{where}: size {size:,} bytes (at least "
                              f"{MIN_COLLECTION_BYTES:,}, a multiple of 8)")
    if at + size > size_bytes:
        raise HeapDamageError(f"{where}: its {size:,} bytes run past the end of the file "
                              f"({size_bytes:,} bytes)")
    fh.seek(at)
    data = fh.read(size)
    if len(data) < size:
        raise HeapDamageError(f"{where}: cut short by the end of the file")
    _check_objects(data, header, size_of_lengths, where)
    return size


def _check_objects(data: bytes, header: int, size_of_lengths: int, where: str) -> None:
    """Walk the objects as the HDF5 library does (``H5HG__cache_heap_deserialize``)."""
    object_header = 8 + size_of_lengths
    end = len(data)
    seen: set[int] = set()
    p = header
    while p < end:
        if end - p < object_header:
            return  # a tail too small for an object header is free space
        index = int.from_bytes(data[p : p + 2], "little")
        size = int.from_bytes(data[p + 8 : p + object_header], "little")
        if index in seen:
            what = "the free space appears" if index == 0 else f"object index {index} is used"
            raise HeapDamageError(f"{where}: {what} twice (byte {p:,} of it)")
        seen.add(index)
        if index == 0:  # the free space: its size counts its header and is not padded
            if size < object_header or size % 8:
                raise HeapDamageError(f"{where}: free space of {size:,} bytes at byte {p:,} of "
                                      f"it (at least {object_header}, a multiple of 8)")
            need = size
        else:
            need = object_header + (size + 7) // 8 * 8
        if p + need > end:
            raise HeapDamageError(f"{where}: object {index} at byte {p:,} of it has {size:,} "
                                  f"bytes, past the collection's end ({end:,} bytes)")
        p += need


class _NotCoveredError(Exception):
    """A file whose heap references are not all found by :func:`_heap_references`."""


def _check_every_collection(f: h5py.File, fh: BinaryIO, size_bytes: int,
                            size_of_lengths: int) -> int:
    """Find every collection by its signature outside the datasets' raw data; check each."""
    n = 0
    for start, end in _gaps(_raw_data_extents(f), size_bytes):
        at = start
        while True:
            found = _find(fh, SIGNATURE, at, end)
            if found is None:
                break
            at = found + check_collection(fh, found, size_bytes, size_of_lengths)
            n += 1
    return n


def _heap_references(f: h5py.File, fh: BinaryIO, so: int, sl: int) -> dict[int, str]:
    """The collections that the file's variable-length data refer to: address -> what refers to
    it first (for the message). :class:`_NotCoveredError` for what this does not parse."""
    found: dict[int, str] = {}

    def add(ids: bytes, holder: str) -> None:
        step = 8 + so
        for i in range(0, len(ids) - step + 1, step):
            address = int.from_bytes(ids[i + 4 : i + 4 + so], "little")
            if address != 0 and address != (1 << (8 * so)) - 1:  # 0 / undefined: no data
                found.setdefault(address, holder)

    def visit(name: bytes, info: h5py.h5o.ObjInfo) -> None:  # h5py's low level: no wrapping
        where = "/" + name.decode("utf-8", "replace").strip("/").removeprefix(".")
        for attr, ids in _attribute_heap_ids(fh, int(info.addr), so, sl):
            add(ids, f"{where} attribute {attr!r}")
        if info.type == h5py.h5o.TYPE_DATASET:
            add(_dataset_heap_ids(h5py.h5d.open(f.id, name), fh, so, where), where)
        elif info.type != h5py.h5o.TYPE_GROUP:
            raise _NotCoveredError(where)  # a committed datatype

    visit(b".", h5py.h5o.get_info(f.id))  # the root: h5py's visit leaves it out
    h5py.h5o.visit(f.id, visit, info=True)  # every other object once
    return found


def _dataset_heap_ids(dsid: h5py.h5d.DatasetID, fh: BinaryIO, so: int, where: str) -> bytes:
    """The heap IDs a dataset's raw data holds (b"" for a type without variable-length data)."""
    dtype = dsid.get_type()
    cls = dtype.get_class()
    if cls == h5py.h5t.STRING and not dtype.is_variable_str():
        return b""
    if cls in (h5py.h5t.INTEGER, h5py.h5t.FLOAT, h5py.h5t.BITFIELD, h5py.h5t.OPAQUE,
               h5py.h5t.ENUM, h5py.h5t.TIME):
        return b""
    layout = dsid.get_create_plist().get_layout()
    if cls != h5py.h5t.STRING or layout != h5py.h5d.CONTIGUOUS:
        raise _NotCoveredError(where)  # compound, array, sequence, reference; chunked or compact
    offset = dsid.get_offset()
    if offset is None:
        return b""  # never written
    fh.seek(offset)
    return fh.read(dsid.get_space().get_simple_extent_npoints() * (8 + so))


def _attribute_heap_ids(fh: BinaryIO, address: int, so: int,
                        sl: int) -> Iterator[tuple[str, bytes]]:
    """(name, heap IDs) of every attribute of variable-length strings in the object header at
    ``address``; :class:`_NotCoveredError` for what is not parsed here (dense attribute storage,
    shared messages, attribute types holding other variable-length data or references)."""
    for kind, flags, body in _header_messages(fh, address, so, sl):
        if kind == _ATTRIBUTE_INFO:
            heap_at = 2 + (2 if body[1] & 1 else 0)
            heap = int.from_bytes(body[heap_at : heap_at + so], "little")
            if heap != (1 << (8 * so)) - 1:
                raise _NotCoveredError("dense attribute storage")
        elif kind == _ATTRIBUTE:
            if flags & 0x02:
                raise _NotCoveredError("shared attribute message")
            yield from _attribute(body, sl)


def _attribute(body: bytes, sl: int) -> Iterator[tuple[str, bytes]]:
    version = body[0]
    if version not in (1, 2, 3) or (version > 1 and body[1] & 0x03):
        raise _NotCoveredError("attribute message")  # shared datatype or dataspace
    name_size, type_size, space_size = (int.from_bytes(body[i : i + 2], "little")
                                        for i in (2, 4, 6))
    at = 9 if version == 3 else 8

    def field(n: int) -> bytes:
        nonlocal at
        out = body[at : at + n]
        at += (n + 7) // 8 * 8 if version == 1 else n
        return out

    name = field(name_size).rstrip(b"\0").decode("utf-8", "replace")
    datatype = field(type_size)
    dataspace = field(space_size)
    cls, bits = datatype[0] & 0x0F, datatype[1] & 0x0F
    if cls in (0, 1, 2, 3, 4, 5, 8):  # fixed-size numbers, strings, bit fields, opaque, enums
        return
    if cls != 9 or bits != 1:  # 9: variable-length; string
        raise _NotCoveredError("attribute type")
    count = _element_count(dataspace, sl)
    yield name, body[at : at + count * int.from_bytes(datatype[4:8], "little")]


def _element_count(dataspace: bytes, sl: int) -> int:
    version, rank = dataspace[0], dataspace[1]
    if version == 1:
        dims_at = 8
    elif version == 2:
        if dataspace[3] == 2:  # null dataspace
            return 0
        dims_at = 4
    else:
        raise _NotCoveredError("dataspace")
    count = 1
    for i in range(rank):
        count *= int.from_bytes(dataspace[dims_at + i * sl : dims_at + (i + 1) * sl], "little")
    return count


_ATTRIBUTE = 0x0C
_ATTRIBUTE_INFO = 0x15
_CONTINUATION = 0x10
_MAX_HEADER_CHUNKS = 10_000


def _header_messages(fh: BinaryIO, address: int, so: int,
                     sl: int) -> Iterator[tuple[int, int, bytes]]:
    """(type, flags, body) of every message of the object header at ``address``, following
    continuation messages (HDF5 file format specification, "Data Object Headers")."""
    fh.seek(address)
    head = fh.read(16)
    if head[:4] == b"OHDR":
        version, flags = head[4], head[5]
        at = 6 + (16 if flags & 0x20 else 0) + (4 if flags & 0x10 else 0)
        width = 1 << (flags & 0x03)
        fh.seek(address + at)
        size = int.from_bytes(fh.read(width), "little")
        chunks = [(address + at + width, size)]  # the first chunk's messages (checksum after)
        order = bool(flags & 0x04)
    elif head[0] == 1:
        version, order = 1, False
        chunks = [(address + 16, int.from_bytes(head[8:12], "little"))]
    else:
        raise _NotCoveredError("object header")
    seen = 0
    while chunks:
        start, size = chunks.pop(0)
        seen += 1
        if seen > _MAX_HEADER_CHUNKS or size > 1 << 32:
            raise _NotCoveredError("object header")
        fh.seek(start)
        data = fh.read(size)
        if len(data) < size:
            raise _NotCoveredError("object header")
        p, end = 0, size
        if version == 2:
            header = 4 + (2 if order else 0)
            if seen > 1:  # a continuation chunk: "OCHK", the messages, a checksum
                if data[:4] != b"OCHK":
                    raise _NotCoveredError("object header")
                p, end = 4, size - 4
        else:
            header = 8
        while p + header <= end:
            if version == 2:
                kind, length, mflags = data[p], int.from_bytes(data[p + 1 : p + 3], "little"), \
                    data[p + 3]
            else:
                kind = int.from_bytes(data[p : p + 2], "little")
                length = int.from_bytes(data[p + 2 : p + 4], "little")
                mflags = data[p + 4]
            body = data[p + header : p + header + length]
            p += header + length
            if len(body) < length:
                raise _NotCoveredError("object header")
            if kind == _CONTINUATION:
                chunks.append((int.from_bytes(body[:so], "little"),
                               int.from_bytes(body[so : so + sl], "little")))
            else:
                yield kind, mflags, body


def _raw_data_extents(f: h5py.File) -> list[tuple[int, int]]:
    """(offset, size) of every dataset's raw data in the file: chunks and contiguous blocks."""
    extents: list[tuple[int, int]] = []

    def chunk(info: h5py.h5d.StoreInfo) -> None:
        extents.append((int(info.byte_offset), int(info.size)))

    def visit(_name: str, obj: object) -> None:
        if not isinstance(obj, h5py.Dataset):
            return
        dsid = obj.id
        if obj.chunks is not None:
            dsid.chunk_iter(chunk)
            return
        offset = dsid.get_offset()  # None when compact (data in the object header) or unwritten
        if offset is not None:
            extents.append((int(offset), int(dsid.get_storage_size())))

    f.visititems(visit)
    return extents


def _gaps(extents: list[tuple[int, int]], size_bytes: int) -> Iterator[tuple[int, int]]:
    """The byte ranges of ``[0, size_bytes)`` that no extent covers, in order."""
    at = 0
    for offset, size in sorted(extents):
        if offset > at:
            yield at, min(offset, size_bytes)
        at = max(at, offset + size)
        if at >= size_bytes:
            return
    if at < size_bytes:
        yield at, size_bytes


def _find(fh: BinaryIO, needle: bytes, start: int, end: int) -> int | None:
    """The first offset in ``[start, end)`` where ``needle`` begins (within the range)."""
    overlap = len(needle) - 1
    at = start
    while at < end:
        fh.seek(at)
        block = fh.read(min(_READ_BYTES, end - at))
        if len(block) < len(needle):
            return None
        i = block.find(needle)
        if i >= 0:
            return at + i
        if len(block) < _READ_BYTES:
            return None
        at += len(block) - overlap
    return None
