# SPDX-License-Identifier: MIT
"""What the package needs of a CiA 306 EDS or DCF: the objects' names, data
types, access, limits, defaults (a DCF's ParameterValue), and python-canopen's
Factor/Unit keys for .phys. The file is an INI file (configparser). The
daemon reads its configured nodes' files itself (docs/config.md); this is the
client's view, for names."""
from __future__ import annotations

import configparser
import re
from dataclasses import dataclass, field
from typing import Iterator, Optional, Union

VAR, ARRAY, RECORD, DOMAIN_OBJ = 0x7, 0x8, 0x9, 0x2

_SECTION = re.compile(r"^([0-9A-F]{4})(?:SUB([0-9A-F]{1,2}))?$", re.IGNORECASE)


@dataclass
class Variable:
    """One sub-object: a value with a type."""
    index: int
    sub: int
    name: str
    data_type: Optional[int] = None
    access: str = "rw"
    default: Optional[str] = None  # the file's text (DefaultValue)
    value: Optional[str] = None    # a DCF's ParameterValue
    low: Optional[str] = None
    high: Optional[str] = None
    factor: float = 1.0
    unit: str = ""
    pdo_mapping: bool = False


@dataclass
class Object:
    """An object of the dictionary: a VAR (its one Variable at sub 0), or an
    ARRAY / RECORD of them."""
    index: int
    name: str
    object_type: int = VAR
    subs: dict[int, Variable] = field(default_factory=dict)

    def __iter__(self) -> Iterator[int]:
        return iter(sorted(self.subs))

    def sub_by_name(self, name: str) -> Variable:
        for v in self.subs.values():
            if v.name == name:
                return v
        raise KeyError(f"{self.name}: no sub-object named {name!r}")


class ObjectDictionary:
    """The objects of one EDS/DCF, by index and by name."""

    def __init__(self) -> None:
        self.objects: dict[int, Object] = {}
        self._names: dict[str, int] = {}

    def add(self, obj: Object) -> None:
        self.objects[obj.index] = obj
        self._names[obj.name] = obj.index

    def __contains__(self, key: Union[int, str]) -> bool:
        return (key in self._names) if isinstance(key, str) else key in self.objects

    def __getitem__(self, key: Union[int, str]) -> Object:
        if isinstance(key, str):
            if key not in self._names:
                raise KeyError(f"no object named {key!r}")
            key = self._names[key]
        return self.objects[key]

    def __iter__(self) -> Iterator[int]:
        return iter(sorted(self.objects))

    def variable(self, index: int, sub: int) -> Optional[Variable]:
        obj = self.objects.get(index)
        return obj.subs.get(sub) if obj else None


def parse_int(text: str, node_id: Optional[int] = None) -> int:
    """A CiA 306 integer: decimal, 0x hex, leading-0 octal, $NODEID+... ."""
    t = text.strip().upper().replace(" ", "")
    if "$NODEID" in t:
        if node_id is None:
            raise ValueError(f"{text!r} needs the node-ID")
        return sum(parse_int(part) if part != "$NODEID" else node_id
                   for part in t.split("+") if part)
    if t.startswith("0X"):
        return int(t, 16)
    if len(t) > 1 and t.startswith("0") and t.isdigit():
        return int(t, 8)
    return int(t, 10)


def _get(sect: configparser.SectionProxy, key: str) -> Optional[str]:
    v = sect.get(key)
    return v.strip() if v is not None else None


def _num(sect: configparser.SectionProxy, key: str, fallback: int) -> int:
    v = _get(sect, key)
    if not v:
        return fallback
    try:
        return parse_int(v)
    except ValueError:
        return fallback


def _variable(sect: configparser.SectionProxy, index: int, sub: int) -> Variable:
    v = Variable(index, sub, _get(sect, "ParameterName") or f"{index:04X}sub{sub}")
    dt = _get(sect, "DataType")
    v.data_type = parse_int(dt) if dt else None
    v.access = (_get(sect, "AccessType") or "rw").lower()
    v.default = _get(sect, "DefaultValue")
    v.value = _get(sect, "ParameterValue")
    v.low = _get(sect, "LowLimit")
    v.high = _get(sect, "HighLimit")
    v.unit = _get(sect, "Unit") or ""
    v.pdo_mapping = _num(sect, "PDOMapping", 0) == 1
    factor = _get(sect, "Factor")
    if factor:
        try:
            v.factor = float(factor)
        except ValueError:
            pass
    return v


def _compact_subs(cp: configparser.ConfigParser, sect_name: str, obj: Object,
                  template: Variable, count: int) -> None:
    """CompactSubObj=n (CiA 306 §4.5.2.3): subs 1..n like the object, their
    names in [xxxxName] when given."""
    names = cp[f"{sect_name}Name"] if cp.has_section(f"{sect_name}Name") else None
    obj.subs[0] = Variable(obj.index, 0, "Number of entries", 0x05, "ro", str(count))
    for sub in range(1, count + 1):
        name = names.get(str(sub)) if names is not None else None
        obj.subs[sub] = Variable(obj.index, sub, name or f"{obj.name}{sub}", template.data_type,
                                 template.access, template.default, None, template.low,
                                 template.high, template.factor, template.unit,
                                 template.pdo_mapping)


def load(path: str) -> ObjectDictionary:
    """Read an EDS or DCF file."""
    cp = configparser.ConfigParser(interpolation=None, strict=False,
                                   inline_comment_prefixes=(";",))
    with open(path, encoding="latin-1") as f:
        cp.read_file(f)
    od = ObjectDictionary()
    subs: list[tuple[int, int, configparser.SectionProxy]] = []
    for name in cp.sections():
        m = _SECTION.match(name)
        if not m:
            continue
        index = int(m.group(1), 16)
        sect = cp[name]
        if m.group(2) is not None:
            subs.append((index, int(m.group(2), 16), sect))
            continue
        obj = Object(index, _get(sect, "ParameterName") or f"{index:04X}",
                     _num(sect, "ObjectType", VAR))
        if obj.object_type in (VAR, DOMAIN_OBJ):
            obj.subs[0] = _variable(sect, index, 0)
        compact = _num(sect, "CompactSubObj", 0)
        if compact and obj.object_type in (ARRAY, RECORD):
            _compact_subs(cp, name, obj, _variable(sect, index, 1), compact)
        od.add(obj)
    for index, sub, sect in subs:
        obj = od.objects.get(index)
        if obj is not None:
            obj.subs[sub] = _variable(sect, index, sub)
    return od
