"""Wire encodings: JSON and CBOR frames, png compression, outgoing fragments and their reassembly."""

from __future__ import annotations

import array
import binascii
import io
import json
import math
import sys

import cbor2
import orjson
from pybase64 import b64encode_as_string

from .errors import ProtocolError, json_type, shown
from .ops import Fragment, peek_id

_DUMPS_OPTIONS = orjson.OPT_SERIALIZE_NUMPY
_LITTLE = sys.byteorder == 'little'

# RFC 8746 little-endian typed-array tags by (kind, item size)
_TAGS = {('u', 1): 64, ('i', 1): 72, ('u', 2): 69, ('i', 2): 77, ('u', 4): 70, ('i', 4): 78,
         ('u', 8): 71, ('i', 8): 79, ('f', 4): 85, ('f', 8): 86}


def _kind(code: str) -> str:
    return 'f' if code in 'fd' else 'u' if code.isupper() else 'i'


_CODE_OF: dict[tuple[str, int], str] = {}  # (kind, size) -> array typecode
for _c in 'bBhHiIlLqQfd':
    _CODE_OF.setdefault((_kind(_c), array.array(_c).itemsize), _c)
_TAG_OF_CODE = {c: _TAGS[(_kind(c), array.array(c).itemsize)] for c in 'bBhHiIlLqQfd'}
TYPED_ARRAY_TAGS = {tag: _CODE_OF[key] for key, tag in _TAGS.items()}


# --- JSON ---------------------------------------------------------------------------------------

def _json_default(value):
    if isinstance(value, (bytes, bytearray, memoryview)):
        return b64encode_as_string(value)
    if isinstance(value, array.array):
        return value.tolist()
    tolist = getattr(value, 'tolist', None)  # numpy arrays and scalars orjson declined
    if tolist is not None:
        return tolist()
    raise TypeError(f'cannot encode {type(value).__name__} as JSON')


def dumps(obj) -> bytes:
    """JSON bytes; bytes become base64 strings and NaN/Inf become null (in lists too).

    The result is an exact-size copy: orjson's own bytes object keeps the buffer it grew while
    encoding, often many times the text (orjson 3.13: 4 KiB for a 41-byte status, 32 KiB for the
    4.1 KB reply of /rosapi/topics_and_raw_types), and a frame waiting in a client's queue would
    hold all of it (a client not reading 16 MiB of such replies cost the process 116 MiB). The
    copy costs under 0.5 µs for 4.6 KiB and 33 µs for 1.4 MB (once per message, not per client).
    """
    return bytes(memoryview(orjson.dumps(obj, default=_json_default, option=_DUMPS_OPTIONS)))


def _constant(token: str) -> float:
    return {'NaN': math.nan, 'Infinity': math.inf, '-Infinity': -math.inf}[token]


def decode_text(data: str | bytes) -> dict:
    """A JSON text frame as an op object; ProtocolError on bad JSON or a non-object.

    Errors are raised outside of except blocks: an exception's context would keep the parser's
    error, whose .doc is the whole frame, alive with it.
    """
    error = None
    try:
        obj = orjson.loads(data)
    except orjson.JSONDecodeError as e:
        error = str(e)
    if error is not None:
        obj = _lenient(data, error)
    if type(obj) is not dict:
        raise ProtocolError(f'expected a JSON object, got {json_type(obj)}')
    return obj


_INVALID = object()


def _lenient(data: str | bytes, error: str):
    """What orjson refused, parsed again as Python's json does: Python clients (json.dumps) send
    NaN/Infinity tokens. That parser also lets escaped lone surrogates ("\\ud800") through, which
    no encoder can write back and no ROS string may hold: those are refused here, at the edge."""
    try:
        obj = json.loads(data, parse_constant=_constant)
    except (ValueError, RecursionError):
        obj = _INVALID
    if obj is _INVALID:
        raise ProtocolError(f'invalid JSON: {error}')
    bad = _not_unicode(obj)
    if bad is not None:
        op = obj.get('op') if type(obj) is dict else None
        op = op if type(op) is str and _unicode(op) else None
        id = peek_id(obj) if bad != 'id' else None
        raise ProtocolError(f"field '{bad}' is not valid Unicode (it holds a lone surrogate); "
                            'strings must be UTF-8', op=op, id=id)
    return obj


def _unicode(text: str) -> bool:
    if text.isascii():
        return True
    try:
        text.encode('utf-8')
    except UnicodeEncodeError:
        return False
    return True


def _not_unicode(obj) -> str | None:
    """The path of the first string (value or key) in obj that is not valid Unicode, or None."""
    stack = [(obj, '')]
    while stack:
        value, path = stack.pop()
        t = type(value)
        if t is str:
            if not _unicode(value):
                return path or '(the message)'
        elif t is dict:
            for key, item in value.items():
                if not _unicode(key):
                    return f'{path}.{shown(key)}' if path else shown(key)
                stack.append((item, f'{path}.{key}' if path else key))
        elif t is list:
            stack.extend((item, f'{path}[{i}]') for i, item in enumerate(value))
    return None


# --- CBOR ---------------------------------------------------------------------------------------

def _typed_array(tag: int, payload: bytes) -> list:
    values = array.array(TYPED_ARRAY_TAGS[tag])
    if len(payload) % values.itemsize:
        raise ValueError(f'typed array tag {tag}: {len(payload)} bytes is not a whole number of items')
    values.frombytes(payload)
    if not _LITTLE:
        values.byteswap()
    return values.tolist()


def _tag_hook(*args):
    # cbor2 5 calls hook(decoder, tag), cbor2 6 calls hook(tag, immutable)
    tag = args[0] if isinstance(args[0], cbor2.CBORTag) else args[1]
    if tag.tag in TYPED_ARRAY_TAGS and isinstance(tag.value, bytes):
        return _typed_array(tag.tag, tag.value)
    return tag


def decode_binary(data: bytes) -> dict:
    """A CBOR binary frame as an op object (typed arrays become lists); ProtocolError otherwise."""
    error = None
    try:
        obj = cbor2.loads(data, tag_hook=_tag_hook, max_depth=100, strict_hashable_types=True)
    except Exception as e:   # whatever the decoder or its semantic tags raise: the bytes were bad
        error = f'invalid CBOR: {shown(str(e), 200)}'
    if error is not None:
        raise ProtocolError(error)
    if type(obj) is not dict:
        raise ProtocolError(f'expected a CBOR map, got {json_type(obj)}')
    return obj


def typed_array_tag(values: array.array) -> cbor2.CBORTag:
    """An array.array as its RFC 8746 little-endian typed-array tag."""
    if not _LITTLE:
        values = array.array(values.typecode, values)
        values.byteswap()
    return cbor2.CBORTag(_TAG_OF_CODE[values.typecode], values.tobytes())


def _cbor_default(encoder, value) -> None:
    if isinstance(value, memoryview):
        encoder.encode(bytes(value))
    elif hasattr(value, 'dtype') and hasattr(value, 'tolist'):  # numpy
        if value.ndim == 1 and (value.dtype.kind, value.dtype.itemsize) in _CODE_OF:
            encoder.encode(typed_array_tag(array.array(_numpy_code(value), value.tobytes())))
        else:
            encoder.encode(value.tolist())
    else:
        raise cbor2.CBOREncodeTypeError(f'cannot encode {type(value).__name__} as CBOR')


def _numpy_code(value) -> str:
    return _CODE_OF[(value.dtype.kind, value.dtype.itemsize)]


def encode_cbor(obj) -> bytes:
    """CBOR bytes; bytes stay byte strings, typed-array tags from convert.to_cbor pass through.

    numpy arrays become typed arrays too; array.array is written by cbor2 as a plain list (an
    encoder override for it would double the cost of every frame), so tag those with to_cbor.
    """
    return cbor2.dumps(obj, default=_cbor_default)


# --- png ----------------------------------------------------------------------------------------

def png_encode(frame: bytes | str) -> str:
    """rosbridge png compression: the bytes as pixels of a near-square RGB image padded with '\\n'."""
    from PIL import Image  # pillow is only needed by png subscribers

    if isinstance(frame, str):
        frame = frame.encode()
    length = len(frame)
    width = max(1, math.floor(math.sqrt(length / 3.0)))
    height = max(1, math.ceil(length / 3.0 / width))
    padded = bytes(frame) + b'\n' * (width * height * 3 - length)
    buf = io.BytesIO()
    Image.frombytes('RGB', (width, height), padded).save(buf, 'png')
    return binascii.b2a_base64(buf.getvalue(), newline=False).decode('ascii')


def png_ops(frame: bytes | str, max_size: int | None = None, id: str | None = None) -> list[dict]:
    """The png op(s) carrying frame; split into id/num/total pieces when longer than max_size.

    roslibjs decodes each png op on its own and ignores num/total, so for browser clients send
    one png op (no max_size).
    """
    data = png_encode(frame)
    if max_size is None or len(data) <= max_size:
        op = {'op': 'png', 'data': data}
        if id is not None:
            op['id'] = id
        return [op]
    if max_size < 1:
        raise ValueError('max_size must be positive')
    pieces = [data[i:i + max_size] for i in range(0, len(data), max_size)]
    return [{'op': 'png', 'id': id, 'data': p, 'num': n, 'total': len(pieces)} for n, p in enumerate(pieces)]


def decode_png(data_b64: str, max_bytes: int = 64 * 2**20) -> dict:
    """The op object inside a png op's data (the whole data, pieces already joined).

    The image is refused by its header, before decoding, when its pixels would exceed max_bytes
    (the gateway passes its frame limit): a small png can inflate to gigabytes.
    """
    from PIL import Image

    error = None
    try:
        raw = binascii.a2b_base64(data_b64, strict_mode=True)
        with Image.open(io.BytesIO(raw)) as img:
            size = img.width * img.height * 3
            if size > max_bytes:
                error = (f'png: image of {img.width}x{img.height} pixels is too large: {size} bytes, over the '
                         f'limit of {max_bytes} bytes')
            else:
                pixels = img.convert('RGB').tobytes()
    except Exception as e:   # base64, PIL and zlib errors alike: the data was bad
        error = f'png: cannot decode data: {shown(str(e), 200)}'
    if error is not None:
        raise ProtocolError(error, op='png')
    return decode_text(pixels.rstrip(b'\n'))


# --- fragments ----------------------------------------------------------------------------------

def fragment_ops(frame: bytes | str, fragment_size: int, id: str) -> list[dict]:
    """rosbridge fragment ops for a JSON frame longer than fragment_size; [] if it fits.

    id must be non-empty (roslibjs drops fragments without one); the pieces are split by
    characters, so each data string is at most fragment_size characters.
    """
    if fragment_size < 1:
        raise ValueError('fragment_size must be positive')
    if not id:
        raise ValueError('fragments need an id')
    if len(frame) <= fragment_size:
        return []
    text = frame if isinstance(frame, str) else bytes(frame).decode()  # split characters, not UTF-8 bytes
    total = -(-len(text) // fragment_size)
    return [{'op': 'fragment', 'id': id, 'data': text[i * fragment_size:(i + 1) * fragment_size],
             'num': i, 'total': total} for i in range(total)]


PIECE_COST = 128    # bytes a stored piece counts beyond its data: its envelope and the memory that holds it
MESSAGE_COST = 512  # bytes an incomplete message counts beyond its pieces (its entry and id)


class _Pending:
    __slots__ = ('last', 'pieces', 'size', 'total')

    def __init__(self, total: int, now: float) -> None:
        self.total = total
        self.pieces: dict[int, str] = {}
        self.size = 0
        self.last = now


class Reassembler:
    """Collects incoming fragment ops per id into the op they carry, with timeout and flood limits.

    Every bound holds before anything is stored: a piece counts its data plus ``PIECE_COST`` (an
    empty piece is not free: 200,000 of them held ~16 MB when they counted 0), a message its
    ``MESSAGE_COST``, ``total`` may not exceed ``max_bytes`` (each piece of a real message carries
    at least a character), and all pending messages of one client share ``max_bytes`` and
    ``max_messages``. Passing a bound raises a ProtocolError with ``close`` 1008: the client is
    told why and disconnected, as one that floods should be.
    """

    def __init__(self, timeout: float = 600.0, max_bytes: int = 64 * 2**20, max_messages: int = 64) -> None:
        self.timeout = timeout
        self.max_bytes = max_bytes
        self.max_messages = max_messages
        self._pending: dict[str, _Pending] = {}
        self._bytes = 0

    @property
    def pending_bytes(self) -> int:
        return self._bytes

    def __len__(self) -> int:
        return len(self._pending)

    def _drop(self, fid: str) -> None:
        entry = self._pending.pop(fid, None)
        if entry is not None:
            self._bytes -= entry.size

    def add(self, frag: Fragment, now: float) -> dict | None:
        """Store one fragment; the decoded op object once all of its id's pieces are in."""
        fid = frag.id

        def fail(why: str, close: int | None = None):
            self._drop(fid)
            if close is not None:
                why += f'; closing the connection ({close})'
            return ProtocolError(f'fragment: {why}', op='fragment', id=fid, close=close)

        entry = self._pending.get(fid)
        if entry is None:
            if len(self._pending) >= self.max_messages:
                raise fail(f'too many incomplete messages (limit {self.max_messages})', 1008)
            if frag.total > self.max_bytes:
                raise fail(f'total {frag.total} exceeds the message limit of {self.max_bytes} bytes', 1008)
            grow = MESSAGE_COST + len(fid)
            if self._bytes + grow > self.max_bytes:
                raise fail(f'incomplete messages exceed {self.max_bytes} bytes', 1008)
            entry = _Pending(frag.total, now)
            entry.size = grow
            self._bytes += grow
            self._pending[fid] = entry
        elif entry.total != frag.total:
            raise fail(f'total changed from {entry.total} to {frag.total}')
        if not 0 <= frag.num < frag.total:
            raise fail(f'num {frag.num} is outside 0..{frag.total - 1}')
        old = entry.pieces.get(frag.num)
        grow = len(frag.data) - (len(old) if old is not None else -PIECE_COST)
        if self._bytes + grow > self.max_bytes:
            raise fail(f'incomplete messages exceed {self.max_bytes} bytes', 1008)
        entry.pieces[frag.num] = frag.data
        entry.size += grow
        entry.last = now
        self._bytes += grow
        if len(entry.pieces) < entry.total:
            return None
        self._drop(fid)
        text = ''.join(entry.pieces[i] for i in range(entry.total))
        try:
            return decode_text(text)
        except ProtocolError as e:
            raise ProtocolError(f'fragment: reassembled message: {e.message}', op='fragment', id=fid) from None

    def expire(self, now: float) -> list[str]:
        """Drop messages whose last fragment is older than the timeout; their ids."""
        if not self._pending:
            return []
        old = [fid for fid, entry in self._pending.items() if now - entry.last > self.timeout]
        for fid in old:
            self._drop(fid)
        return old
