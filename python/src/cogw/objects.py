# SPDX-License-Identifier: MIT
"""python-canopen's access syntax over libcogw: node.sdo[0x1018][1].raw,
node.sdo["Identity object"]["Vendor-ID"].raw, .phys where the EDS gives a
Factor, .data for the bytes; the same for the daemon's own objects
(line.od[...]). An access (an SDO channel of a node, the daemon's OD) moves
the bytes; this module types them."""
from __future__ import annotations

from typing import Any, Optional, Protocol, Union

from . import datatypes
from .datatypes import TypeLike
from .eds import ObjectDictionary, Variable as OdVariable

Key = Union[int, str]


class Access(Protocol):
    label: str

    def upload(self, index: int, sub: int) -> bytes: ...

    def download(self, index: int, sub: int, data: bytes) -> None: ...


class _Typed:
    """What reading and writing one sub-object share, sync or async."""

    def __init__(self, access: Any, index: int, sub: int, od: Optional[OdVariable]):
        self._access = access
        self.index = index
        self.subindex = sub
        self.od = od

    @property
    def name(self) -> str:
        return self.od.name if self.od else f"{self.index:04X}sub{self.subindex}"

    @property
    def data_type(self) -> Optional[int]:
        return self.od.data_type if self.od else None

    @property
    def factor(self) -> float:
        return self.od.factor if self.od else 1.0

    def _where(self) -> str:
        return f"{self._access.label} {self.index:04X}:{self.subindex:02X}"

    def _decode(self, data: bytes, type_: Optional[TypeLike]) -> datatypes.Value:
        t = type_ if type_ is not None else self.data_type
        if t is None:
            # nothing says the type: an unsigned integer of the size that came, else the bytes
            return int.from_bytes(data, "little") if 1 <= len(data) <= 8 else bytes(data)
        return datatypes.decode(t, data)

    def _encode(self, value: datatypes.Value, type_: Optional[TypeLike]) -> bytes:
        t = type_ if type_ is not None else self.data_type
        if t is not None:
            return datatypes.encode(t, value)
        if isinstance(value, (bytes, bytearray)):
            return bytes(value)
        if isinstance(value, str):
            return value.encode("latin-1")
        raise TypeError(f"{self._where()}: no data type known for {value!r}: give one "
                        "(write(value, 'u16')) or the node's EDS/DCF")

    def _to_phys(self, raw: datatypes.Value) -> datatypes.Value:
        if self.factor != 1 and isinstance(raw, (int, float)) and not isinstance(raw, bool):
            return raw * self.factor
        return raw

    def _from_phys(self, value: datatypes.Value) -> datatypes.Value:
        if self.factor != 1 and isinstance(value, (int, float)):
            raw = value / self.factor
            if self.data_type in datatypes.INTEGER_TYPES:
                return int(round(raw))
            return raw
        return value


class SdoVariable(_Typed):
    """One sub-object, read and written at once (blocking calls)."""

    def read(self, type: Optional[TypeLike] = None) -> datatypes.Value:  # noqa: A002
        """The value, typed by `type` (a CiA name, short name or number), else by the EDS."""
        return self._decode(self._access.upload(self.index, self.subindex), type)

    def write(self, value: datatypes.Value, type: Optional[TypeLike] = None) -> None:  # noqa: A002
        self._access.download(self.index, self.subindex, self._encode(value, type))

    @property
    def raw(self) -> datatypes.Value:
        return self.read()

    @raw.setter
    def raw(self, value: datatypes.Value) -> None:
        self.write(value)

    @property
    def phys(self) -> datatypes.Value:
        """raw × the EDS's Factor (python-canopen's .phys)."""
        return self._to_phys(self.read())

    @phys.setter
    def phys(self, value: datatypes.Value) -> None:
        self.write(self._from_phys(value))

    @property
    def data(self) -> bytes:
        return self._access.upload(self.index, self.subindex)

    @data.setter
    def data(self, value: bytes) -> None:
        self._access.download(self.index, self.subindex, bytes(value))


class AsyncSdoVariable(_Typed):
    """One sub-object for asyncio: await var.read(), await var.write(v)."""

    async def read(self, type: Optional[TypeLike] = None) -> datatypes.Value:  # noqa: A002
        return self._decode(await self._access.upload(self.index, self.subindex), type)

    async def write(self, value: datatypes.Value, type: Optional[TypeLike] = None) -> None:  # noqa: A002
        await self._access.download(self.index, self.subindex, self._encode(value, type))

    async def read_phys(self) -> datatypes.Value:
        return self._to_phys(await self.read())

    async def write_phys(self, value: datatypes.Value) -> None:
        await self.write(self._from_phys(value))

    async def upload(self) -> bytes:
        return await self._access.upload(self.index, self.subindex)

    async def download(self, data: bytes) -> None:
        await self._access.download(self.index, self.subindex, bytes(data))


_FORWARDED = ("raw", "phys", "data")


class DictObject:
    """An object (index): [sub] or ["name"] gives its sub-objects; .raw/.phys/.data
    and read()/write() act on sub 0, so a VAR reads like python-canopen's."""

    def __init__(self, dictionary: "Dictionary", index: int):
        object.__setattr__(self, "_dict", dictionary)
        object.__setattr__(self, "index", index)
        od = dictionary.od.objects.get(index) if dictionary.od else None
        object.__setattr__(self, "od", od)
        object.__setattr__(self, "_sub0", self[0])

    @property
    def name(self) -> str:
        return self.od.name if self.od else f"{self.index:04X}"

    def __getitem__(self, key: Key) -> Any:
        if isinstance(key, str):
            if self.od is None:
                raise KeyError(f"{key!r}: no EDS/DCF gives the names of {self.index:04X}")
            sub = self.od.sub_by_name(key).sub
        else:
            sub = key
        var = self.od.subs.get(sub) if self.od else None
        return self._dict.var_cls(self._dict.access, self.index, sub, var)

    def __iter__(self):
        return iter(self.od.subs if self.od else ())

    def __getattr__(self, name: str) -> Any:
        return getattr(self._sub0, name)

    def __setattr__(self, name: str, value: Any) -> None:
        if name in _FORWARDED:
            setattr(self._sub0, name, value)
        else:
            object.__setattr__(self, name, value)


class Dictionary:
    """Objects of a node (through its SDO server) or of the daemon's own OD, by index
    or by the EDS's name."""

    def __init__(self, access: Any, od: Optional[ObjectDictionary], var_cls: type):
        self.access = access
        self.od = od
        self.var_cls = var_cls

    def __getitem__(self, key: Key) -> DictObject:
        if isinstance(key, str):
            if self.od is None:
                raise KeyError(f"{key!r}: names need the node's EDS/DCF")
            key = self.od[key].index
        return DictObject(self, key)

    def __contains__(self, key: Key) -> bool:
        return self.od is not None and key in self.od

    def __iter__(self):
        return iter(self.od if self.od else ())
