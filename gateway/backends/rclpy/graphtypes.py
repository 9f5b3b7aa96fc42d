"""Message types the install lacks, described by the nodes of the graph that use them (REP 2011).

A robot's own interface package is usually not installed where the gateway runs (and turtlesim,
tf2_msgs or example_interfaces are not on PyPI). Jazzy lets any node be asked: the graph gives
each endpoint's type hash (``get_publishers_info_by_topic`` / ``get_subscriptions_info_by_topic``),
and a node holding an endpoint of the type answers ``<node>/get_type_description`` with
``include_type_sources``: the TypeDescription and the ``.msg`` text of the type and of every type
it references, comments and constants included (1-100 ms measured, the first call with
discovery). The texts go through ``protocol.msgdefs.parse_msg`` into the backend's definitions,
so rosapi, JSON and CBOR see the type as an installed one; the description makes a ``RawType``
(``rawtype``), so the gateway's endpoints carry the robot's hash and move CDR bytes; and the
gateway's own CDR reader and writer (``cdr``, then ``protocol.cdr`` through rosbags for what the
fast path leaves) turn those bytes into message dicts and back. Nothing is built.

What the graph cannot describe: services (a node's type cache holds the service's own hash, the
graph shows only its Request/Response messages' hashes, and the node answers "Type not currently
in use" for those), the goal and result of actions, and a message type no node is using now.

The backend's types are asked for synchronously on the loop (``msg_def``, ``subscribe``), so a
first use waits here, bounded by ``timeout``, for the executor thread to bring the answer in; a
failure is remembered for ``RETRY`` seconds so a listing of many topics does not wait for each.
"""

from __future__ import annotations

import logging
import threading
import time
from dataclasses import dataclass, field

from protocol.cdr import from_cdr, to_cdr
from protocol.msgdefs import Definitions, MsgDef, UnknownType, definition_text, normalize

from . import cdr as rclpy_cdr
from .rawtype import RawType, type_hash

log = logging.getLogger('rosgate.rclpy')

RETRY = 2.0             # seconds a failed description is not asked for again
SELF_TEST_TOPIC = '/_rosgate/raw_type_self_test'
# type_description_interfaces/msg/FieldType ids -> .msg primitive names
_PRIMITIVES = {2: 'int8', 3: 'uint8', 4: 'int16', 5: 'uint16', 6: 'int32', 7: 'uint32',
               8: 'int64', 9: 'uint64', 10: 'float32', 11: 'float64', 12: 'float64', 13: 'char',
               14: 'char', 15: 'bool', 16: 'byte', 17: 'string', 18: 'wstring', 19: 'string',
               20: 'wstring', 21: 'string', 22: 'wstring'}


def hash_string(type_hash) -> str:
    """rclpy's TypeHash -> 'RIHS01_<64 hex>' ('' for an endpoint that carries none)."""
    if type_hash.version <= 0:
        return ''
    return 'RIHS%02d_%s' % (type_hash.version, bytes(type_hash.value).hex())


def field_text(f) -> str:
    """One Field of an IndividualTypeDescription as a .msg line."""
    t = f.type
    base_id, shape = t.type_id % 48, t.type_id // 48   # shape: 0 plain, 1 array, 2 bounded seq, 3 seq
    if base_id == 1:
        pkg, _, name = t.nested_type_name.split('/')
        base = f'{pkg}/{name}'
    else:
        base = _PRIMITIVES[base_id]
        if base_id in (21, 22) and t.string_capacity:
            base = f'{base}<={t.string_capacity}'
    return base + {0: '', 1: f'[{t.capacity}]', 2: f'[<={t.capacity}]', 3: '[]'}[shape] + ' ' + f.name


def text_from_description(individual) -> str:
    """.msg text from an IndividualTypeDescription, for a type whose source came back empty
    (action feedback parts: encoding 'implicit'); it has no comments and no constants."""
    return '\n'.join(field_text(f) for f in individual.fields
                     if f.name != 'structure_needs_at_least_one_member')


@dataclass
class Description:
    type: str                         # 'pkg/msg/Name'
    hash: str                         # 'RIHS01_...'
    node: str                         # the node that answered
    description: object               # type_description_interfaces/msg/TypeDescription
    texts: dict[str, str] = field(default_factory=dict)   # type -> .msg text, the type's and every referenced one


class GraphTypes:
    """Describes message types from the graph and makes their type supports and CDR codecs.

    ``node``: the backend's node, spun by the executor on ``executor_thread`` (a describe from
    that thread would wait for itself, so it is refused)."""

    def __init__(self, node, executor_thread: threading.Thread | None, defs, timeout: float = 3.0):
        """defs: the backend's RosDefinitions (the fast codec looks nested types up there)."""
        self.node, self._executor_thread, self.defs, self.timeout = node, executor_thread, defs, timeout
        self._described: dict[str, Description] = {}
        self._failed: dict[str, tuple[float, str]] = {}
        self._raw: dict[str, RawType] = {}
        self._tested: str | None = None         # None: not yet; '': passed; else why it failed
        self._cdr_defs: Definitions | None = None
        self._readers: dict[str, object] = {}
        self._writers: dict[str, object] = {}

    # --- describe -----------------------------------------------------------------------------

    def describe(self, full: str) -> Description:
        """The description of a message type some node of the graph uses; UnknownType if none can
        give it (naming why)."""
        found = self._described.get(full)
        if found is not None:
            return found
        failed = self._failed.get(full)
        if failed is not None and time.monotonic() < failed[0]:
            raise UnknownType(failed[1])
        try:
            found = self._described[full] = self._ask(full)
        except UnknownType as e:
            self._failed[full] = (time.monotonic() + RETRY, str(e))
            raise
        log.info('%s described by %s (not installed here)', full, found.node)
        return found

    def _ask(self, full: str) -> Description:
        if threading.current_thread() is self._executor_thread:
            raise UnknownType(f'unknown message type {full!r} (not described from the executor thread)')
        topics = [name for name, types in self.node.get_topic_names_and_types() if full in types]
        if not topics:
            raise UnknownType(f'unknown message type {full!r}: it is not installed here, and no node '
                              f'on the ROS graph publishes or subscribes a topic of that type')
        failures: list[str] = []
        for topic in topics:
            try:
                return self.describe_topic(topic, full)
            except UnknownType as e:
                failures.append(str(e))
        raise UnknownType(f'unknown message type {full!r}: it is not installed here, and the graph '
                          f'did not describe it: ' + '; '.join(failures))

    def describe_topic(self, topic: str, full: str, *, own: bool = False) -> Description:
        """Ask the nodes with an endpoint of ``full`` on ``topic`` (other nodes; ``own``: this one)."""
        me = self.node.get_fully_qualified_name()
        deadline = time.monotonic() + self.timeout
        while True:     # discovery names an endpoint's node a little after the endpoint itself
            infos = self.node.get_publishers_info_by_topic(topic) + self.node.get_subscriptions_info_by_topic(topic)
            named = [i for i in infos if i.topic_type == full and hash_string(i.topic_type_hash)
                     and not i.node_name.startswith('_NODE_NAME_UNKNOWN')
                     and (_fq(i) == me) == own]
            if named or time.monotonic() > deadline:
                break
            time.sleep(0.02)
        if not named:
            raise UnknownType(f'{topic}: no node with a {full} endpoint there could be asked')
        failures = []
        for info in {_fq(i): i for i in named}.values():
            try:
                return self._call(_fq(info), full, hash_string(info.topic_type_hash), deadline)
            except UnknownType as e:
                failures.append(str(e))
        raise UnknownType('; '.join(failures))

    def _call(self, node: str, full: str, type_hash: str, deadline: float) -> Description:
        from type_description_interfaces.srv import GetTypeDescription  # noqa: PLC0415 (rclpy's own)

        service = node.rstrip('/') + '/get_type_description'
        client = self.node.create_client(GetTypeDescription, service)
        try:
            if not client.wait_for_service(timeout_sec=max(0.1, deadline - time.monotonic())):
                raise UnknownType(f'{service} is not available')
            done = threading.Event()
            future = client.call_async(GetTypeDescription.Request(
                type_name=full, type_hash=type_hash, include_type_sources=True))
            future.add_done_callback(lambda f: done.set())
            if not done.wait(max(0.1, deadline - time.monotonic())) or future.result() is None:
                raise UnknownType(f'{service} did not answer within {self.timeout} s')
            answer = future.result()
        finally:
            self.node.destroy_client(client)
        if not answer.successful:
            raise UnknownType(f'{service}: {answer.failure_reason}')
        described = answer.type_description
        individuals = {t.type_name: t for t in [described.type_description,
                                                 *described.referenced_type_descriptions]}
        sources = {s.type_name: (s.encoding, s.raw_file_contents) for s in answer.type_sources}
        texts = {}
        for name, individual in individuals.items():
            encoding, text = sources.get(name, ('', ''))
            texts[name] = text if encoding == 'msg' and text else text_from_description(individual)
        return Description(full, type_hash, node, described, texts)

    # --- type supports ------------------------------------------------------------------------

    def type_support(self, full: str):
        """The class rclpy takes for a described type: a RawType's (CDR only)."""
        raw = self._raw.get(full)
        if raw is None:
            self.self_test()
            d = self.describe(full)
            raw = self._raw[full] = RawType(d.description, d.hash)
        return raw.cls

    def self_test(self) -> None:
        """Once: an installed type (rcl_interfaces/msg/Log, as this node's /rosout publisher has
        it) through a RawType both ways against its generated type support, over a topic of this
        node. Raises UnknownType saying why when the run-time type supports do not work here."""
        if self._tested is None:
            started = time.monotonic()
            try:
                self._self_test()
                self._tested = ''
                log.debug('raw type support self-test passed in %.3f s', time.monotonic() - started)
            except Exception as e:  # noqa: BLE001 (whatever failed, the answer is the same)
                self._tested = (f'types that are not installed cannot be used: the run-time type '
                                f'support self-test failed ({e}); this needs the Jazzy layouts of '
                                f'rclpy 7.1, rosidl 4.6 and rosidl_typesupport_fastrtps 3.6 '
                                f'(pip install \'rosgate[ros]\'), or install the interface package')
                log.warning('%s', self._tested)
        if self._tested:
            raise UnknownType(self._tested)

    def _self_test(self) -> None:
        from rcl_interfaces.msg import Log  # noqa: PLC0415
        from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy  # noqa: PLC0415
        from rclpy.qos import QoSProfile  # noqa: PLC0415
        from rclpy.serialization import deserialize_message, serialize_message  # noqa: PLC0415
        from rclpy.type_support import check_is_valid_msg_type  # noqa: PLC0415

        full = 'rcl_interfaces/msg/Log'
        check_is_valid_msg_type(Log)    # loads its type support
        d = self.describe_topic('/rosout', full, own=True)
        raw = RawType(d.description, d.hash)
        qos = QoSProfile(depth=10).get_c_qos_profile()
        node, topic = self.node, SELF_TEST_TOPIC
        with node.handle:
            handles = [_rclpy.Publisher(node.handle, raw.cls, topic, qos),
                       _rclpy.Subscription(node.handle, Log, topic, qos),
                       _rclpy.Publisher(node.handle, Log, topic, qos),
                       _rclpy.Subscription(node.handle, raw.cls, topic, qos)]
        raw_pub, sub, pub, raw_sub = handles
        try:
            hashes = {hash_string(i.topic_type_hash) for i in node.get_publishers_info_by_topic(topic)}
            if hashes != {d.hash}:
                raise RuntimeError(f'endpoint hashes {sorted(hashes)} are not {d.hash}')
            data = serialize_message(Log(level=20, name='rosgate', msg='raw type self-test', line=7))
            raw_pub.publish_raw(data)
            for reader, cls in ((sub, Log), (raw_sub, raw.cls)):
                got = _take(reader, cls, 1.0)
                if got != data:
                    raise RuntimeError('a message published through a raw type support came back '
                                       'different' if got else 'no message came through a raw type support')
            pub.publish(deserialize_message(data, Log))
            if _take(sub, Log, 1.0) != data or _take(raw_sub, raw.cls, 1.0) != data:
                raise RuntimeError('a raw type support did not take what the generated one published')
        finally:
            for h in handles:
                h.destroy_when_not_in_use()

    def check_built(self, name: str, kind: str, cls) -> None:
        """A service or action built here from texts against what its server on the graph speaks:
        UnknownType when the request hashes differ (the text is not the robot's)."""
        name = self.node.resolve_service_name(name)
        if kind == 'srv':
            topic, request = f'rq{name}Request', cls.Request
        else:
            topic, request = f'rq{name}/_action/send_goalRequest', cls.Impl.SendGoalService.Request
        me = self.node.get_fully_qualified_name()
        infos = (self.node.get_publishers_info_by_topic(topic, no_mangle=True)
                 + self.node.get_subscriptions_info_by_topic(topic, no_mangle=True))
        theirs = {hash_string(i.topic_type_hash) for i in infos if _fq(i) != me} - {''}
        ours = type_hash(request)
        if theirs and ours not in theirs:
            raise UnknownType(f'{name}: the {kind} type built here from its text is not the one its server '
                              f'speaks (request hash {ours[:15]}..., the graph has {sorted(h[:15] + "..." for h in theirs)}): '
                              f'give the robot\'s own text with --interfaces')

    # --- CDR ----------------------------------------------------------------------------------

    def reader(self, full: str):
        """CDR bytes -> message dict for a described type (the fast path, else rosbags)."""
        return self._codec(self._readers, full, rclpy_cdr.reader, from_cdr, Exception)

    def writer(self, full: str):
        """Message dict -> CDR bytes for a described type; raises ConversionError for bad values."""
        return self._codec(self._writers, full, rclpy_cdr.writer, to_cdr, rclpy_cdr.Slow)

    def _codec(self, cache: dict, full: str, compile, general, slow):
        """One conversion of a described type, made once: rclpy_cdr's compiled walk where it has
        one, falling back to protocol.cdr (rosbags) for what it raises ``slow`` on."""
        codec = cache.get(full)
        if codec is None:
            fast = compile(self._plan, self.defs.msg(full))
            cdr_defs = self._cdr()

            def codec(value):
                if fast is not None:
                    try:
                        return fast(value)
                    except slow:  # noqa: BLE001 (rclpy_cdr.Slow, or short data: rosbags decides)
                        pass
                return general(cdr_defs, full, value)
            cache[full] = codec
        return codec

    def _plan(self, msgdef: MsgDef) -> tuple:
        """Fields of a definition as rclpy_cdr walks them: (name, Field, nested MsgDef or None)."""
        return tuple((f.name, f, None if f.primitive else self.defs.msg(f.type)) for f in msgdef.fields)

    def _cdr(self) -> Definitions:
        """Definitions with a rosbags typestore that knows every described type (protocol.cdr)."""
        from rosbags.typesys import Stores, get_typestore, get_types_from_msg  # noqa: PLC0415

        if self._cdr_defs is None:
            self._cdr_defs = Definitions()
            self._cdr_defs.load_typestore(get_typestore(Stores.ROS2_JAZZY))
        cdr_defs = self._cdr_defs
        store = cdr_defs.typestore
        new = {}
        for d in self._described.values():
            for name, text in d.texts.items():
                if name not in store.fielddefs and name not in new:
                    new[name] = cdr_defs.add_msg(name, text)
        types = {}
        for name, msgdef in new.items():
            for key, value in get_types_from_msg(definition_text(msgdef), name).items():
                types[name if normalize(key, 'msg') == name else key] = value
        if types:
            store.register(types)
        return cdr_defs


def _fq(info) -> str:
    return info.node_namespace.rstrip('/') + '/' + info.node_name


def _take(reader, cls, timeout: float) -> bytes | None:
    deadline = time.monotonic() + timeout
    while True:
        got = reader.take_message(cls, True)
        if got is not None:
            return got[0]
        if time.monotonic() > deadline:
            return None
        time.sleep(0.005)
