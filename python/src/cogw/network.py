# SPDX-License-Identifier: MIT
"""python-canopen's Network shape over the daemon, so that a script ports by
changing its constructor:

    network = canopen.Network()              network = cogw.Network("main")
    network.connect(channel="can0", ...)     network.connect(line=0)
    node = network.add_node(5, "dev.eds")    node = network.add_node(5, "dev.eds")
    node.sdo["Producer heartbeat time"].raw = 1000   (the same from here on)
"""
from __future__ import annotations

from typing import Any, Iterator, Optional

from .client import Connection, Node, ODLike, _od


class Network:
    """Nodes of one line of a cogwd instance, python-canopen style."""

    def __init__(self, instance: str = "main", line: int = 0):
        self.instance = instance
        self.line = line
        self.conn: Optional[Connection] = None
        self.nodes: dict[int, Node] = {}

    def connect(self, line: Optional[int] = None, **_ignored: Any) -> "Network":
        """Open the connection; python-canopen's bus arguments (channel,
        interface, bitrate) are the daemon's business and are ignored."""
        if line is not None:
            self.line = line
        if self.conn is None:
            self.conn = Connection(self.instance)
        return self

    def disconnect(self) -> None:
        if self.conn is not None:
            self.conn.close()
            self.conn = None

    def add_node(self, node: int, object_dictionary: ODLike = None,
                 upload_eds: bool = False) -> Node:
        if self.conn is None:
            self.connect()
        assert self.conn is not None
        n = self.conn.node(node, self.line, _od(object_dictionary))
        self.nodes[node] = n
        return n

    def __getitem__(self, node: int) -> Node:
        return self.nodes[node]

    def __contains__(self, node: int) -> bool:
        return node in self.nodes

    def __iter__(self) -> Iterator[int]:
        return iter(self.nodes)

    def __enter__(self) -> "Network":
        return self.connect()

    def __exit__(self, *exc: Any) -> None:
        self.disconnect()
