"""Fuzzed rosbridge frames from a random.Random: the hypothesis suite and the 100k-op tool share it.

Each frame is one websocket message (text or binary). Frames made with a definite defect carry a
fresh id in ``bad_id``: the gateway must answer each of them with an error status with that id.
The others (mutations of valid ops, random JSON, random bytes) may do anything the protocol
allows; the checks on them are that the gateway lives and keeps answering. A few text frames are
not valid UTF-8 (``text`` bytes): they fail the connection, so they carry the close code the
gateway must answer with (``close``: 1007, after an error status).
"""

from __future__ import annotations

import copy
import itertools
import json
import random
from dataclasses import dataclass

import cbor2

from protocol.codec import png_encode

FIB = 'example_interfaces/action/Fibonacci'
TEMPLATES = [
    {'op': 'subscribe', 'topic': '/fuzz/a', 'type': 'std_msgs/msg/String', 'throttle_rate': 0, 'queue_length': 1},
    {'op': 'subscribe', 'topic': '/client_count', 'compression': 'cbor'},
    {'op': 'unsubscribe', 'topic': '/fuzz/a'},
    {'op': 'advertise', 'topic': '/fuzz/a', 'type': 'std_msgs/msg/String', 'latch': True},
    {'op': 'publish', 'topic': '/fuzz/a', 'msg': {'data': 'x'}},
    {'op': 'publish', 'topic': '/fuzz/twist', 'type': 'geometry_msgs/msg/Twist',
     'msg': {'linear': {'x': 0.1, 'y': 0, 'z': 0}, 'angular': {'z': 0.2}}},
    {'op': 'unadvertise', 'topic': '/fuzz/a'},
    {'op': 'call_service', 'service': '/add_two_ints', 'args': {'a': 1, 'b': 2}},
    {'op': 'call_service', 'service': '/rosapi/topics'},
    {'op': 'call_service', 'service': '/rosapi/get_param', 'args': {'name': '/add_two_ints_server:x'}},
    {'op': 'advertise_service', 'service': '/fuzz/srv', 'type': 'std_srvs/srv/Trigger'},
    {'op': 'unadvertise_service', 'service': '/fuzz/srv'},
    {'op': 'service_response', 'service': '/fuzz/srv', 'id': 'r', 'values': {'success': True}, 'result': True},
    {'op': 'send_action_goal', 'action': '/fibonacci', 'action_type': FIB, 'args': {'order': 2}, 'feedback': True},
    {'op': 'cancel_action_goal', 'action': '/fibonacci', 'id': 'g'},
    {'op': 'advertise_action', 'action': '/fuzz/act', 'type': FIB},
    {'op': 'unadvertise_action', 'action': '/fuzz/act'},
    {'op': 'action_feedback', 'action': '/fuzz/act', 'id': 'g', 'values': {'sequence': [1]}},
    {'op': 'action_result', 'action': '/fuzz/act', 'id': 'g', 'values': {'sequence': [1]}, 'status': 4,
     'result': True},
    {'op': 'set_level', 'level': 'error'},
    {'op': 'auth', 'token': 'not-a-token'},
    {'op': 'fragment', 'id': 'f', 'data': '{"op": "set_le', 'num': 0, 'total': 2},
    {'op': 'fragment', 'id': 'f', 'data': 'vel", "level": "error"}', 'num': 1, 'total': 2},
    {'op': 'png', 'data': 'iVBORw0KGgo='},
    {'op': 'png', 'data': png_encode('{"op": "unsubscribe", "topic": "/fuzz/a"}')},
    {'op': 'subscribe', 'topic': '/turtle1/pose', 'throttle_rate': 100, 'compression': 'png'},
    {'op': 'subscribe', 'topic': '/fuzz/a', 'type': 'std_msgs/msg/String', 'fragment_size': 5},
    {'op': 'subscribe', 'topic': '/fuzz/a', 'type': 'std_msgs/msg/String', 'compression': 'cbor-raw'},
    {'op': 'publish', 'topic': '/turtle1/cmd_vel', 'msg': {'linear': {'x': 0.1}, 'angular': {'z': 0.1}}},
    {'op': 'call_service', 'service': '/rosapi/message_details', 'args': {'type': 'geometry_msgs/msg/Twist'}},
    {'op': 'call_service', 'service': '/rosapi/set_param', 'args': {'name': '/turtlesim:background_r', 'value': '9'}},
    {'op': 'call_service', 'service': '/turtle1/teleport_absolute', 'args': {'x': 1.0, 'y': 2.0, 'theta': 0.5},
     'fragment_size': 8, 'compression': 'cbor'},
]
# per op: string fields and integer fields that parse_op checks (a wrong value there is a defect)
STRINGS = ('topic', 'service', 'action', 'type', 'action_type')
INTEGERS = ('throttle_rate', 'queue_length', 'num', 'total')
_bad_ids = itertools.count(1)


INVALID_UTF8 = [b'\xff', b'\xc0\xaf', b'\x80', b'\xe2\x82', b'\xed\xa0\x80', b'\xf4\x90\x80\x80']


@dataclass
class Frame:
    payload: str | bytes
    bad_id: str | None = None    # set when the gateway must answer with an error status with this id
    text: bool | None = None     # True: payload (bytes) goes out as a text frame
    close: int | None = None     # the close code this frame must get (after a status)


def json_value(rng: random.Random, depth: int = 0):
    kind = rng.randrange(10 if depth < 3 else 7)
    if kind == 0:
        return None
    if kind == 1:
        return rng.random() < 0.5
    if kind == 2:
        return rng.choice([0, -1, 1, 2**31, 2**63, -(2**64), rng.randrange(-10**6, 10**6)])
    if kind == 3:
        return rng.choice([0.5, -1e308, 1e308, float('nan'), float('inf'), rng.uniform(-1e3, 1e3)])
    if kind in (4, 5, 6):
        return text(rng)
    if kind in (7, 8):
        return [json_value(rng, depth + 1) for _ in range(rng.randrange(4))]
    return {text(rng, 8): json_value(rng, depth + 1) for _ in range(rng.randrange(4))}


def text(rng: random.Random, size: int = 24) -> str:
    pool = rng.choice(['abc/_', 'abcdefghij/_:.-0123456789', '\x00\t\n"\\{}[]', 'äöü€😀中文', '/fuzz/'])
    return ''.join(rng.choice(pool) for _ in range(rng.randrange(size)))


def _mutate(rng: random.Random, op: dict) -> dict:
    op = copy.deepcopy(op)
    for _ in range(rng.randrange(1, 4)):
        keys = list(op)
        action = rng.randrange(4)
        if action == 0 and keys:
            del op[rng.choice(keys)]
        elif action == 1 and keys:
            op[rng.choice(keys)] = json_value(rng)
        elif action == 2:
            op[text(rng, 10)] = json_value(rng)
        else:
            op['id'] = json_value(rng)
    return op


def _defect(rng: random.Random, cbor: bool) -> tuple[dict, str]:
    """A template made wrong in one way the protocol layer must refuse; and its fresh id."""
    bad_id = f'bad-{next(_bad_ids)}'
    op = copy.deepcopy(rng.choice([t for t in TEMPLATES if t['op'] != 'fragment']))
    op['id'] = bad_id
    strings = [k for k in STRINGS if k in op]
    integers = [k for k in INTEGERS if k in op]
    choice = rng.randrange(6)
    if choice == 0 or (choice == 1 and not strings) or (choice == 2 and not integers):
        op['op'] = 'no_such_op_' + text(rng, 6)
    elif choice == 1:
        op[rng.choice(strings)] = rng.choice([1, [], {}, True, 2.5])
    elif choice == 2:
        op[rng.choice(integers)] = rng.choice(
            [-(10**5000), 10**400] if cbor else [-1, 'many', 1.5, 2**70])
    elif choice == 3 and not cbor:
        key = rng.choice(strings or ['op'])
        op[key] = str(op.get(key, 'x')) + '\ud800'   # a lone surrogate: JSON escapes it, CBOR cannot
    elif choice == 4 and op['op'] in ('publish', 'subscribe', 'advertise', 'call_service'):
        del op['topic' if 'topic' in op else 'service']
    else:
        op['op'] = rng.choice([None, 7, ['subscribe'], {'op': 'x'}]) if rng.random() < 0.3 else 'nope'
    return op, bad_id


def encode(rng: random.Random, obj, cbor: bool) -> str | bytes:
    if cbor:
        return cbor2.dumps(obj)
    if rng.random() < 0.5:
        return json.dumps(obj)   # lone surrogates go out as \\udXXX escapes
    raw = json.dumps(obj, ensure_ascii=False)
    try:
        raw.encode('utf-8')
    except UnicodeEncodeError:   # a websocket text frame cannot carry it unescaped
        return json.dumps(obj)
    return raw


def frame(rng: random.Random) -> Frame:
    cbor = rng.random() < 0.35
    kind = rng.randrange(10)
    if kind < 3:
        op, bad_id = _defect(rng, cbor)
        return Frame(encode(rng, op, cbor), bad_id)
    if kind < 8:
        return Frame(encode(rng, _mutate(rng, rng.choice(TEMPLATES)), cbor))
    if kind == 8:
        return Frame(encode(rng, json_value(rng), cbor))
    if rng.random() > 0.95:   # (not < 0.05: hypothesis's randoms favour small values)
        return not_utf8(rng)
    if rng.random() < 0.5:
        return Frame(bytes(rng.randrange(256) for _ in range(rng.randrange(64))))
    return Frame(text(rng, 64))


def not_utf8(rng: random.Random) -> Frame:
    """A text frame with a byte sequence UTF-8 does not allow, somewhere in an otherwise valid op."""
    raw = json.dumps(_mutate(rng, rng.choice(TEMPLATES)), ensure_ascii=False).encode('utf-8', 'surrogatepass')
    at = rng.randrange(len(raw) + 1)
    return Frame(raw[:at] + rng.choice(INVALID_UTF8) + raw[at:], text=True, close=1007)


def safe_for_cbor(obj) -> bool:
    try:
        cbor2.dumps(obj)
    except Exception:
        return False
    return True
