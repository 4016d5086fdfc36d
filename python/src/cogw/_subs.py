# SPDX-License-Identifier: MIT
"""Subscriptions counted per line and class: several streams of one connection
may want a class; the daemon hears of the first to come and the last to go."""
from __future__ import annotations


class SubscriptionCount:
    def __init__(self) -> None:
        self._users: dict[tuple[int, int], int] = {}

    def add(self, line: int, mask: int) -> int:
        """Count a user of each class of mask: the classes nobody had."""
        new = 0
        for bit in (1 << i for i in range(32)):
            if mask & bit:
                n = self._users.get((line, bit), 0)
                self._users[(line, bit)] = n + 1
                new |= bit if n == 0 else 0
        return new

    def remove(self, line: int, mask: int) -> int:
        """One user less of each class of mask: the classes nobody has now."""
        gone = 0
        for bit in (1 << i for i in range(32)):
            if mask & bit and self._users.get((line, bit), 0) > 0:
                self._users[(line, bit)] -= 1
                gone |= bit if self._users[(line, bit)] == 0 else 0
        return gone
