"""The whole gateway over rclpy, through websockets: traffic that used to wait for rclpy's executor.

A rosgate process (``--backend rclpy``) on the contract suite's ROS domain, driven by tornado
websocket clients; ROS callers are plain rclpy nodes of their own context (``RosCaller``).
"""

from __future__ import annotations

import asyncio
import base64
import itertools
import json
import socket

import cbor2
import pytest
from tornado.websocket import websocket_connect

from tests.support.contract import rclpy_missing
from tests.support.rawsocket import client_frame, raw_websocket
from tests.support.wait import TIMEOUT, until

pytestmark = [
    pytest.mark.asyncio(loop_scope='session'),
    pytest.mark.skipif(rclpy_missing() is not None, reason='rclpy does not import here'),
]


@pytest.fixture(scope='module')
def gateway(rclpy_helpers, start_gateway):
    return start_gateway('--backend', 'rclpy', '--send-buffer-limit', str(2 * 2**20))


class Client:
    def __init__(self, conn):
        self.conn = conn

    @classmethod
    async def open(cls, gateway) -> Client:
        return cls(await websocket_connect(gateway.ws_url, max_message_size=2**30))

    async def send(self, op: dict) -> None:
        await self.conn.write_message(json.dumps(op))

    async def recv(self, timeout: float = 10.0) -> dict:
        frame = await asyncio.wait_for(self.conn.read_message(), timeout)
        assert frame is not None, 'connection closed'
        return json.loads(frame)

    async def expect(self, predicate, timeout: float = 10.0) -> dict:
        loop = asyncio.get_running_loop()
        deadline = loop.time() + timeout
        while True:
            msg = await self.recv(max(0.01, deadline - loop.time()))
            if predicate(msg):
                return msg

    async def sync(self) -> None:
        """Everything sent before has been handled (a round trip through the gateway)."""
        await self.send({'op': 'call_service', 'id': 'sync', 'service': '/rosapi/get_time'})
        await self.expect(lambda m: m.get('id') == 'sync')

    def close(self) -> None:
        self.conn.close()


def stalled_client(gateway, ops: list[dict]) -> socket.socket:
    """A websocket client that sends ``ops`` and then never reads."""
    sock, _rest = raw_websocket(gateway.host, gateway.port, gateway.path, rcvbuf=4096)
    for op in ops:
        sock.sendall(client_frame(0x1, json.dumps(op).encode()))
    return sock


async def warm_up(sub: Client, publish, topic: str, timeout: float = 20.0) -> None:
    """Until DDS has matched the publisher with the gateway's subscription of topic: one of its own
    warm-up messages arrived (a late message of another source on the topic proves nothing)."""
    deadline = asyncio.get_running_loop().time() + timeout
    while True:
        assert asyncio.get_running_loop().time() < deadline, f'{topic}: the subscription never matched'
        publish('warm-up')
        try:
            await sub.expect(lambda m: m.get('op') == 'publish' and m.get('topic') == topic
                             and 'warm-up' in json.dumps(m.get('msg')), timeout=0.2)
            return
        except asyncio.TimeoutError:
            continue


async def subscribe_raw_and_plain(raw: Client, plain: Client, topic: str, type: str) -> None:
    """raw subscribed to topic as cbor-raw (the CDR bytes), plain as JSON."""
    await raw.send({'op': 'subscribe', 'topic': topic, 'type': type, 'compression': 'cbor-raw', 'queue_length': 100})
    await plain.send({'op': 'subscribe', 'topic': topic, 'type': type, 'queue_length': 100})
    await raw.sync()
    await plain.sync()


async def raw_bytes(raw: Client, n: int, keep) -> list[bytes]:
    """The CDR bytes of the next n messages a cbor-raw client gets that keep(bytes) accepts."""
    got = []
    while len(got) < n:
        frame = await asyncio.wait_for(raw.conn.read_message(), 20)
        assert isinstance(frame, bytes), frame
        msg = cbor2.loads(frame)
        if msg.get('op') == 'publish' and keep(msg['msg']['bytes']):
            got.append(msg['msg']['bytes'])
    return got


def through(client: Client, topic: str):
    """publish(text) on topic through a websocket client (std_msgs/String, advertised)."""
    return lambda text: asyncio.ensure_future(
        client.send({'op': 'publish', 'topic': topic, 'msg': {'data': text}}))


async def test_a_stalled_client_costs_the_others_nothing(gateway):
    topic, payload = '/rclpy_flood', 'z' * 100_000
    slow = stalled_client(gateway, [{'op': 'subscribe', 'topic': topic, 'type': 'std_msgs/msg/String'}])
    fast, pub = await Client.open(gateway), await Client.open(gateway)
    try:
        await fast.send({'op': 'subscribe', 'topic': topic, 'type': 'std_msgs/msg/String'})
        await fast.sync()
        await pub.send({'op': 'advertise', 'topic': topic, 'type': 'std_msgs/msg/String'})
        await warm_up(fast, through(pub, topic), topic)
        count = 300    # 30 MB past a client that never reads
        for i in range(count):   # lock-step: each message reaches the fast client, in order
            await pub.send({'op': 'publish', 'topic': topic, 'msg': {'data': f'{i:06d}' + payload}})
            msg = await fast.expect(lambda m: m.get('op') == 'publish' and m['msg']['data'] != 'warm-up')
            assert int(msg['msg']['data'][:6]) == i
    finally:
        fast.close()
        pub.close()
        slow.close()
    assert gateway.alive


async def test_browser_served_service_and_action_answer_ros_callers_under_load(gateway, caller, rclpy_helpers):
    helpers = rclpy_helpers
    browser, flood_pub, flood_sub = [await Client.open(gateway) for _ in range(3)]
    await browser.send({'op': 'advertise_service', 'service': '/browser_add', 'type': helpers.add_type})
    await browser.send({'op': 'advertise_action', 'action': '/browser_fib', 'type': helpers.fib_type})
    await browser.sync()

    served = {'calls': 0, 'goals': 0}

    async def serve() -> None:       # the browser: answers calls and goals from the gateway
        while True:
            msg = await browser.recv(timeout=None)
            if msg.get('op') == 'call_service' and msg.get('service') == '/browser_add':
                served['calls'] += 1
                args = msg['args']
                total = (args['a'] + args['b']) if 'a' in args else args['int64_value'] + args['int32_value']
                values = {'sum': total} if 'a' in args else {'int64_value': total}
                await browser.send({'op': 'service_response', 'service': '/browser_add', 'id': msg['id'],
                                    'values': values, 'result': True})
            elif msg.get('op') == 'send_action_goal':
                served['goals'] += 1
                order, sequence = msg['args']['order'], [0, 1]
                while len(sequence) < order + 1:
                    sequence.append(sequence[-1] + sequence[-2])
                    await browser.send({'op': 'action_feedback', 'action': msg['action'], 'id': msg['id'],
                                        'values': {'sequence': sequence}})
                await browser.send({'op': 'action_result', 'action': msg['action'], 'id': msg['id'],
                                    'status': 4, 'values': {'sequence': sequence}, 'result': True})

    delivered = [0]

    async def flood() -> None:       # as fast as the gateway moves it, 32 in flight
        topic = '/rclpy_load'
        await flood_sub.send({'op': 'subscribe', 'topic': topic, 'type': 'std_msgs/msg/String',
                              'queue_length': 100})
        await flood_sub.sync()
        await flood_pub.send({'op': 'advertise', 'topic': topic, 'type': 'std_msgs/msg/String'})
        window = asyncio.Semaphore(32)

        async def read() -> None:
            while True:
                msg = await flood_sub.recv(timeout=None)
                if msg.get('op') == 'publish':
                    delivered[0] += 1
                    window.release()

        reader = asyncio.ensure_future(read())
        try:
            while True:
                try:
                    await asyncio.wait_for(window.acquire(), 1.0)
                except asyncio.TimeoutError:     # lost to discovery at the start: refill
                    window = asyncio.Semaphore(32)
                    continue
                await flood_pub.send({'op': 'publish', 'topic': topic, 'msg': {'data': 'x' * 64}})
        finally:
            reader.cancel()

    tasks = [asyncio.ensure_future(serve()), asyncio.ensure_future(flood())]
    try:
        await until(lambda: delivered[0] >= 1000, timeout=30, what='the flood flowing')
        await until(lambda: caller.ready('/browser_add', '/browser_fib'), timeout=15,
                    what='the browser-served service and action seen by the ROS caller')
        before = delivered[0]
        for i in range(20):
            response = await caller.call('/browser_add', helpers.add_request(i, 1000))
            assert helpers.add_sum(response) == i + 1000
        result, feedback = await caller.goal('/browser_fib', 6)
        assert list(result.sequence) == [0, 1, 1, 2, 3, 5, 8]
        # feedback travels apart from the result: some may still be on its way
        assert feedback and all(f == [0, 1, 1, 2, 3, 5, 8][:len(f)] for f in feedback)
        assert served == {'calls': 20, 'goals': 1}
        assert delivered[0] > before      # the flood went on meanwhile
    finally:
        for task in tasks:
            task.cancel()
        for client in (browser, flood_pub, flood_sub):
            client.close()
    assert gateway.alive


async def test_messages_of_a_client_and_a_ros_node_on_one_topic_keep_their_order(gateway, caller):
    """The gateway takes what it published itself at once, on the loop; a ROS node's messages on
    the same topic come through the pump thread: each source's messages arrive in order, all."""
    topic = '/rclpy_mixed'
    sub, pub = await Client.open(gateway), await Client.open(gateway)
    node_publish, _count = caller.string_publisher(topic)
    try:
        await sub.send({'op': 'subscribe', 'topic': topic, 'type': 'std_msgs/msg/String', 'queue_length': 1000})
        await sub.sync()
        await pub.send({'op': 'advertise', 'topic': topic, 'type': 'std_msgs/msg/String'})
        await warm_up(sub, through(pub, topic), topic)
        await warm_up(sub, node_publish, topic)
        got: dict[str, list[int]] = {'c': [], 'n': []}
        rounds, step = 300, 20    # at most 2 x 20 in flight: within the gateway reader's history
        for start in range(0, rounds, step):
            for i in range(start, start + step):
                await pub.send({'op': 'publish', 'topic': topic, 'msg': {'data': f'c{i}'}})
                node_publish(f'n{i}')
            while len(got['c']) < start + step or len(got['n']) < start + step:
                data = (await sub.expect(lambda m: m.get('op') == 'publish'))['msg']['data']
                if data != 'warm-up':
                    got[data[0]].append(int(data[1:]))
        assert got == {'c': list(range(rounds)), 'n': list(range(rounds))}
    finally:
        sub.close()
        pub.close()
    assert gateway.alive


async def test_a_client_that_subscribes_again_hears_a_ros_node_after_another_client_published(gateway, caller):
    """While a client publishes, the pump leaves the topic's readers to the loop; a reader made
    meanwhile (the subscriber came back) is handed back to the pump with the rest."""
    topic = '/rclpy_handover'
    subscribe = {'op': 'subscribe', 'id': 's', 'topic': topic, 'type': 'std_msgs/msg/String', 'queue_length': 100}
    sub, pub = await Client.open(gateway), await Client.open(gateway)
    node_publish, _count = caller.string_publisher(topic)
    try:
        await sub.send(subscribe)
        await sub.sync()
        await pub.send({'op': 'advertise', 'topic': topic, 'type': 'std_msgs/msg/String'})
        await warm_up(sub, through(pub, topic), topic)
        for i in range(50):
            await pub.send({'op': 'publish', 'topic': topic, 'msg': {'data': f'c{i}'}})
        await sub.send({'op': 'unsubscribe', 'id': 's', 'topic': topic})   # the gateway's reader goes
        await sub.send(subscribe)                                            # and a new one comes
        await sub.sync()
        await warm_up(sub, node_publish, topic)
        for i in range(50):
            node_publish(f'n{i}')
        got = []
        while len(got) < 50:
            data = (await sub.expect(lambda m: m.get('op') == 'publish'))['msg']['data']
            if data.startswith('n'):
                got.append(data)
        assert got == [f'n{i}' for i in range(50)]
    finally:
        sub.close()
        pub.close()
    assert gateway.alive


async def test_a_burst_from_a_ros_node_reaches_json_and_cbor_clients_intact(gateway, caller):
    """The pump hands the loop a batch; each client gets its share in one write of frames the
    gateway builds itself: every length encoding, text and binary."""
    topic, sizes = '/rclpy_burst', [3, 125, 126, 300, 65535, 65536, 70_000]
    expected = [f'{r:02d}{i}'.ljust(size, 'x') for r in range(4) for i, size in enumerate(sizes)]
    json_sub, cbor_sub = await Client.open(gateway), await Client.open(gateway)
    publish, _count = caller.string_publisher(topic)
    try:
        await json_sub.send({'op': 'subscribe', 'topic': topic, 'type': 'std_msgs/msg/String',
                             'queue_length': 1000})
        await cbor_sub.send({'op': 'subscribe', 'topic': topic, 'type': 'std_msgs/msg/String',
                             'queue_length': 1000, 'compression': 'cbor'})
        await json_sub.sync()
        await cbor_sub.sync()
        await warm_up(json_sub, publish, topic)
        for data in expected:
            publish(data)
        for client, decode in ((json_sub, None), (cbor_sub, cbor2.loads)):
            got = []
            while len(got) < len(expected):
                frame = await asyncio.wait_for(client.conn.read_message(), 20)
                assert frame is not None, 'connection closed'
                msg = decode(frame) if decode else json.loads(frame)
                if msg.get('op') == 'publish' and msg['msg']['data'] != 'warm-up':
                    got.append(msg['msg']['data'])
            assert got == expected
    finally:
        json_sub.close()
        cbor_sub.close()
    assert gateway.alive


async def test_cbor_raw_clients_get_the_cdr_as_the_ros_node_published_it(gateway, caller):
    from rclpy.serialization import deserialize_message, serialize_message
    from std_msgs.msg import String

    topic = '/rclpy_raw'
    raw, plain = await Client.open(gateway), await Client.open(gateway)
    publish, _count = caller.string_publisher(topic)
    try:
        await subscribe_raw_and_plain(raw, plain, topic, 'std_msgs/msg/String')
        await warm_up(plain, publish, topic)
        texts = ['hello', 'é' * 700, 'y' * 100_000]
        for text in texts:
            publish(text)
        got = await raw_bytes(raw, len(texts), lambda data: data != serialize_message(String(data='warm-up')))
        for data, text in zip(got, texts):   # as published: the CDR, plus any padding the middleware adds
            expected = serialize_message(String(data=text))
            assert data[:len(expected)] == expected and set(data[len(expected):]) <= {0}, data[-16:]
            assert len(data) - len(expected) < 8
            assert deserialize_message(data, String).data == text
    finally:
        raw.close()
        plain.close()
    assert gateway.alive


async def test_cbor_raw_clients_get_the_cdr_dds_delivered_for_types_without_a_compiled_reader(gateway, caller):
    """JointState (string[]) is taken as a message object for JSON clients; for cbor-raw ones the
    gateway keeps the CDR it took: the bytes another subscriber of the graph gets, not a rebuild."""
    from rclpy.serialization import deserialize_message
    from sensor_msgs.msg import JointState

    topic, type = '/rclpy_raw_joints', 'sensor_msgs/msg/JointState'
    delivered = caller.raw_listener(JointState, topic)
    publish = caller.publisher(JointState, topic)
    raw, plain = await Client.open(gateway), await Client.open(gateway)
    sent = [JointState(name=[f'joint_{i}' * i for i in range(1, n + 1)], position=[0.5 * n] * n,
                       effort=[-1.0] * (n % 2)) for n in range(1, 6)]

    def warm(data: bytes) -> bool:
        return deserialize_message(data, JointState).name == ['warm-up']

    def heard_all() -> list[bytes] | None:
        heard = [d for d in delivered if not warm(d)]
        return heard if len(heard) >= len(sent) else None
    try:
        await subscribe_raw_and_plain(raw, plain, topic, type)
        await warm_up(plain, lambda text: publish(JointState(name=[text])), topic)
        for msg in sent:
            publish(msg)
        got = await raw_bytes(raw, len(sent), lambda data: not warm(data))
        heard = await until(heard_all, what='the ROS subscriber hearing them')
        assert [deserialize_message(d, JointState) for d in got] == sent
        assert got == heard[-len(sent):]
    finally:
        raw.close()
        plain.close()
    assert gateway.alive


async def test_a_service_and_an_action_that_appear_while_the_call_waits_answer_it(gateway, rclpy_helpers):
    """A client calls a service (sends a goal) that a node is creating at that moment: the gateway
    has not discovered it when the call arrives, and waits for it as rosbridge does (1 s)."""
    helpers, client, stops = rclpy_helpers, await Client.open(gateway), []

    async def services() -> list[str]:
        await client.send({'op': 'call_service', 'id': 'services', 'service': '/rosapi/services'})
        return (await client.expect(lambda m: m.get('id') == 'services'))['values']['services']

    try:
        deadline = asyncio.get_running_loop().time() + 15
        while '/add_two_ints' not in await services():    # the gateway knows the helpers' participant
            assert asyncio.get_running_loop().time() < deadline, 'the helper nodes were never discovered'
        for n, typed in enumerate((True, False)):      # roslibjs sends no type: resolved once seen
            service = f'/rclpy_late_add_{n}'
            call = {'op': 'call_service', 'id': f'late{n}', 'service': service,
                    'args': helpers.add_request(2, n)}
            await client.send({**call, 'type': helpers.add_type} if typed else call)
            await client.sync()         # the gateway has the call: the server does not exist yet
            stops.append(helpers.late_server('service', service))
            reply = await client.expect(lambda m: m.get('id') == f'late{n}')
            assert reply['result'] is True, reply
            assert helpers.add_sum(reply['values']) == 2 + n
        await client.send({'op': 'send_action_goal', 'id': 'late_goal', 'action': '/rclpy_late_fib',
                           'action_type': helpers.fib_type, 'args': {'order': 3}})
        await client.sync()
        stops.append(helpers.late_server('action', '/rclpy_late_fib'))
        result = await client.expect(lambda m: m.get('id') == 'late_goal' and m.get('op') == 'action_result')
        assert (result['result'], result['values']) == (True, {'sequence': [0, 1, 1, 2]}), result
    finally:
        for stop in stops:
            stop()
        client.close()
    assert gateway.alive


async def test_a_serving_client_gets_requests_named_as_it_advertised_them(gateway, caller, rclpy_helpers):
    """A ROS node calls a service and sends a goal to an action a browser advertised under a
    relative name and a short type: the browser gets those back (roslibjs routes by them)."""
    helpers, browser = rclpy_helpers, await Client.open(gateway)
    short_fib = helpers.fib_type.replace('/action/', '/')
    try:
        await browser.send({'op': 'advertise_service', 'service': 'rclpy_echo_add',
                            'type': helpers.add_type.replace('/srv/', '/')})
        await browser.send({'op': 'advertise_action', 'action': 'rclpy_echo_fib', 'type': short_fib})
        await browser.sync()
        await until(lambda: caller.ready('/rclpy_echo_add', '/rclpy_echo_fib'), timeout=15,
                    what='the ROS caller seeing the browser-served service and action')
        call = asyncio.ensure_future(caller.call('/rclpy_echo_add', helpers.add_request(1, 2)))
        request = await browser.expect(lambda m: m.get('op') == 'call_service')
        assert request['service'] == 'rclpy_echo_add' and 'type' not in request
        await browser.send({'op': 'service_response', 'service': 'rclpy_echo_add', 'id': request['id'],
                            'values': {'sum': 3} if 'a' in request['args'] else {'int64_value': 3},
                            'result': True})
        assert helpers.add_sum(await call) == 3
        goal = asyncio.ensure_future(caller.goal('/rclpy_echo_fib', 2))
        request = await browser.expect(lambda m: m.get('op') == 'send_action_goal')
        assert (request['action'], request['action_type']) == ('rclpy_echo_fib', short_fib)
        await browser.send({'op': 'action_result', 'action': 'rclpy_echo_fib', 'id': request['id'],
                            'status': 4, 'values': {'sequence': [0, 1, 1]}, 'result': True})
        result, _feedback = await goal
        assert list(result.sequence) == [0, 1, 1]
    finally:
        browser.close()
    assert gateway.alive


async def test_two_gateways_on_one_graph_are_two_nodes(gateway, start_gateway, caller):
    """Each gateway's node is rosgate_<host>_<port> unless --node-name says otherwise."""
    from gateway.cli import default_node_name

    second = start_gateway('--backend', 'rclpy')
    names = [gateway.node, second.node]
    assert names == ['/' + default_node_name(g.port) for g in (gateway, second)]
    assert names[0] != names[1]

    def seen() -> list[str]:
        found = [ns.rstrip('/') + '/' + n for n, ns in caller.node.get_node_names_and_namespaces()]
        return found if set(names) <= set(found) else []
    found = await until(seen, timeout=15, what='both gateways in the graph')
    assert [found.count(name) for name in names] == [1, 1]
    client = await Client.open(second)
    try:   # the new gateway's own view of the graph fills as discovery goes on: ask until it has both
        deadline = asyncio.get_running_loop().time() + 15
        for n in itertools.count():
            await client.send({'op': 'call_service', 'id': f'nodes{n}', 'service': '/rosapi/nodes'})
            nodes = (await client.expect(lambda m: m.get('id') == f'nodes{n}'))['values']['nodes']
            if set(names) <= set(nodes) or asyncio.get_running_loop().time() > deadline:
                break
            await asyncio.sleep(0.1)
        assert set(names) <= set(nodes), nodes
    finally:
        client.close()
    second.stop()


async def test_a_64_kib_byte_array_crosses_the_rclpy_backend_byte_exact_both_ways(gateway, caller):
    """uint8[] of 64 KiB (every byte value): a client's base64 reaches a ROS node as the same bytes,
    and a ROS node's bytes reach a JSON client as their base64 and a CBOR client as themselves. A
    value that is not base64 gets a status naming the op, the id and the field; the connection
    carries on."""
    from rclpy.serialization import deserialize_message
    from sensor_msgs.msg import CompressedImage

    topic, type_ = '/rclpy_bytes_64k', 'sensor_msgs/msg/CompressedImage'
    payload = bytes(reversed(range(256))) * 128 + bytes(range(256)) * 128
    header = {'stamp': {'sec': 7, 'nanosec': 8}, 'frame_id': 'cam'}
    heard = caller.raw_listener(CompressedImage, topic)
    pub = await Client.open(gateway)
    json_sub, cbor_sub = await Client.open(gateway), await Client.open(gateway)
    try:
        await pub.send({'op': 'advertise', 'topic': topic, 'type': type_})
        loop = asyncio.get_running_loop()
        deadline = loop.time() + TIMEOUT
        while not heard:       # until DDS matched the ROS node's subscription with the gateway
            assert loop.time() < deadline, 'the ROS node heard nothing'
            await pub.send({'op': 'publish', 'topic': topic, 'msg': {
                'header': header, 'format': 'raw', 'data': base64.b64encode(payload).decode()}})
            await pub.sync()   # a round trip paces the publishes
        got = deserialize_message(heard[0], CompressedImage)
        assert (got.header.frame_id, got.header.stamp.sec, got.format) == ('cam', 7, 'raw')
        assert bytes(got.data) == payload

        await pub.send({'op': 'publish', 'id': 'not-b64', 'topic': topic,
                        'msg': {'header': header, 'format': 'raw', 'data': 'not base64!'}})
        status = await pub.expect(lambda m: m.get('op') == 'status' and m.get('id') == 'not-b64', TIMEOUT)
        assert status['level'] == 'error', status
        assert status['msg'].startswith('publish (id not-b64):') and "'data'" in status['msg'] \
            and 'base64' in status['msg'], status
        await pub.sync()       # the connection carries on

        for client, compression in ((json_sub, 'none'), (cbor_sub, 'cbor')):
            await client.send({'op': 'subscribe', 'topic': topic, 'type': type_, 'compression': compression})
            await client.sync()
        ros_payload = payload[1:] + payload[:1]
        publish = caller.publisher(CompressedImage, topic)
        from_node = CompressedImage(format='node', data=ros_payload)

        async def heard_from_node(client: Client, decode) -> dict:
            deadline = loop.time() + TIMEOUT
            while True:
                assert loop.time() < deadline, 'no message of the ROS node arrived'
                publish(from_node)
                try:
                    while True:
                        frame = await asyncio.wait_for(client.conn.read_message(), 0.5)
                        assert frame is not None, 'connection closed'
                        msg = decode(frame)
                        if msg.get('op') == 'publish' and msg['msg']['format'] == 'node':
                            return msg['msg']
                except asyncio.TimeoutError:
                    continue
        as_json = await heard_from_node(json_sub, json.loads)
        assert base64.b64decode(as_json['data'], validate=True) == ros_payload
        as_cbor = await heard_from_node(cbor_sub, cbor2.loads)
        assert as_cbor['data'] == ros_payload
    finally:
        for client in (pub, json_sub, cbor_sub):
            client.close()
    assert gateway.alive
