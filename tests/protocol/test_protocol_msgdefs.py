"""Message texts go through one parser, rosbags': a '#' inside a string constant is text, not a
comment, and the defaults a definition gives its fields are kept (the hand-made parser cut
``string C="x#y"`` to ``x`` and dropped every default)."""

from __future__ import annotations

import pytest
from rosbags.typesys import get_types_from_msg

from protocol.convert import default_message, from_cdr, from_json, to_cdr
from protocol.msgdefs import Definitions, Field, definition_text, parse_msg, typedef

TEXT = '''
# a comment line
string C="x#y"          # the constant holds a '#'
string D='a # b'
int32 HEX=0x10
float64 F=1
bool YES=true
float64 x 1.5           # a default
string s "hi # there"
int32[] seq [1, 2]
float32[2] pair [0.5, -1.0]
uint8[] raw [1, 2, 255]
bool flag true
string plain
geometry_msgs/Point p
'''


@pytest.fixture(scope='module')
def defaults():
    defs = Definitions.jazzy()
    msg = defs.add_msg('rosgate_parser_test/msg/Defaults', TEXT)
    defs.typestore.register(get_types_from_msg(definition_text(msg), msg.type))
    return defs, msg


def test_a_hash_inside_a_string_constant_is_kept():
    msg = parse_msg('pkg/msg/C', 'string C="x#y"\n')
    assert msg.constants == (('C', 'string', 'x#y'),)


def test_constants_take_their_type():
    consts = {name: (type_, value) for name, type_, value in parse_msg('pkg/msg/T', TEXT).constants}
    assert consts == {'C': ('string', 'x#y'), 'D': ('string', 'a # b'), 'HEX': ('int32', 16),
                      'F': ('float64', 1.0), 'YES': ('bool', True)}
    assert type(consts['F'][1]) is float


def test_field_defaults_are_kept():
    fields = {f.name: f for f in parse_msg('pkg/msg/T', TEXT).fields}
    assert {name: f.default for name, f in fields.items()} == {
        'x': 1.5, 's': 'hi # there', 'seq': (1, 2), 'pair': (0.5, -1.0), 'raw': (1, 2, 255),
        'flag': True, 'plain': None, 'p': None}
    assert fields['pair'] == Field('pair', 'float32', 2, 0, 0, (0.5, -1.0))
    assert fields['p'].type == 'geometry_msgs/msg/Point'


def test_a_message_without_its_fields_takes_the_defaults(defaults):
    defs, msg = defaults
    out = from_json(defs, msg, {'p': {'x': 1}})
    assert out['x'] == 1.5 and out['s'] == 'hi # there' and out['flag'] is True
    assert out['seq'] == [1, 2] and out['pair'] == [0.5, -1.0] and out['raw'] == bytes([1, 2, 255])
    assert out['plain'] == '' and out['p'] == {'x': 1.0, 'y': 0.0, 'z': 0.0}
    fresh = default_message(defs, msg)
    fresh['seq'].append(3)
    assert default_message(defs, msg)['seq'] == [1, 2]   # each message its own list


def test_the_text_rosbags_typestore_reads_keeps_constants_and_defaults(defaults):
    defs, msg = defaults
    text = definition_text(msg)
    assert 'string C="x#y"' in text and 'string s "hi # there"' in text
    assert parse_msg(msg.type, text) == msg                      # the text reads back the same
    consts, _ = get_types_from_msg(text, msg.type)[msg.type]
    assert ('C', 'string', 'x#y') in consts
    back = from_cdr(defs, msg.type, to_cdr(defs, msg.type, {}))   # CDR of an empty message: defaults
    assert back['x'] == 1.5 and back['s'] == 'hi # there' and list(back['seq']) == [1, 2]


def test_rosapi_shows_the_constant_whole(defaults):
    _, msg = defaults
    t = typedef(msg)
    assert t['constvalues'][t['constnames'].index('C')] == 'x#y'


def test_service_parts_resolve_names_in_the_package_msg():
    srv = Definitions().add_srv('pkg/srv/Do', 'Thing a\nstring NAME="a#b"\n---\nbool ok true\n')
    assert srv.request.fields[0].type == 'pkg/msg/Thing'
    assert srv.request.constants == (('NAME', 'string', 'a#b'),)
    assert srv.response.fields[0].default is True


def test_a_bad_line_is_named():
    with pytest.raises(ValueError, match=r"pkg/msg/Bad: cannot parse line '\$\$ x'"):
        parse_msg('pkg/msg/Bad', 'int32 a\n$$ x\n')


def test_an_actions_derived_types_have_the_fields_rosidl_gives_them():
    """X_SendGoal, X_GetResult and X_FeedbackMessage: the types of an action server's hidden
    endpoints (``_action/send_goal`` ...), found from the action; other names are not derived."""
    defs = Definitions.jazzy()
    fib = 'example_interfaces/action/Fibonacci'
    send = defs.srv(f'{fib}_SendGoal')
    assert [(f.name, f.type) for f in send.request.fields] == [
        ('goal_id', 'unique_identifier_msgs/msg/UUID'), ('goal', f'{fib}_Goal')]
    assert [(f.name, f.type) for f in send.response.fields] == [
        ('accepted', 'bool'), ('stamp', 'builtin_interfaces/msg/Time')]
    result = defs.srv(f'{fib}_GetResult')
    assert [(f.name, f.type) for f in result.response.fields] == [('status', 'int8'), ('result', f'{fib}_Result')]
    assert defs.msg(f'{fib}_GetResult_Request') is result.request
    feedback = defs.msg(f'{fib}_FeedbackMessage')
    assert [(f.name, f.type) for f in feedback.fields] == [
        ('goal_id', 'unique_identifier_msgs/msg/UUID'), ('feedback', f'{fib}_Feedback')]
    assert defs.derived('example_interfaces/srv/AddTwoInts') is None
    assert defs.derived(f'{fib}_Goal') is None
    with pytest.raises(LookupError, match='example_interfaces/action/Nope'):
        defs.srv('example_interfaces/action/Nope_SendGoal')
    message = {'goal_id': {'uuid': bytes(range(16))}, 'feedback': {'sequence': [0, 1, 1]}}   # cbor-raw's CDR
    data = to_cdr(defs, f'{fib}_FeedbackMessage', message)
    assert len(data) == 4 + 16 + 4 + 3 * 4
    assert from_cdr(defs, f'{fib}_FeedbackMessage', data) == message
