"""Fixtures for the protocol unit tests: message definitions, including a test type with every array kind."""

from __future__ import annotations

import pytest

from protocol.msgdefs import Definitions, definition_text

ARRAYS_TYPE = 'rosgate_test/msg/Arrays'
ARRAYS_TEXT = """
bool[] bools
byte[] octets
char[] chars
float32[] f32
float64[] f64
int8[] i8
uint8[] u8
int16[] i16
uint16[] u16
int32[] i32
uint32[] u32
int64[] i64
uint64[] u64
string[] strings
float64[3] fixed
uint8[4] fixed_bytes
string<=5 short
int32[<=3] few
string<=2[] tags
geometry_msgs/Point[2] points
builtin_interfaces/Duration[] durations
byte b
char c
int8 small
uint64 big
float32 single
"""


@pytest.fixture(scope='session')
def defs() -> Definitions:
    """Jazzy definitions plus rosgate_test/msg/Arrays (also registered for CDR)."""
    from rosbags.typesys import get_types_from_msg

    defs = Definitions.jazzy()
    msg = defs.add_msg(ARRAYS_TYPE, ARRAYS_TEXT)
    if ARRAYS_TYPE not in defs.typestore.types:
        defs.typestore.register(get_types_from_msg(definition_text(msg), ARRAYS_TYPE))
    return defs


@pytest.fixture(scope='session')
def arrays(defs):
    return defs.msg(ARRAYS_TYPE)
