# SPDX-License-Identifier: MIT
"""cogw: Python clients of the cogw CANopen manager and gateway daemon, on
libcogw (docs/python.md).

    import cogw
    with cogw.connect("main") as gw:
        print(gw.node(5).sdo[0x1018][1].raw)

Blocking API: cogw.connect / cogw.Connection (client.py); asyncio:
cogw.aio.connect (aio.py); python-canopen's shape: cogw.Network (network.py)."""
from ._version import __version__
from .client import Connection, DeviceObject, Line, Node, Watch, connect
from .datatypes import TimeOfDay
from .eds import ObjectDictionary, load as import_od
from .errors import CogwError, SdoAbortedError, abort_name, status_name
from .events import DeviceValue, EmcyEvent, Event, ManagerEvent, NodeEvent, PdoEvent
from .network import Network
from .status import ProgramError, ProgramResult, WriteResult

__all__ = ["__version__", "Connection", "DeviceObject", "Line", "Node", "Watch", "connect",
           "TimeOfDay", "ObjectDictionary", "import_od", "CogwError", "SdoAbortedError",
           "abort_name", "status_name", "DeviceValue", "EmcyEvent", "Event", "ManagerEvent",
           "NodeEvent", "PdoEvent", "Network", "ProgramError", "ProgramResult", "WriteResult"]
