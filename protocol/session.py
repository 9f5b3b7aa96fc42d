"""Per-client protocol state: frames in, parsed ops and errors out; status ops filtered by level."""

from __future__ import annotations

import re

from .codec import Reassembler, decode_binary, decode_png, decode_text
from .errors import ProtocolError, detached
from .ops import Fragment, Op, Png, SetLevel, parse_op, peek_id

LEVEL_RANK = {'info': 0, 'warning': 1, 'warn': 1, 'error': 2, 'none': 3}


_HEAD = 512   # how much of an oversized text frame is searched for its op and id
_OP = re.compile(r'"op"\s*:\s*"([A-Za-z_]{1,40})"')
_ID = re.compile(r'"id"\s*:\s*"([^"\\]{0,200})"')


def _peek_op_and_id(data) -> tuple[str | None, str | None]:
    """Op and id of a frame too large to parse, when they come early in its JSON text."""
    if isinstance(data, (bytes, bytearray)):
        try:
            head = bytes(data[:_HEAD]).decode('utf-8', 'ignore')
        except Exception:
            return None, None
    else:
        head = data[:_HEAD]
    op, id = _OP.search(head), _ID.search(head)
    return (op.group(1) if op else None), (id.group(1) if id else None)


class Session:
    """One client's protocol state machine; no I/O: call receive_*() with frames, act on the results."""

    def __init__(self, *, fragment_timeout: float = 600.0, max_message_size: int | None = None,
                 max_fragment_bytes: int = 64 * 2**20, max_fragment_messages: int = 64) -> None:
        self.level = 'error'
        self.max_message_size = max_message_size
        limit = max_fragment_bytes if max_message_size is None else min(max_message_size, max_fragment_bytes)
        self.reassembler = Reassembler(fragment_timeout, limit, max_fragment_messages)
        # False while the client has still to authenticate: a fragment then is refused and ends the
        # connection, so a client that has not signed in can make the gateway hold nothing
        self.fragments_allowed = True

    def receive_text(self, data: str | bytes, now: float) -> list[Op | ProtocolError]:
        """Handle one text frame: the ops it completes and the errors it causes, in order."""
        return self._receive(data, now, decode_text)

    def receive_bytes(self, data: bytes, now: float) -> list[Op | ProtocolError]:
        """Handle one binary (CBOR) frame."""
        return self._receive(data, now, decode_binary)

    def _receive(self, data, now: float, decode) -> list[Op | ProtocolError]:
        out: list[Op | ProtocolError] = []
        self._expire(now, out)
        if self._oversize(data, out):
            return out
        try:
            obj = decode(data)
        except ProtocolError as e:
            out.append(detached(e))
            return out
        self._handle(obj, now, out)
        return out

    def expire(self, now: float) -> list[ProtocolError]:
        """Errors for incomplete fragmented messages that timed out (also checked on every frame)."""
        out: list = []
        self._expire(now, out)
        return out

    def status(self, level: str, msg: str, *, id: str | None = None,
               op: str | None = None) -> dict | None:
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
            op, id = _peek_op_and_id(data)
            out.append(ProtocolError(f'message of {size} bytes exceeds max_message_size {limit}', op=op, id=id))
            return True
        return False

    def _expire(self, now: float, out: list) -> None:
        for fid in self.reassembler.expire(now):
            out.append(ProtocolError(
                f'fragment: incomplete message dropped after {self.reassembler.timeout:g} s without fragments',
                op='fragment', id=fid))

    def _handle(self, obj: dict, now: float, out: list, outer: Fragment | Png | None = None) -> None:
        """Parse one op object; outer is the fragment/png op that carried it, if any."""
        try:
            op = parse_op(obj)
            if isinstance(op, Fragment):
                if outer is not None:
                    raise ProtocolError('fragment: a fragment may not carry another fragment',
                                        op='fragment', id=op.id)
                if not self.fragments_allowed:
                    raise ProtocolError('fragment: not accepted before authentication (send auth first); '
                                        'closing the connection (1008)', op='fragment', id=op.id, close=1008)
                full = self.reassembler.add(op, now)
                if full is not None:
                    self._handle(full, now, out, op)
                return
            if isinstance(op, Png):
                if outer is not None:
                    raise ProtocolError('png: a png op may not carry another png op', op='png', id=op.id)
                if op.total not in (None, 1):
                    raise ProtocolError('png: fragmented png input is not supported', op='png', id=op.id)
                limit = self.max_message_size or 64 * 2**20
                self._handle(decode_png(op.data, limit), now, out, op)
                return
            if isinstance(op, SetLevel):
                self.level = op.level
            out.append(op)
        except ProtocolError as e:
            if e.id is None:   # name the op the client can match: its own id, else the carrier's
                own = peek_id(obj) if e.op is None or e.op == obj.get('op') else None
                if own is not None:
                    e.id = own
                elif outer is not None:
                    e.op, e.id = outer.OP, outer.id
            out.append(detached(e))
