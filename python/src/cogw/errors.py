# SPDX-License-Identifier: MIT
"""Errors as exceptions: the mailbox status (libcogw's one error space,
named by cogw_strerror) and, for an SDO or object dictionary refusal, the
CiA 301 abort code named by libcogw's own table (sdo_abort_to_string)."""
from __future__ import annotations

from ._lib import E_ABORT, lib


def status_name(status: int) -> str:
    """libcogw's name of a status (0 or a negative COGW_E_* code)."""
    return lib.cogw_strerror(status).decode()


def abort_name(code: int) -> str:
    """The CiA 301 name of an SDO abort code (0x06020000 -> "object does not exist")."""
    return lib.sdo_abort_to_string(code & 0xFFFFFFFF).decode()


class CogwError(Exception):
    """A call refused by the daemon or failed in libcogw.

    status: the COGW_E_* / mailbox status (negative), status_name its name."""

    def __init__(self, status: int, what: str = ""):
        self.status = status
        self.status_name = status_name(status)
        self.what = what
        super().__init__(f"{what}: {self.status_name} ({status})" if what else
                         f"{self.status_name} ({status})")


class SdoAbortedError(CogwError):
    """An SDO transfer or a local object access ended by an abort
    (status COGW_E_ABORT). code / abort: the CiA 301 abort code;
    abort_name its name. (python-canopen's SdoAbortedError has .code too.)"""

    def __init__(self, code: int, what: str = ""):
        self.code = code
        self.abort = code
        self.abort_name = abort_name(code)
        super().__init__(E_ABORT, what)
        self.args = (f"{what + ': ' if what else ''}SDO abort 0x{code:08X} ({self.abort_name})",)

    def __str__(self) -> str:
        return self.args[0]


def check(rc: int, what: str = "", abort: int = 0) -> int:
    """rc if it is not an error; else the exception that says why."""
    if rc >= 0:
        return rc
    if rc == E_ABORT:
        raise SdoAbortedError(abort, what)
    raise CogwError(rc, what)
