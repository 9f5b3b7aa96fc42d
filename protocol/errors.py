"""The protocol's exception family: every error a client can cause, with op, id and level."""

from __future__ import annotations


class ProtocolError(Exception):
    """The client sent something wrong; it becomes a ``status`` op naming op and id. ``close``
    (a websocket close code, 1008) when the client passed a bound and the connection ends after
    the status."""

    def __init__(self, message: str, *, op: str | None = None, id: str | None = None,
                 level: str = 'error', close: int | None = None) -> None:
        super().__init__(message)
        self.message = message
        self.op = op
        self.id = id
        self.level = level
        self.close = close

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


def shown(value: object, limit: int = 80) -> str:
    """A value for an error sentence: short, and safe for any value a client can send (a
    5,000-digit integer cannot even be printed: Python refuses to convert it to text)."""
    if type(value) is int:
        bits = value.bit_length()
        return str(value) if bits <= 128 else f'{"a negative" if value < 0 else "an"} integer of {bits} bits'
    try:
        text = repr(value)
    except Exception:   # a value whose repr fails is still an answerable mistake
        return json_type(value)
    return text if len(text) <= limit else text[:limit - 3] + '...'


def detached(error: ProtocolError) -> ProtocolError:
    """The error without its traceback and context, which hold the frames of the parser and with
    them the whole client frame (a JSONDecodeError's .doc), often in a reference cycle."""
    error.__traceback__ = None
    error.__context__ = None
    error.__cause__ = None
    return error
