"""Whose fault an error is, decided in one place.

Answerable errors are the protocol's own exceptions (the client sent something wrong) and the ROS
side's refusals (``BackendError``, ``UnknownType``: the graph lacks what the client asked for);
the client gets their sentence. Anything else that escapes a handler (``ValueError``,
``TypeError``, ``KeyError``, ... from our code) is a bug of the gateway: it is logged with its
traceback and the client hears "internal error" and carries on.
"""

from __future__ import annotations

from protocol.errors import ProtocolError
from protocol.msgdefs import UnknownType

from .base import BackendError

ANSWERABLE = (ProtocolError, BackendError, UnknownType)


def answerable(exc: BaseException) -> bool:
    return isinstance(exc, ANSWERABLE)


def sentence(exc: BaseException) -> str:
    """What the client is told about exc."""
    if isinstance(exc, ProtocolError):
        return exc.message
    if isinstance(exc, ANSWERABLE):
        return str(exc) or type(exc).__name__
    return f'internal error ({type(exc).__name__}); the server carries on'
