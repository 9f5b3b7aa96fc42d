"""Outgoing frames: an op dict -> the websocket frames a client asked for."""

from __future__ import annotations

from typing import Any

from protocol import codec
from protocol.convert import to_cbor
from protocol.msgdefs import MsgDef

Frames = list[tuple[bytes, bool]]   # (payload, binary)


def text(op: dict) -> bytes:
    return codec.dumps(op)


def frames(op: dict, compression: str = 'none', fragment_size: int | None = None, *,
           msgdef: MsgDef | None = None, defs: Any = None, body: str = 'msg') -> Frames:
    """Encode ``op`` once for one (compression, fragment_size) pair.

    With ``cbor`` the message under ``op[body]`` becomes typed arrays (needs msgdef and defs).
    ``cbor-raw`` callers put the ``{secs, nsecs, bytes}`` body in place themselves.
    """
    if compression in ('cbor', 'cbor-raw'):
        if compression == 'cbor' and msgdef is not None and isinstance(op.get(body), dict):
            op = {**op, body: to_cbor(msgdef, op[body], defs)}
        return [(codec.encode_cbor(op), True)]
    frame = codec.dumps(op)
    if compression == 'png':
        # one png op: roslibjs decodes each png op on its own, so png is never split
        return [(codec.dumps(p), False) for p in codec.png_ops(frame, id=op.get('id'))]
    if fragment_size and len(frame) > fragment_size:
        return [(codec.dumps(f), False)
                for f in codec.fragment_ops(frame, fragment_size, op.get('id') or _fragment_id(op))]
    return [(frame, False)]


def _fragment_id(op: dict) -> str:
    return f"{op.get('op')}:{op.get('topic') or op.get('service') or op.get('action') or ''}"
