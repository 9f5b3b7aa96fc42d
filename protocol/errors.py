"""The protocol's exception family: every error a client can cause, with op, id and level."""

from __future__ import annotations


class ProtocolError(Exception):
    """The client sent something wrong; it becomes a ``status`` op naming op and id."""

    def __init__(self, message: str, *, op: str | None = None, id: str | None = None,
                 level: str = 'error') -> None:
        super().__init__(message)
        self.message = message
        self.op = op
        self.id = id
        self.level = level

    def __str__(self) -> str:
        return self.message

    def __repr__(self) -> str:
        return f'{type(self).__name__}({self.message!r}, op={self.op!r}, id={self.id!r}, level={self.level!r})'

    def __eq__(self, other: object) -> bool:
        return (type(other) is type(self) and (self.message, self.op, self.id, self.level)
                == (other.message, other.op, other.id, other.level))

    __hash__ = Exception.__hash__


class ConversionError(ProtocolError):
    """A message value does not fit its type; ``path`` names the field ('linear.x', 'poses[2].x')."""

    def __init__(self, message: str, *, path: str = '', op: str | None = None, id: str | None = None,
                 level: str = 'error') -> None:
        super().__init__(message, op=op, id=id, level=level)
        self.path = path


def json_type(value: object) -> str:
    """The JSON word for a Python value's type, for error sentences."""
    if value is None:
        return 'null'
    if isinstance(value, bool):
        return 'boolean'
    if isinstance(value, (int, float)):
        return 'number'
    if isinstance(value, str):
        return 'string'
    if isinstance(value, dict):
        return 'object'
    if isinstance(value, (list, tuple)):
        return 'array'
    if isinstance(value, (bytes, bytearray, memoryview)):
        return 'bytes'
    return type(value).__name__
