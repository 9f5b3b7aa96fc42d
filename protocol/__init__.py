"""Sans-I/O rosbridge v2 protocol: ops, encodings, message conversion and per-client sessions."""

from .codec import (Reassembler, decode_binary, decode_png, decode_text, dumps, encode_cbor, fragment_ops,
                    png_ops)
from .convert import default_message, from_args, from_cdr, from_json, to_cbor, to_cdr
from .errors import ConversionError, ProtocolError
from .msgdefs import ActionDef, Definitions, Field, MsgDef, SrvDef, UnknownType, normalize
from .ops import (OPS, ActionFeedback, ActionResult, Advertise, AdvertiseAction, AdvertiseService, Auth,
                  CallService, CancelActionGoal, Fragment, Op, Png, Publish, SendActionGoal, ServiceResponse,
                  SetLevel, Subscribe, Unadvertise, UnadvertiseAction, UnadvertiseService, Unsubscribe, parse_op)
from .session import Session

__all__ = [
    'OPS', 'ActionDef', 'ActionFeedback', 'ActionResult', 'Advertise', 'AdvertiseAction', 'AdvertiseService',
    'Auth', 'CallService', 'CancelActionGoal', 'ConversionError', 'Definitions', 'Field', 'Fragment', 'MsgDef',
    'Op', 'Png', 'ProtocolError', 'Publish', 'Reassembler', 'SendActionGoal', 'ServiceResponse', 'Session',
    'SetLevel', 'SrvDef', 'Subscribe', 'Unadvertise', 'UnadvertiseAction', 'UnadvertiseService', 'UnknownType',
    'Unsubscribe', 'decode_binary', 'decode_png', 'decode_text', 'default_message', 'dumps', 'encode_cbor',
    'fragment_ops', 'from_args', 'from_cdr', 'from_json', 'normalize', 'parse_op', 'png_ops', 'to_cbor',
    'to_cdr',
]
