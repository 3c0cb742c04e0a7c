r"""Clear the "open for write" status flags a crashed SWMR writer leaves in an HDF5 file (like ``h5clear -s``).

A run log is written in SWMR mode (``libver="latest"``, superblock version 3).  While a writer has the file
open, the superblock's *file consistency flags* (byte 11) say so; a writer that is killed never resets them,
and every HDF5 reader that does not open the file in SWMR-read mode then refuses it ("file is already open
for write (may use <h5clear file> ...)").  h5py has no ``h5clear``; the flags are one byte of the superblock,
which is protected by a checksum (Jenkins' lookup3, ``H5_checksum_lookup3``), so clearing them is: check the
signature and version, check the stored checksum (refuse a superblock we do not understand), zero the byte,
write the new checksum.  Superblock versions 2 and 3 (HDF5 file format specification, "Superblock"):

====== ====================================================
offset field
====== ====================================================
0      signature ``\x89HDF\r\n\x1a\n`` (8 bytes)
8      version (2 or 3)
9, 10  size of offsets O, size of lengths
11     file consistency flags
12     base address, superblock extension, end of file, root object header (4 × O bytes)
12+4O  checksum (4 bytes, lookup3 of the bytes before it)
====== ====================================================

Only a file whose writer is gone may be cleared (a live writer's readers must use SWMR); the run log stores
its writer's host and process id for that decision (:func:`hardware.runlog.recover_crashed_log`).
"""

from __future__ import annotations

import pathlib
import struct

SIGNATURE = b"\x89HDF\r\n\x1a\n"
_M = 0xFFFFFFFF


def _rot(x: int, k: int) -> int:
    return ((x << k) | (x >> (32 - k))) & _M


def lookup3(data: bytes, initval: int = 0) -> int:
    """Bob Jenkins' lookup3 ``hashlittle`` (byte-wise form), the checksum HDF5 uses for its metadata."""
    n = len(data)
    a = b = c = (0xDEADBEEF + n + initval) & _M
    k = 0
    while n > 12:
        a = (a + int.from_bytes(data[k:k + 4], "little")) & _M
        b = (b + int.from_bytes(data[k + 4:k + 8], "little")) & _M
        c = (c + int.from_bytes(data[k + 8:k + 12], "little")) & _M
        a = (a - c) & _M; a ^= _rot(c, 4); c = (c + b) & _M         # noqa: E702 - the mix() of lookup3
        b = (b - a) & _M; b ^= _rot(a, 6); a = (a + c) & _M         # noqa: E702
        c = (c - b) & _M; c ^= _rot(b, 8); b = (b + a) & _M         # noqa: E702
        a = (a - c) & _M; a ^= _rot(c, 16); c = (c + b) & _M        # noqa: E702
        b = (b - a) & _M; b ^= _rot(a, 19); a = (a + c) & _M        # noqa: E702
        c = (c - b) & _M; c ^= _rot(b, 4); b = (b + a) & _M         # noqa: E702
        n -= 12
        k += 12
    if n == 0:
        return c
    tail = data[k:k + n] + bytes(12 - n)
    a = (a + int.from_bytes(tail[0:4], "little")) & _M
    b = (b + int.from_bytes(tail[4:8], "little")) & _M
    c = (c + int.from_bytes(tail[8:12], "little")) & _M
    c ^= b; c = (c - _rot(b, 14)) & _M                               # noqa: E702 - the final() of lookup3
    a ^= c; a = (a - _rot(c, 11)) & _M                               # noqa: E702
    b ^= a; b = (b - _rot(a, 25)) & _M                               # noqa: E702
    c ^= b; c = (c - _rot(b, 16)) & _M                               # noqa: E702
    a ^= c; a = (a - _rot(c, 4)) & _M                                # noqa: E702
    b ^= a; b = (b - _rot(a, 14)) & _M                               # noqa: E702
    c ^= b; c = (c - _rot(b, 24)) & _M                               # noqa: E702
    return c


def _superblock(path) -> tuple[bytes, int]:
    """(superblock bytes up to the checksum, checksum offset) of a version 2/3 superblock at offset 0, or
    ValueError."""
    with open(path, "rb") as f:
        head = f.read(12)
        if len(head) < 12 or head[:8] != SIGNATURE:
            raise ValueError("not an HDF5 file with its superblock at offset 0")
        if head[8] not in (2, 3):
            raise ValueError(f"superblock version {head[8]} (only versions 2 and 3 have status flags here)")
        o = head[9]
        if o not in (2, 4, 8, 16, 32):
            raise ValueError(f"implausible size of offsets {o}")
        end = 12 + 4 * o
        f.seek(0)
        body = f.read(end + 4)
    if len(body) < end + 4:
        raise ValueError("the superblock is truncated")
    stored = struct.unpack("<I", body[end:end + 4])[0]
    if lookup3(body[:end]) != stored:
        raise ValueError("the superblock checksum does not match: not touching this file")
    return body[:end], end


def status_flags(path) -> int:
    """The file consistency flags of the superblock (0: closed cleanly; ValueError if unreadable)."""
    return _superblock(path)[0][11]


def clear_status_flags(path) -> bool:
    """Zero the status flags (and rewrite the superblock checksum); True if they were set.  The caller
    must know that no writer holds the file.  A file shorter than the end-of-file address its superblock
    records (truncated) is refused (ValueError): it is left as it is for the reader to report."""
    body, end = _superblock(path)
    if body[11] == 0:
        return False
    o = body[9]
    eof = int.from_bytes(body[12 + 2 * o:12 + 3 * o], "little")
    size = pathlib.Path(path).stat().st_size
    if size < eof:
        raise ValueError(f"the file is {size} bytes but its superblock says {eof}: truncated, not touching it")
    new = body[:11] + b"\x00" + body[12:]
    with open(pathlib.Path(path), "r+b") as f:
        f.seek(11)
        f.write(b"\x00")
        f.seek(end)
        f.write(struct.pack("<I", lookup3(new)))
    return True
