"""Per-client protocol state: frames in, parsed ops and errors out; status ops filtered by level."""

from __future__ import annotations

from .codec import Reassembler, decode_binary, decode_png, decode_text
from .errors import ProtocolError
from .ops import Fragment, Op, Png, SetLevel, parse_op, peek_id

LEVEL_RANK = {'info': 0, 'warning': 1, 'warn': 1, 'error': 2, 'none': 3}


class Session:
    """One client's protocol state machine; no I/O: call receive_*() with frames, act on the results."""

    def __init__(self, *, fragment_timeout: float = 600.0, max_message_size: int | None = None,
                 max_fragment_bytes: int = 64 * 2**20, max_fragment_messages: int = 64) -> None:
        self.level = 'error'
        self.max_message_size = max_message_size
        limit = max_fragment_bytes if max_message_size is None else min(max_message_size, max_fragment_bytes)
        self.reassembler = Reassembler(fragment_timeout, limit, max_fragment_messages)

    def receive_text(self, data: str | bytes, now: float) -> list[Op | ProtocolError]:
        """Handle one text frame: the ops it completes and the errors it causes, in order."""
        out: list[Op | ProtocolError] = []
        self._expire(now, out)
        if self._oversize(data, out):
            return out
        try:
            obj = decode_text(data)
        except ProtocolError as e:
            out.append(e)
            return out
        self._handle(obj, now, out, nested=False)
        return out

    def receive_bytes(self, data: bytes, now: float) -> list[Op | ProtocolError]:
        """Handle one binary (CBOR) frame."""
        out: list[Op | ProtocolError] = []
        self._expire(now, out)
        if self._oversize(data, out):
            return out
        try:
            obj = decode_binary(data)
        except ProtocolError as e:
            out.append(e)
            return out
        self._handle(obj, now, out, nested=False)
        return out

    def expire(self, now: float) -> list[ProtocolError]:
        """Errors for incomplete fragmented messages that timed out (also checked on every frame)."""
        out: list = []
        self._expire(now, out)
        return out

    def status(self, level: str, msg: str, *, id: str | None = None, op: str | None = None) -> dict | None:  # noqa: A002
        """A status op for the client, or None when its set_level filters this level out."""
        if level == 'warn':
            level = 'warning'
        if LEVEL_RANK.get(level, 2) < LEVEL_RANK[self.level] or self.level == 'none':
            return None
        if op and not msg.startswith(f'{op}:') and not msg.startswith(f'{op} '):
            msg = f'{op}: {msg}'
        out = {'op': 'status', 'level': level, 'msg': msg}
        if id is not None:
            out['id'] = id
        return out

    def error_status(self, error: ProtocolError) -> dict | None:
        """The status op for a ProtocolError (None when filtered)."""
        return self.status(error.level, error.message, id=error.id, op=error.op)

    # --- internals ------------------------------------------------------------------------------

    def _oversize(self, data, out: list) -> bool:
        limit = self.max_message_size
        if limit is None:
            return False
        size = len(data)
        if isinstance(data, str) and size <= limit < size * 4:
            size = len(data.encode('utf-8', 'surrogatepass'))
        if size > limit:
            out.append(ProtocolError(f'message of {size} bytes exceeds max_message_size {limit}'))
            return True
        return False

    def _expire(self, now: float, out: list) -> None:
        for fid in self.reassembler.expire(now):
            out.append(ProtocolError(
                f'fragment: incomplete message dropped after {self.reassembler.timeout:g} s without fragments',
                op='fragment', id=fid))

    def _handle(self, obj: dict, now: float, out: list, nested: bool) -> None:
        try:
            op = parse_op(obj)
            if isinstance(op, Fragment):
                if nested:
                    raise ProtocolError('fragment: a fragment may not carry another fragment',
                                        op='fragment', id=op.id)
                full = self.reassembler.add(op, now)
                if full is not None:
                    self._handle(full, now, out, nested=True)
                return
            if isinstance(op, Png):
                if nested:
                    raise ProtocolError('png: a png op may not carry another png op', op='png', id=op.id)
                if op.total not in (None, 1):
                    raise ProtocolError('png: fragmented png input is not supported', op='png', id=op.id)
                self._handle(decode_png(op.data), now, out, nested=True)
                return
            if isinstance(op, SetLevel):
                self.level = op.level
            out.append(op)
        except ProtocolError as e:
            if e.id is None and e.op is None:
                e.id = peek_id(obj)
            out.append(e)
