"""The panel surfaces of a .3dm file as object records written all at once (``save_3dm(engine="fast")``).

rhino3dm adds an object to a model in about seventeen Python calls per panel (corners, name, eight user
strings, ``AddSurface``), each 2–8 µs, and ``File3dm.Encode`` then writes every record chunk by chunk:
about 2.5 s for 10,000 panels. Here the records of all panels are written with NumPy and byte joins, from
**templates**: the records that the installed rhino3dm itself writes, in the same call, for one panel of
each layer, with sentinel values where the panels differ (the four corners, the object id, the name, the
user-text values). The template is rebuilt from its parts and compared byte for byte with rhino3dm's
record before it is used; if the installed openNURBS lays a record out otherwise, :class:`LayoutError` is
raised and ``save_3dm`` writes through rhino3dm instead (slower, the same file).

A .3dm file is a sequence of chunks: a 4-byte type code, then an 8-byte length (files of version 5 and
later) and that many bytes of data — or, for a *short* chunk (type code bit ``0x80000000``), an 8-byte
value and no data. A chunk whose type code has bit ``0x8000`` ends with the CRC-32 (zlib's) of its *own*
bytes, not counting the chunks nested in it (openNURBS ``opennurbs_archive.cpp``: ``BeginWrite3dmBigChunk``,
``EndWrite3dmChunk``, ``UpdateCRC``; type codes from ``opennurbs_3dm.h``). A panel's record::

    OBJECT_RECORD [crc of nothing]
      OBJECT_RECORD_TYPE (short)
      OPENNURBS_CLASS: CLASS_UUID [crc], CLASS_DATA [crc] (the surface; corners at a fixed place), CLASS_END
      OBJECT_RECORD_ATTRIBUTES [crc] (version, object id, layer, name, ...)
      OBJECT_RECORD_ATTRIBUTES_USERDATA (only with user text)
        OPENNURBS_CLASS_USERDATA: 1 byte, USERDATA_HEADER [crc],
          ANONYMOUS [crc of nothing]
            ANONYMOUS [crc]: version, count, one ANONYMOUS [crc] chunk (version, key, value) per user string
        CLASS_END
      OBJECT_RECORD_END (short)

Strings are openNURBS wide strings: an int32 count of UTF-16 code units including the terminating zero,
the UTF-16LE text and two zero bytes.
"""

from __future__ import annotations

import struct
import uuid
import zlib
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from itertools import repeat
from typing import Any

import numpy as np

__all__ = ["LayoutError", "PanelRecords", "panel_records", "random_ids", "splice_records"]

_SHORT, _CRC = 0x80000000, 0x8000
_HEAD = struct.Struct("<IQ")
_U32 = struct.Struct("<I")
_I32 = struct.Struct("<i")
_OBJECT_TABLE = 0x10000013
_OBJECT_RECORD = 0x20008070
_END_OF_FILE = 0x00007FFF
# the CV order of a 2 x 2 NURBS surface in openNURBS: (0,0) (0,1) (1,0) (1,1) = panel corners 0 3 1 2
_CV_CORNER = (0, 3, 1, 2)


class LayoutError(Exception):
    """The installed openNURBS writes a record differently from what this module expects."""


def _chunks(buf: bytes, start: int, end: int) -> list[tuple[int, int, int, int]]:
    """``(type code, chunk start, data start, chunk end)`` of the chunks that fill ``buf[start:end]``."""
    out = []
    pos = start
    while pos < end:
        if pos + 12 > end:
            raise LayoutError(f"a chunk header runs past byte {end}")
        tc, n = _HEAD.unpack_from(buf, pos)
        stop = pos + 12 if tc & _SHORT else pos + 12 + n
        if stop > end:
            raise LayoutError(f"chunk {tc:#x} at byte {pos} runs past byte {end}")
        out.append((tc, pos, pos + 12, stop))
        pos = stop
    return out


def _one(chunks: list[tuple[int, int, int, int]], tc: int, what: str) -> tuple[int, int, int, int]:
    found = [c for c in chunks if c[0] == tc]
    if len(found) != 1:
        raise LayoutError(f"{what}: {len(found)} chunks of type {tc:#x}")
    return found[0]


def _wide(texts: Sequence[str]) -> list[bytes]:
    """openNURBS wide strings: int32 count of UTF-16 units with the terminator, UTF-16LE text, two zero bytes."""
    enc = list(map(str.encode, texts, repeat("utf-16-le")))
    return list(map(b"%s%s\0\0".__mod__, zip(map(_I32.pack, [len(e) // 2 + 1 for e in enc]), enc)))


def _crc4(data: bytes) -> bytes:
    return _U32.pack(zlib.crc32(data))


@dataclass(frozen=True)
class _Strings:
    """The user-text part of a template record (the attributes' user data)."""

    ud_tc: int            # OBJECT_RECORD_ATTRIBUTES_USERDATA
    class_ud_tc: int      # OPENNURBS_CLASS_USERDATA
    lead: bytes           # its version byte and header chunk (constant)
    outer_tc: int         # ANONYMOUS around the list
    outer_crc: bytes
    inner_tc: int         # ANONYMOUS: the list
    inner_direct: bytes   # version and count
    inner_crc: bytes
    tail: bytes           # CLASS_END after the user data
    string_tc: int
    prefixes: tuple[bytes, ...]          # per key: version + key as a wide string
    fixed: tuple[bytes | None, ...]      # per key: the whole chunk when its value is the same for every panel


@dataclass(frozen=True)
class _Template:
    record_tc: int
    record_crc: bytes
    type_chunk: bytes
    class_chunk: bytes    # with the sentinel corners
    coord_at: int         # the 12 corner coordinates (float64) in class_chunk
    data_at: int          # CLASS_DATA's data in class_chunk
    crc_at: int           # CLASS_DATA's CRC in class_chunk
    attr_tc: int
    attr_parts: tuple[bytes, bytes, bytes]   # attributes data = parts[0] + id + parts[1] + name + parts[2]
    strings: _Strings | None
    end_chunk: bytes


def _sentinel_corners(k: int) -> np.ndarray:
    return (1.0e9 + 1024.0 * k + np.arange(12, dtype=np.float64).reshape(4, 3) * 1.125)


def _sentinel_text(k: int, i: int) -> str:
    return f"qn\u00e9{k}sentinel{i}~"


def _parse_template(rec: bytes, k: int, keys: Sequence[str], fixed: dict[str, str], ident: bytes,
                    name: str) -> _Template:
    """Split rhino3dm's record of sentinel panel ``k`` into the parts that are the same for every panel."""
    (rtc, _, r0, r1), = _chunks(rec, 0, len(rec))
    if rtc != _OBJECT_RECORD or not rtc & _CRC:
        raise LayoutError(f"record type {rtc:#x}")
    record_crc = rec[r1 - 4:r1]
    if record_crc != _crc4(b""):
        raise LayoutError("the record holds data besides its chunks")
    parts = _chunks(rec, r0, r1 - 4)
    if len(parts) not in (4, 5):
        raise LayoutError(f"{len(parts)} chunks in a record")
    type_c, class_c, attr_c = parts[:3]
    end_c = parts[-1]
    if not type_c[0] & _SHORT or not end_c[0] & _SHORT:
        raise LayoutError("no short type and end chunks")
    class_chunk = rec[class_c[1]:class_c[3]]
    inner = _chunks(rec, class_c[2], class_c[3])
    data_c = max(inner, key=lambda c: c[3] - c[2])
    if not data_c[0] & _CRC:
        raise LayoutError("the surface data has no CRC")
    cv = _sentinel_corners(k)[list(_CV_CORNER)].astype("<f8").tobytes()
    at = class_chunk.find(cv)
    if at < 0 or class_chunk.find(cv, at + 1) >= 0:
        raise LayoutError("the corners are not stored once, in CV order")
    data_at, crc_at = data_c[2] - class_c[1], data_c[3] - 4 - class_c[1]
    if not data_at <= at and at + len(cv) <= crc_at:
        raise LayoutError("the corners lie outside the surface data")
    # attributes: version, id, layer, name, ...
    atc = attr_c[0]
    if not atc & _CRC:
        raise LayoutError("the attributes have no CRC")
    body = rec[attr_c[2]:attr_c[3] - 4]
    wname = _wide([name])[0]
    i, j = body.find(ident), body.find(wname)
    if i < 0 or j < i + 16 or body.count(ident) != 1 or body.count(wname) != 1:
        raise LayoutError("the object id and name are not found once in the attributes")
    attr_parts = (body[:i], body[i + 16:j], body[j + len(wname):])
    strings = None
    if len(parts) == 5:
        strings = _parse_strings(rec, parts[3], k, keys, fixed)
    elif keys:
        raise LayoutError("no user data in a record with user text")
    return _Template(rtc, record_crc, rec[type_c[1]:type_c[3]], class_chunk, at, data_at, crc_at, atc,
                     attr_parts, strings, rec[end_c[1]:end_c[3]])


def _parse_strings(rec: bytes, ud: tuple[int, int, int, int], k: int, keys: Sequence[str],
                   fixed: dict[str, str]) -> _Strings:
    ud_parts = _chunks(rec, ud[2], ud[3])
    if len(ud_parts) != 2 or not ud_parts[1][0] & _SHORT:
        raise LayoutError("the attribute user data is not one class and its end")
    cud = ud_parts[0]
    # one version byte, the user-data header, the list
    lead_end = cud[2] + 1 + 12 + _HEAD.unpack_from(rec, cud[2] + 1)[1]
    header, outer = _chunks(rec, cud[2] + 1, cud[3])
    if header[3] != lead_end:
        raise LayoutError("no user-data header after the version byte")
    (itc, _, i0, i1), = _chunks(rec, outer[2], outer[3] - 4)
    outer_crc = rec[outer[3] - 4:outer[3]]
    if not outer[0] & _CRC or outer_crc != _crc4(b""):
        raise LayoutError("the user-string list's wrapper holds data")
    direct = rec[i0:i0 + 12]
    strings = _chunks(rec, i0 + 12, i1 - 4)
    if len(strings) != len(keys) or _I32.unpack_from(direct, 8)[0] != len(keys):
        raise LayoutError(f"{len(strings)} user strings where {len(keys)} were set")
    inner_crc = rec[i1 - 4:i1]
    if not itc & _CRC or inner_crc != _crc4(direct):
        raise LayoutError("the user-string list's CRC is not that of its version and count")
    stc = strings[0][0]
    prefixes, fixed_chunks = [], []
    for (tc, c0, s0, s1), key in zip(strings, keys):
        value = fixed.get(key, _sentinel_text(k, keys.index(key)))
        tail = _wide([key])[0] + _wide([value])[0]
        data = rec[s0:s1 - 4]
        if tc != stc or not tc & _CRC or not data.endswith(tail) or rec[s1 - 4:s1] != _crc4(data):
            raise LayoutError(f"the user string {key!r} is not (version, key, value) with its CRC")
        prefix = data[: len(data) - len(tail)] + _wide([key])[0]
        prefixes.append(prefix)
        fixed_chunks.append(rec[c0:s1] if key in fixed else None)
    return _Strings(ud[0], cud[0], rec[cud[2]:lead_end], outer[0], outer_crc, itc, direct, inner_crc,
                    rec[ud_parts[1][1]:ud_parts[1][3]], stc, tuple(prefixes), tuple(fixed_chunks))


@dataclass(frozen=True)
class PanelRecords:
    """Templates of the two kinds of panel record (bilinear, planar) of one file version and key list."""

    templates: tuple[_Template, _Template]
    keys: tuple[str, ...]

    def records(self, flags: np.ndarray, corners: np.ndarray, names: Sequence[str],
                columns: Sequence[Sequence[str]], ids: np.ndarray) -> bytes:
        """The records of all panels, in order, as one byte string.

        Parameters
        ----------
        flags : (m,) bool
            Which template (planar) each panel uses.
        corners : (m, 4, 3) float64
        names : m str
        columns : one sequence of m texts per key that is not fixed per template
        ids : (m, 16) uint8
            Object ids as openNURBS stores them (``uuid.UUID.bytes_le``).
        """
        m = len(flags)
        if m == 0:
            return b""
        t0, t1 = self.templates
        flags = np.asarray(flags, dtype=bool)
        # the surfaces: the template's class chunk with each panel's corners and the data's CRC
        width = len(t0.class_chunk)
        classes = np.empty((m, width), dtype=np.uint8)
        for flag, t in ((False, t0), (True, t1)):
            classes[flags == flag] = np.frombuffer(t.class_chunk, dtype=np.uint8)
        cv = np.ascontiguousarray(corners[:, list(_CV_CORNER)], dtype="<f8").reshape(m, 12)
        classes[:, t0.coord_at:t0.coord_at + 96] = cv.view(np.uint8).reshape(m, 96)
        data = classes[:, t0.data_at:t0.crc_at]
        crcs = np.fromiter(map(zlib.crc32, data), dtype="<u4", count=m)
        classes[:, t0.crc_at:t0.crc_at + 4] = crcs.view(np.uint8).reshape(m, 4)
        class_bytes = classes.tobytes()
        classes_k = [class_bytes[i:i + width] for i in range(0, m * width, width)]
        # the attributes: version, id, layer, name, ...
        pick = [t1 if f else t0 for f in flags.tolist()]
        id_bytes = ids.astype(np.uint8).tobytes()
        idk = [id_bytes[i:i + 16] for i in range(0, 16 * m, 16)]
        attr_bodies = [b"".join((t.attr_parts[0], i, t.attr_parts[1], n, t.attr_parts[2]))
                       for t, i, n in zip(pick, idk, _wide(names))]
        attrs = [b"%s%s%s" % (_HEAD.pack(t0.attr_tc, len(b) + 4), b, _crc4(b)) for b in attr_bodies]
        if t0.strings is None:
            user = [b""] * m
        else:
            user = self._user_data(flags, pick, columns)
        heads = [t.type_chunk for t in pick]
        ends = [t.end_chunk for t in pick]
        bodies = list(map(b"".join, zip(heads, classes_k, attrs, user, ends)))
        crc = t0.record_crc
        return b"".join(b"%s%s%s" % (_HEAD.pack(t0.record_tc, len(b) + 4), b, crc) for b in bodies)

    def _user_data(self, flags: np.ndarray, pick: list[_Template], columns: Sequence[Sequence[str]]) -> list[bytes]:
        s0, s1 = self.templates[0].strings, self.templates[1].strings
        assert s0 is not None and s1 is not None
        per_key = []
        col = iter(columns)
        for i, key in enumerate(self.keys):
            f0, f1 = s0.fixed[i], s1.fixed[i]
            if f0 is not None and f1 is not None:
                per_key.append([f1 if f else f0 for f in flags.tolist()])
                continue
            prefix = s0.prefixes[i]
            data = [prefix + w for w in _wide(next(col))]
            per_key.append([b"%s%s%s" % (_HEAD.pack(s0.string_tc, len(d) + 4), d, _crc4(d)) for d in data])
        lists = list(map(b"".join, zip(*per_key)))
        out = []
        for s, body in zip((s1 if f else s0 for f in flags.tolist()), lists):
            inner = b"%s%s%s%s" % (_HEAD.pack(s.inner_tc, 12 + len(body) + 4), s.inner_direct, body, s.inner_crc)
            outer = b"%s%s%s" % (_HEAD.pack(s.outer_tc, len(inner) + 4), inner, s.outer_crc)
            cud = b"%s%s%s" % (_HEAD.pack(s.class_ud_tc, len(s.lead) + len(outer)), s.lead, outer)
            out.append(b"%s%s%s" % (_HEAD.pack(s.ud_tc, len(cud) + len(s.tail)), cud, s.tail))
        return out


def panel_records(build: Callable[[Any, np.ndarray, list[str], list[list[str]], list[bytes], list[bool]], None],
                  new_model: Callable[[], Any], encode: Callable[[Any], bytes], keys: Sequence[str],
                  fixed: dict[bool, dict[str, str]]) -> PanelRecords:
    """Templates made by rhino3dm: ``build(model, corners, names, columns, ids, flags)`` adds panels to a
    model from ``new_model()`` exactly as the rhino3dm engine does, ``encode(model)`` writes it.

    ``keys`` are the user-text keys in order; ``fixed[flag]`` the keys whose value is the same for every
    panel of that kind (``planar``), with that value.

    Raises
    ------
    LayoutError
        If rhino3dm's records cannot be rebuilt exactly from their parts.
    """
    model = new_model()
    corners = np.stack([_sentinel_corners(k) for k in (0, 1)])
    names = [_sentinel_text(k, -1) for k in (0, 1)]
    varying = [key for key in keys if key not in fixed[False] or key not in fixed[True]]
    columns = [[_sentinel_text(k, list(keys).index(key)) for k in (0, 1)] for key in varying]
    idents = [uuid.UUID(int=(0x51AD0DE5 << 96) + 0x4000_8000_0000_0000_0000 + k) for k in (0, 1)]
    build(model, corners, names, columns, [u.bytes_le for u in idents], [False, True])
    file = encode(model)
    table = [c for c in _chunks(file, 32, len(file)) if c[0] == _OBJECT_TABLE]
    if len(table) != 1:
        raise LayoutError("no single object table")
    recs = [c for c in _chunks(file, table[0][2], table[0][3]) if c[0] == _OBJECT_RECORD]
    if len(recs) != 2:
        raise LayoutError(f"{len(recs)} object records for two panels")
    out = []
    for k, (_, c0, _, c1) in enumerate(recs):
        rec = file[c0:c1]
        t = _parse_template(rec, k, keys, fixed[bool(k)], idents[k].bytes_le, names[k])
        out.append(t)
    records = PanelRecords((out[0], out[1]), tuple(keys))
    ids = np.frombuffer(b"".join(u.bytes_le for u in idents), dtype=np.uint8).reshape(2, 16)
    again = records.records(np.array([False, True]), corners, names, columns, ids)
    if again != b"".join(file[c0:c1] for _, c0, _, c1 in recs):
        raise LayoutError("the records rebuilt from their parts differ from rhino3dm's")
    return records


def splice_records(file: bytes, records: bytes, *, after: int) -> bytes:
    """``file`` (a whole .3dm) with ``records`` inserted into its object table after its first ``after`` records.

    The object table's length and the end-of-file chunk's file length are updated.

    Raises
    ------
    LayoutError
        If the file has no single object table, fewer than ``after`` records, or no end-of-file chunk last.
    """
    top = _chunks(file, 32, len(file))
    table = [c for c in top if c[0] == _OBJECT_TABLE]
    if len(table) != 1 or top[-1][0] != _END_OF_FILE or top[-1][3] - top[-1][2] != 8:
        raise LayoutError("no single object table, or no end-of-file chunk last")
    tc, t0, d0, t1 = table[0]
    if tc & _CRC:
        raise LayoutError("the object table has a CRC")
    recs = _chunks(file, d0, t1)
    if len(recs) <= after or any(c[0] != _OBJECT_RECORD for c in recs[:after]):
        raise LayoutError(f"fewer than {after} records before the table's end")
    at = recs[after][1]
    n = len(records)
    head = file[:t0] + _HEAD.pack(tc, t1 - d0 + n) + file[d0:at]
    rest = bytearray(file[at:])
    rest[-8:] = struct.pack("<Q", len(file) + n)
    return b"".join((head, records, bytes(rest)))


def random_ids(m: int) -> np.ndarray:
    """``(m, 16)`` uint8: random version-4 UUIDs as openNURBS stores them (``uuid.UUID.bytes_le``)."""
    import os

    raw = np.frombuffer(os.urandom(16 * m), dtype=np.uint8).reshape(m, 16).copy()
    # bytes_le: bytes 6-7 hold time_hi_and_version little-endian; byte 8 the variant
    raw[:, 7] = (raw[:, 7] & 0x0F) | 0x40
    raw[:, 8] = (raw[:, 8] & 0x3F) | 0x80
    return raw
