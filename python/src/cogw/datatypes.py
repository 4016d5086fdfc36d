# SPDX-License-Identifier: MIT
"""CiA 301 basic data types (§7.1.4, the numbers of §7.4.7.1 table 44): which
type a name means is libcogw's table (cogw_type_find / cogw_type_of: "u16",
"UNSIGNED16", ...); here a value's bytes (little-endian, as CiA 301 encodes
them) become the Python value and back."""
from __future__ import annotations

import struct
from dataclasses import dataclass
from typing import Union

from ._lib import lib

BOOLEAN = 0x01
INTEGER8 = 0x02
INTEGER16 = 0x03
INTEGER32 = 0x04
UNSIGNED8 = 0x05
UNSIGNED16 = 0x06
UNSIGNED32 = 0x07
REAL32 = 0x08
VISIBLE_STRING = 0x09
OCTET_STRING = 0x0A
UNICODE_STRING = 0x0B
TIME_OF_DAY = 0x0C
TIME_DIFFERENCE = 0x0D
DOMAIN = 0x0F
INTEGER24 = 0x10
REAL64 = 0x11
INTEGER40 = 0x12
INTEGER48 = 0x13
INTEGER56 = 0x14
INTEGER64 = 0x15
UNSIGNED24 = 0x16
UNSIGNED40 = 0x18
UNSIGNED48 = 0x19
UNSIGNED56 = 0x1A
UNSIGNED64 = 0x1B

_SIGNED = {INTEGER8, INTEGER16, INTEGER24, INTEGER32, INTEGER40, INTEGER48, INTEGER56, INTEGER64}
_UNSIGNED = {UNSIGNED8, UNSIGNED16, UNSIGNED24, UNSIGNED32, UNSIGNED40, UNSIGNED48, UNSIGNED56,
             UNSIGNED64}
INTEGER_TYPES = _SIGNED | _UNSIGNED
REAL_TYPES = {REAL32, REAL64}
NUMBER_TYPES = INTEGER_TYPES | REAL_TYPES | {BOOLEAN}

TypeLike = Union[int, str]
Value = Union[int, float, bool, str, bytes, "TimeOfDay"]


@dataclass(frozen=True)
class DataType:
    """A basic type as libcogw names it."""
    type: int        # the CiA 301 number (MBX_T_*)
    name: str        # short name: "u16"
    cia_name: str    # "UNSIGNED16"
    size: int        # bytes, 0 = variable (strings, DOMAIN)


@dataclass(frozen=True)
class TimeOfDay:
    """TIME_OF_DAY / TIME_DIFFERENCE (CiA 301 §7.1.6.5): ms after midnight, days since
    1984-01-01 (TIME_DIFFERENCE: a duration in the same two parts)."""
    days: int
    ms: int


_cache: dict[TypeLike, DataType] = {}


def resolve(t: TypeLike) -> DataType:
    """A type given by its number, its short name or its CiA name."""
    hit = _cache.get(t)
    if hit is not None:
        return hit
    p = lib.cogw_type_of(t) if isinstance(t, int) else lib.cogw_type_find(str(t).encode())
    if not p:
        raise ValueError(f"unknown CiA data type {t!r} (known: "
                         f"{lib.cogw_type_names().decode()})")
    c = p.contents
    dt = DataType(c.type, c.name.decode(), c.cia_name.decode(), c.size)
    _cache[t] = dt
    return dt


def decode(t: TypeLike, data: bytes) -> Value:
    """The value of these bytes as type t."""
    dt = resolve(t)
    if dt.size and len(data) != dt.size:
        raise ValueError(f"{dt.cia_name} takes {dt.size} bytes, got {len(data)}")
    code = dt.type
    if code in _UNSIGNED:
        return int.from_bytes(data, "little")
    if code in _SIGNED:
        return int.from_bytes(data, "little", signed=True)
    if code == BOOLEAN:
        return data[0] != 0
    if code == REAL32:
        return struct.unpack("<f", data)[0]
    if code == REAL64:
        return struct.unpack("<d", data)[0]
    if code == VISIBLE_STRING:
        return data.rstrip(b"\0").decode("latin-1")
    if code == UNICODE_STRING:
        return data.decode("utf-16-le").rstrip("\0")
    if code in (TIME_OF_DAY, TIME_DIFFERENCE):
        ms, days = struct.unpack("<IH", data)
        return TimeOfDay(days, ms & 0x0FFFFFFF)
    return bytes(data)  # OCTET_STRING, DOMAIN


def encode(t: TypeLike, value: Value) -> bytes:
    """The bytes of a value of type t; ValueError when it is not one."""
    dt = resolve(t)
    code = dt.type
    if code in INTEGER_TYPES:
        if isinstance(value, bool) or not isinstance(value, int):
            value = _as_int(value, dt)
        try:
            return int(value).to_bytes(dt.size, "little", signed=code in _SIGNED)
        except OverflowError:
            raise ValueError(f"{value} is out of the range of {dt.cia_name}") from None
    if code == BOOLEAN:
        return b"\x01" if value else b"\x00"
    if code == REAL32:
        return struct.pack("<f", float(value))  # type: ignore[arg-type]
    if code == REAL64:
        return struct.pack("<d", float(value))  # type: ignore[arg-type]
    if code == VISIBLE_STRING:
        return value.encode("latin-1") if isinstance(value, str) else bytes(value)  # type: ignore[arg-type]
    if code == UNICODE_STRING:
        return value.encode("utf-16-le") if isinstance(value, str) else bytes(value)  # type: ignore[arg-type]
    if code in (TIME_OF_DAY, TIME_DIFFERENCE):
        if not isinstance(value, TimeOfDay):
            raise ValueError(f"{dt.cia_name} takes a TimeOfDay(days, ms)")
        return struct.pack("<IH", value.ms & 0x0FFFFFFF, value.days)
    if isinstance(value, str):
        raise ValueError(f"{dt.cia_name} takes bytes")
    return bytes(value)  # type: ignore[arg-type]


def _as_int(value: object, dt: DataType) -> int:
    if isinstance(value, bool):
        return int(value)
    if isinstance(value, float) and value.is_integer():
        return int(value)
    if isinstance(value, str):
        return int(value, 0)
    raise ValueError(f"{value!r} is not a value of {dt.cia_name}")
