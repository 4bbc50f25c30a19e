"""Panel surfaces and structure lines of a .3dm file as object records written at once (``save_3dm(engine="fast")``).

rhino3dm adds an object to a model in about seventeen Python calls per panel (corners, name, eight user
strings, ``AddSurface``), each 2–8 µs, and ``File3dm.Encode`` then writes every record chunk by chunk:
about 3 s of CPU for 10,000 panels. Here the records of all panels are written with NumPy and byte joins,
from **templates**: the records that the installed rhino3dm itself writes, in the same call, for one panel
of each layer (and two polylines), with sentinel values where the objects differ (the corners or points,
the object id, the name, the user-text values). A template is rebuilt from its parts and compared byte
for byte with rhino3dm's records before it is used; if the installed openNURBS lays a record out
otherwise, :class:`LayoutError` is raised and ``save_3dm`` writes through rhino3dm instead (slower, the
same file).

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

import io
import struct
import uuid
import zlib
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from itertools import chain, repeat
from typing import Any, BinaryIO

import numpy as np

__all__ = ["LayoutError", "PanelRecords", "PolylineRecords", "panel_records", "polyline_records", "random_ids",
           "splice_records", "write_records"]

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
    rtc, record_crc, parts = _record_parts(rec)
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
    if not (data_at <= at and at + len(cv) <= crc_at):
        raise LayoutError("the corners lie outside the surface data")
    atc, attr_parts = _attributes(rec, attr_c, ident, name)
    strings = None
    if len(parts) == 5:
        strings = _parse_strings(rec, parts[3], k, keys, fixed)
    elif keys:
        raise LayoutError("no user data in a record with user text")
    return _Template(rtc, record_crc, rec[type_c[1]:type_c[3]], class_chunk, at, data_at, crc_at, atc,
                     attr_parts, strings, rec[end_c[1]:end_c[3]])


def _attributes(rec: bytes, attr_c: tuple[int, int, int, int], ident: bytes,
                name: str) -> tuple[int, tuple[bytes, bytes, bytes]]:
    """The attributes chunk's type code and its data around the object id and the name."""
    atc = attr_c[0]
    if not atc & _CRC:
        raise LayoutError("the attributes have no CRC")
    body = rec[attr_c[2]:attr_c[3] - 4]
    wname = _wide([name])[0]
    i, j = body.find(ident), body.find(wname)
    if i < 0 or j < i + 16 or body.count(ident) != 1 or body.count(wname) != 1:
        raise LayoutError("the object id and name are not found once in the attributes")
    return atc, (body[:i], body[i + 16:j], body[j + len(wname):])


def _record_parts(rec: bytes) -> tuple[int, bytes, list[tuple[int, int, int, int]]]:
    """The record's type code, its CRC, and its chunks (checked: type first and end last, both short)."""
    (rtc, _, r0, r1), = _chunks(rec, 0, len(rec))
    if rtc != _OBJECT_RECORD or not rtc & _CRC:
        raise LayoutError(f"record type {rtc:#x}")
    record_crc = rec[r1 - 4:r1]
    if record_crc != _crc4(b""):
        raise LayoutError("the record holds data besides its chunks")
    parts = _chunks(rec, r0, r1 - 4)
    if len(parts) < 4 or not parts[0][0] & _SHORT or not parts[-1][0] & _SHORT:
        raise LayoutError("no short type and end chunks around a record")
    return rtc, record_crc, parts


@dataclass(frozen=True)
class PolylineRecords:
    """The template of a polyline's object record (the structure lines): its points vary in number.

    The polyline's data (openNURBS ``ON_PolylineCurve::Write``): a version byte, the points (an int32
    count and the coordinates), the parameters (a count and 0, 1, 2, ...) and the dimension.
    """

    record_tc: int
    record_crc: bytes
    type_chunk: bytes
    class_tc: int
    uuid_chunk: bytes
    data_tc: int
    lead: bytes
    tail: bytes
    class_end: bytes
    attr_tc: int
    attr_parts: tuple[bytes, bytes, bytes]
    end_chunk: bytes

    def records(self, points: Sequence[np.ndarray], names: Sequence[str], ids: np.ndarray) -> bytes:
        """The records of polylines through ``points[i]`` ``(n_i, 3)``, named ``names[i]``, with object ids
        ``ids`` ``(k, 16)`` uint8 (``UUID.bytes_le``)."""
        out = []
        for pts, name, ident in zip(points, _wide(names), np.ascontiguousarray(ids, dtype=np.uint8)):
            n = len(pts)
            data = b"".join((self.lead, _I32.pack(n), np.ascontiguousarray(pts, dtype="<f8").tobytes(),
                             _I32.pack(n), np.arange(n, dtype="<f8").tobytes(), self.tail))
            data = b"%s%s%s" % (_HEAD.pack(self.data_tc, len(data) + 4), data, _crc4(data))
            body = b"".join((self.uuid_chunk, data, self.class_end))
            klass = _HEAD.pack(self.class_tc, len(body)) + body
            attr = b"".join((self.attr_parts[0], ident.tobytes(), self.attr_parts[1], name, self.attr_parts[2]))
            attr = b"%s%s%s" % (_HEAD.pack(self.attr_tc, len(attr) + 4), attr, _crc4(attr))
            body = b"".join((self.type_chunk, klass, attr, self.end_chunk))
            out.append(b"%s%s%s" % (_HEAD.pack(self.record_tc, len(body) + 4), body, self.record_crc))
        return b"".join(out)


def polyline_records(build: Callable[[Any, list[np.ndarray], list[str], list[bytes]], None],
                     new_model: Callable[[], Any], encode: Callable[[Any], bytes]) -> PolylineRecords:
    """The polyline record template made by rhino3dm: ``build(model, points, names, ids)`` adds
    polylines to a model from ``new_model()`` exactly as the rhino3dm engine does.

    Raises
    ------
    LayoutError
        If rhino3dm's records of two sentinel polylines cannot be rebuilt exactly from the template.
    """
    model = new_model()
    points = [1.0e9 + np.arange(9, dtype=np.float64).reshape(3, 3) * 1.375,
              -2.0e7 + np.arange(15, dtype=np.float64).reshape(5, 3) * 0.625]
    names = ["qn\u00e9line0", "qn\u00e9line\U0001d538long1"]
    idents = [uuid.UUID(int=(0x51AD0DE5 << 96) + 0x4000_8000_0000_0000_0100 + k) for k in (0, 1)]
    build(model, points, names, [u.bytes_le for u in idents])
    file = encode(model)
    table = [c for c in _chunks(file, 32, len(file)) if c[0] == _OBJECT_TABLE]
    if len(table) != 1:
        raise LayoutError("no single object table")
    recs = [file[c0:c1] for tc, c0, _, c1 in _chunks(file, table[0][2], table[0][3]) if tc == _OBJECT_RECORD]
    if len(recs) != 2:
        raise LayoutError(f"{len(recs)} object records for two polylines")
    rec = recs[0]
    rtc, record_crc, parts = _record_parts(rec)
    if len(parts) != 4:
        raise LayoutError(f"{len(parts)} chunks in a polyline record")
    type_c, class_c, attr_c, end_c = parts
    inner = _chunks(rec, class_c[2], class_c[3])
    if len(inner) != 3 or class_c[0] & _CRC:
        raise LayoutError("a polyline's class chunk is not (id, data, end)")
    uuid_c, data_c, cend_c = inner
    if not data_c[0] & _CRC:
        raise LayoutError("the polyline data has no CRC")
    data = rec[data_c[2]:data_c[3] - 4]
    pts = points[0].astype("<f8").tobytes()
    at = data.find(pts)
    if at < 4 or _I32.unpack_from(data, at - 4)[0] != 3:
        raise LayoutError("the polyline's points are not stored once after their count")
    after = _I32.pack(3) + np.arange(3, dtype="<f8").tobytes()
    if not data[at + len(pts):].startswith(after):
        raise LayoutError("the polyline's parameters are not 0, 1, 2, ...")
    atc, attr_parts = _attributes(rec, attr_c, idents[0].bytes_le, names[0])
    template = PolylineRecords(rtc, record_crc, rec[type_c[1]:type_c[3]], class_c[0], rec[uuid_c[1]:uuid_c[3]],
                               data_c[0], data[:at - 4], data[at + len(pts) + len(after):],
                               rec[cend_c[1]:cend_c[3]], atc, attr_parts, rec[end_c[1]:end_c[3]])
    ids = np.frombuffer(b"".join(u.bytes_le for u in idents), dtype=np.uint8).reshape(2, 16)
    if template.records(points, names, ids) != b"".join(recs):
        raise LayoutError("the polyline records rebuilt from their parts differ from rhino3dm's")
    return template


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

        Every piece of every record is made column by column (one ``map`` or NumPy operation per
        piece over all panels), and the records are joined once.

        Parameters
        ----------
        flags : (m,) bool
            Which template (planar) each panel uses.
        corners : (m, 4, 3) float64
        names : m str
        columns : one sequence of m texts per key that is not fixed per template, in key order
        ids : (m, 16) uint8
            Object ids as openNURBS stores them (``uuid.UUID.bytes_le``).
        """
        m = len(flags)
        if m == 0:
            return b""
        t0, t1 = self.templates
        flags = np.asarray(flags, dtype=bool)
        idx = flags.astype(np.intp)

        def per_flag(a: Any, b: Any) -> list:
            """``a`` for a bilinear panel, ``b`` for a planar one."""
            both = np.empty(2, dtype=object)
            both[0], both[1] = a, b
            return both[idx].tolist()

        # the surfaces: the template's class chunk with each panel's corners and the data's CRC
        width = len(t0.class_chunk)
        classes = np.empty((m, width), dtype=np.uint8)
        classes[:] = np.frombuffer(t0.class_chunk, dtype=np.uint8)
        classes[flags] = np.frombuffer(t1.class_chunk, dtype=np.uint8)
        cv = np.ascontiguousarray(corners[:, list(_CV_CORNER)], dtype="<f8").reshape(m, 12)
        classes[:, t0.coord_at:t0.coord_at + 96] = cv.view(np.uint8).reshape(m, 96)
        crcs = np.fromiter(map(zlib.crc32, classes[:, t0.data_at:t0.crc_at]), dtype="<u4", count=m)
        classes[:, t0.crc_at:t0.crc_at + 4] = crcs.view(np.uint8).reshape(m, 4)
        blob = classes.tobytes()
        class_k = [blob[i:i + width] for i in range(0, m * width, width)]
        # the attributes: parts[0] + id + parts[1] + name + parts[2], then their CRC
        blob = np.ascontiguousarray(ids, dtype=np.uint8).tobytes()
        id_k = [blob[i:i + 16] for i in range(0, 16 * m, 16)]
        name_k = _wide(names)
        p0 = per_flag(t0.attr_parts[0], t1.attr_parts[0])
        p1 = per_flag(t0.attr_parts[1], t1.attr_parts[1])
        p2 = per_flag(t0.attr_parts[2], t1.attr_parts[2])
        crc = map(zlib.crc32, id_k, per_flag(zlib.crc32(t0.attr_parts[0]), zlib.crc32(t1.attr_parts[0])))
        crc = map(zlib.crc32, name_k, map(zlib.crc32, p1, crc))
        attr_crc = list(map(_U32.pack, map(zlib.crc32, p2, crc)))
        n_attr = (np.array(list(map(len, name_k)))
                  + np.array(per_flag(sum(map(len, t0.attr_parts)), sum(map(len, t1.attr_parts)))) + 20)
        attr_head = list(map(_HEAD.pack, repeat(t0.attr_tc), n_attr.tolist()))
        n_record = (len(t0.type_chunk) + width + len(t0.end_chunk) + 4) + 12 + n_attr
        pieces = [per_flag(t0.type_chunk, t1.type_chunk), class_k, attr_head, p0, id_k, p1, name_k, p2, attr_crc]
        if t0.strings is not None:
            user, n_user = self._user_data(idx, per_flag, columns)
            pieces += user
            n_record = n_record + 12 + n_user
        pieces += [per_flag(t0.end_chunk, t1.end_chunk), repeat(t0.record_crc, m)]
        record_head = map(_HEAD.pack, repeat(t0.record_tc), n_record.tolist())
        return b"".join(chain.from_iterable(zip(record_head, *pieces)))

    def _user_data(self, idx: np.ndarray, per_flag: Callable[[Any, Any], list],
                   columns: Sequence[Sequence[str]]) -> tuple[list[Any], np.ndarray]:
        """The columns of pieces of every panel's attribute user data, and its length (header excluded)."""
        s0, s1 = self.templates[0].strings, self.templates[1].strings
        if s0 is None or s1 is None or len(s0.lead) != len(s1.lead) or len(s0.tail) != len(s1.tail):
            raise LayoutError("the two templates' user data differ in form")
        m = len(idx)
        pieces: list[Any] = []
        n_inner = np.full(m, len(s0.inner_direct) + 4, dtype=np.int64)  # version, count, CRC; + the strings
        col = iter(columns)
        for i in range(len(self.keys)):
            f0, f1 = s0.fixed[i], s1.fixed[i]
            if f0 is not None and f1 is not None:
                pieces.append(per_flag(f0, f1))
                n_inner += np.array([len(f0), len(f1)])[idx]
                continue
            if f0 is not None or f1 is not None or s0.prefixes[i] != s1.prefixes[i]:
                raise LayoutError(f"the user string {self.keys[i]!r} is fixed in one template only")
            prefix = s0.prefixes[i]
            w = _wide(next(col))
            n = np.array(list(map(len, w))) + (len(prefix) + 4)
            crc = map(_U32.pack, map(zlib.crc32, w, repeat(zlib.crc32(prefix), m)))
            pieces += [map(_HEAD.pack, repeat(s0.string_tc), n.tolist()), repeat(prefix, m), w, crc]
            n_inner += n + 12
        n_outer = 12 + n_inner + 4
        n_class = len(s0.lead) + 12 + n_outer
        n_user = 12 + n_class + len(s0.tail)
        head = [map(_HEAD.pack, repeat(s0.ud_tc), n_user.tolist()),
                map(_HEAD.pack, repeat(s0.class_ud_tc), n_class.tolist()),
                per_flag(s0.lead, s1.lead),
                map(_HEAD.pack, repeat(s0.outer_tc), n_outer.tolist()),
                map(_HEAD.pack, repeat(s0.inner_tc), n_inner.tolist()),
                per_flag(s0.inner_direct, s1.inner_direct)]
        tail = [per_flag(s0.inner_crc, s1.inner_crc), per_flag(s0.outer_crc, s1.outer_crc),
                per_flag(s0.tail, s1.tail)]
        return head + pieces + tail, n_user


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
    t0, t1 = out
    same = ("record_tc", "record_crc", "coord_at", "data_at", "crc_at", "attr_tc")
    if (any(getattr(t0, a) != getattr(t1, a) for a in same)
            or [len(t.class_chunk) for t in out] != [len(t1.class_chunk)] * 2
            or len(t0.type_chunk) != len(t1.type_chunk) or len(t0.end_chunk) != len(t1.end_chunk)
            or (t0.strings is None) != (t1.strings is None)
            or (t0.strings is not None and t1.strings is not None
                and (t0.strings.string_tc, t0.strings.ud_tc, t0.strings.class_ud_tc, t0.strings.outer_tc,
                     t0.strings.inner_tc) != (t1.strings.string_tc, t1.strings.ud_tc, t1.strings.class_ud_tc,
                                               t1.strings.outer_tc, t1.strings.inner_tc))):
        raise LayoutError("the planar and the bilinear panel's records differ in form")
    records = PanelRecords((out[0], out[1]), tuple(keys))
    ids = np.frombuffer(b"".join(u.bytes_le for u in idents), dtype=np.uint8).reshape(2, 16)
    again = records.records(np.array([False, True]), corners, names, columns, ids)
    if again != b"".join(file[c0:c1] for _, c0, _, c1 in recs):
        raise LayoutError("the records rebuilt from their parts differ from rhino3dm's")
    return records


def write_records(f: BinaryIO, file: bytes, batches: Iterable[bytes], *, after: int) -> int:
    """Write ``file`` (a whole .3dm) to ``f`` with the records of ``batches`` inserted into its object
    table after its first ``after`` records; return the number of bytes written.

    The object table's length (patched once the records are written: ``f`` must be seekable) and the
    end-of-file chunk's file length are updated.

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
    start = f.tell()
    f.write(file[:d0])
    f.write(file[d0:at])
    n = 0
    for batch in batches:
        f.write(batch)
        n += len(batch)
    f.write(file[at:-8])
    f.write(struct.pack("<Q", len(file) + n))
    end = f.tell()
    f.seek(start + t0)
    f.write(_HEAD.pack(tc, t1 - d0 + n))
    f.seek(end)
    return end - start


def splice_records(file: bytes, records: bytes, *, after: int) -> bytes:
    """``file`` with ``records`` inserted, as :func:`write_records`, as bytes.

    Raises
    ------
    LayoutError
        As :func:`write_records`.
    """
    out = io.BytesIO()
    write_records(out, file, [records], after=after)
    return out.getvalue()


def random_ids(m: int) -> np.ndarray:
    """``(m, 16)`` uint8: random version-4 UUIDs as openNURBS stores them (``uuid.UUID.bytes_le``)."""
    import os

    raw = np.frombuffer(os.urandom(16 * m), dtype=np.uint8).reshape(m, 16).copy()
    # bytes_le: bytes 6-7 hold time_hi_and_version little-endian; byte 8 the variant
    raw[:, 7] = (raw[:, 7] & 0x0F) | 0x40
    raw[:, 8] = (raw[:, 8] & 0x3F) | 0x80
    return raw
