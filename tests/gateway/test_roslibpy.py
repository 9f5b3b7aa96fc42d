"""The reference's websocket cases, re-done black-box with the real roslibpy client."""

from __future__ import annotations

import threading
import time
import uuid

import roslibpy

from tests.support.ros import cancelled, client
from tests.support.wait import wait_for


def test_smoke_ten_messages_each_way(ros):
    inbound = roslibpy.Topic(ros, '/smoke/in', 'std_msgs/msg/String')
    outbound = roslibpy.Topic(ros, '/smoke/out', 'std_msgs/msg/String')
    got_in, got_out = [], []
    inbound.subscribe(got_in.append)
    outbound.subscribe(got_out.append)
    wait_for(lambda: '/smoke/in' in ros.get_topics())
    inbound.advertise()
    outbound.advertise()
    for i in range(10):
        inbound.publish(roslibpy.Message({'data': f'in {i}'}))
        outbound.publish(roslibpy.Message({'data': f'out {i}'}))
    wait_for(lambda: len(got_in) == 10 and len(got_out) == 10)
    assert [m['data'] for m in got_in] == [f'in {i}' for i in range(10)]
    assert [m['data'] for m in got_out] == [f'out {i}' for i in range(10)]


def test_call_service_exact_response(ros):
    service = roslibpy.Service(ros, '/add_two_ints', 'example_interfaces/srv/AddTwoInts')
    assert dict(service.call(roslibpy.ServiceRequest({'a': 40, 'b': 2}), timeout=5)) == {'sum': 42}
    big = 2**53 + 1   # int64 survives JSON exactly on the Python side
    assert service.call(roslibpy.ServiceRequest({'a': big, 'b': 1}), timeout=5)['sum'] == big + 1


def test_call_service_failure_is_result_false(ros):
    service = roslibpy.Service(ros, '/add_two_ints', 'example_interfaces/srv/AddTwoInts')
    errors = []
    done = threading.Event()
    service.call(roslibpy.ServiceRequest({'a': 'x'}), lambda r: done.set(),
                 lambda e: (errors.append(e), done.set()))
    assert done.wait(5)
    assert errors and "'args.a'" in errors[0]


def test_advertise_service_and_its_duplicate(ros, gateway):
    server = roslibpy.Service(ros, '/rg_test/add', 'example_interfaces/srv/AddTwoInts')

    def handler(request, response):
        response['sum'] = request['a'] + request['b']
        return True

    server.advertise(handler)
    wait_for(lambda: '/rg_test/add' in ros.get_services())
    other = roslibpy.Ros(gateway.host, gateway.port)
    other.run(timeout=10)
    try:
        caller = roslibpy.Service(other, '/rg_test/add', 'example_interfaces/srv/AddTwoInts')
        assert caller.call(roslibpy.ServiceRequest({'a': 3, 'b': 4}), timeout=5)['sum'] == 7

        # a second server for the same name replaces the first, as in rosbridge
        duplicate = roslibpy.Service(other, '/rg_test/add', 'example_interfaces/srv/AddTwoInts')

        def doubled(request, response):
            response['sum'] = 2 * (request['a'] + request['b'])
            return True

        duplicate.advertise(doubled)
        wait_for(lambda: caller.call(roslibpy.ServiceRequest({'a': 3, 'b': 4}), timeout=5)['sum'] == 14)
        assert ros.get_services().count('/rg_test/add') == 1
    finally:
        other.close()
    # the replacing client left: the service is gone, not hanging
    wait_for(lambda: '/rg_test/add' not in ros.get_services())


def test_send_action_goal_fibonacci_feedback_and_result(ros):
    client = roslibpy.ActionClient(ros, '/fibonacci', 'example_interfaces/action/Fibonacci')
    results, feedback = [], []
    goal_id = client.send_goal(roslibpy.Goal({'order': 6}), results.append, feedback.append, results.append)
    client.wait_goal(goal_id, timeout=10)
    assert results[0]['status'] == roslibpy.GoalStatus.SUCCEEDED
    assert results[0]['values'] == {'sequence': [0, 1, 1, 2, 3, 5, 8]}
    assert [f['sequence'] for f in feedback][-1] == [0, 1, 1, 2, 3, 5, 8]
    assert len(feedback) >= 5


def test_cancel_action_goal(ros, gateway):
    client = roslibpy.ActionClient(ros, '/fibonacci', 'example_interfaces/action/Fibonacci')
    result = cancelled(client, {'order': 40}, after_feedback=2, timeout=10)
    assert len(result['values']['sequence']) < 41


def test_multiple_subscribers(ros, gateway):
    others = [roslibpy.Ros(gateway.host, gateway.port) for _ in range(3)]
    for o in others:
        o.run(timeout=10)
    try:
        inboxes = []
        for o in others:
            box = []
            roslibpy.Topic(o, '/multi', 'std_msgs/msg/Int32').subscribe(box.append)
            inboxes.append(box)
        pub = roslibpy.Topic(ros, '/multi', 'std_msgs/msg/Int32')
        pub.advertise()
        sent = iter(range(10**6))
        wait_for(lambda: _published_until_all(pub, inboxes, next(sent)))
        for box in inboxes:
            values = [m['data'] for m in box]
            assert values == sorted(values)
    finally:
        for o in others:
            o.close()


def _published_until_all(pub, inboxes, value: int) -> bool:
    pub.publish(roslibpy.Message({'data': value}))
    time.sleep(0.02)
    return all(inboxes)


def test_latched_topic_reaches_late_subscribers(ros, gateway):
    pub = roslibpy.Topic(ros, '/latched/state', 'std_msgs/msg/String', latch=True)
    pub.advertise()
    pub.publish(roslibpy.Message({'data': 'ready'}))
    wait_for(lambda: '/latched/state' in ros.get_topics())
    for _ in range(2):   # the first late subscriber creates the shared subscription, the second joins it
        late = roslibpy.Ros(gateway.host, gateway.port)
        late.run(timeout=10)
        try:
            got = []
            roslibpy.Topic(late, '/latched/state', 'std_msgs/msg/String').subscribe(got.append)
            wait_for(lambda: got)
            assert got[0] == {'data': 'ready'}
        finally:
            late.close()


def test_rosapi_listings_and_details(ros):
    assert '/add_two_ints' in ros.get_services()
    assert ros.get_service_type('/add_two_ints') == 'example_interfaces/srv/AddTwoInts'
    servers = roslibpy.Service(ros, '/rosapi/action_servers', 'rosapi_msgs/srv/GetActionServers')
    assert '/fibonacci' in servers.call(roslibpy.ServiceRequest({}), timeout=5)['action_servers']
    assert '/rosapi' in ros.get_nodes()
    details = ros.get_service_request_details('example_interfaces/srv/AddTwoInts')
    assert details['typedefs'][0]['fieldnames'] == ['a', 'b']
    assert details['typedefs'][0]['fieldtypes'] == ['int64', 'int64']
    msg = ros.get_message_details('geometry_msgs/msg/Twist')['typedefs']
    assert [t['type'] for t in msg] == ['geometry_msgs/Twist', 'geometry_msgs/Vector3']


def test_rosapi_hidden_action_names_only_when_named(ros):
    """/fibonacci's hidden services and topics: out of the listings and a node's details, as ROS 2's
    tools leave them out unless asked; answered when named; described as ROS 2 types them."""
    hidden = '/fibonacci/_action/'
    assert not [n for n in ros.get_services() if hidden in n]
    assert not [n for n in ros.get_topics() if hidden in n]
    details = roslibpy.Service(ros, '/rosapi/node_details', 'rosapi_msgs/srv/NodeDetails').call(
        roslibpy.ServiceRequest({'node': '/fibonacci_action_server'}), timeout=5)
    assert not [n for kind in ('services', 'publishing') for n in details[kind] if hidden in n], details
    assert ros.get_service_type(hidden + 'get_result') == 'example_interfaces/action/Fibonacci_GetResult'
    assert ros.get_topic_type(hidden + 'feedback') == 'example_interfaces/action/Fibonacci_FeedbackMessage'
    publishers = roslibpy.Service(ros, '/rosapi/publishers', 'rosapi_msgs/srv/Publishers').call(
        roslibpy.ServiceRequest({'topic': hidden + 'status'}), timeout=5)['publishers']
    assert publishers == ['/fibonacci_action_server']
    request = ros.get_service_request_details('example_interfaces/action/Fibonacci_SendGoal')['typedefs']
    assert [(t['type'], t['fieldnames']) for t in request][:2] == [
        ('example_interfaces/Fibonacci_SendGoal_Request', ['goal_id', 'goal']),
        ('unique_identifier_msgs/UUID', ['uuid'])]


def test_a_goal_sent_through_the_hidden_send_goal_is_canceled_when_its_client_disconnects(ros, gateway):
    """As its send_action_goal goals are: a robot under a program stops when the connection drops."""
    goal_id = list(uuid.uuid4().bytes)
    with client(gateway) as sender:
        sent = roslibpy.Service(sender, '/fibonacci/_action/send_goal', '').call(
            roslibpy.ServiceRequest({'goal_id': {'uuid': goal_id}, 'goal': {'order': 46}}), timeout=5)
        assert sent['accepted'] is True
    result = roslibpy.Service(ros, '/fibonacci/_action/get_result', '').call(
        roslibpy.ServiceRequest({'goal_id': {'uuid': goal_id}}), timeout=10)
    assert result['status'] == 5 and len(result['result']['sequence']) < 47   # CANCELED, before its end


def test_params_through_rosapi(ros):
    names = ros.get_params()
    assert '/fibonacci_action_server:step_interval' in names
    param = roslibpy.Param(ros, '/fibonacci_action_server:step_interval')
    assert param.get(timeout=5) == 0.05
    param.set(0.04, timeout=5)
    assert param.get(timeout=5) == 0.04
    param.set(0.05, timeout=5)


def test_rapid_disconnect_smoke(gateway):
    for i in range(20):
        client = roslibpy.Ros(gateway.host, gateway.port)
        client.run(timeout=10)
        topic = roslibpy.Topic(client, f'/rapid/{i % 3}', 'std_msgs/msg/String')
        topic.subscribe(lambda m: None)
        topic.advertise()
        topic.publish(roslibpy.Message({'data': 'x'}))
        client.close()
    survivor = roslibpy.Ros(gateway.host, gateway.port)
    survivor.run(timeout=10)
    try:
        service = roslibpy.Service(survivor, '/add_two_ints', 'example_interfaces/srv/AddTwoInts')
        assert service.call(roslibpy.ServiceRequest({'a': 1, 'b': 1}), timeout=5)['sum'] == 2
    finally:
        survivor.close()
    assert gateway.alive


def test_client_count_and_connected_clients(start_gateway):
    gw = start_gateway('--robot', 'none')   # its own gateway: no other test's clients come and go
    ros = roslibpy.Ros(gw.host, gw.port)
    ros.run(timeout=10)
    try:
        counts, clients = [], []
        roslibpy.Topic(ros, '/client_count', 'std_msgs/msg/Int32').subscribe(counts.append)
        roslibpy.Topic(ros, '/connected_clients', 'rosbridge_msgs/msg/ConnectedClients').subscribe(clients.append)
        wait_for(lambda: counts and counts[-1]['data'] == 1 and clients and len(clients[-1]['clients']) == 1)
        other = roslibpy.Ros(gw.host, gw.port)
        other.run(timeout=10)
        try:
            wait_for(lambda: counts[-1]['data'] == 2 and len(clients[-1]['clients']) == 2)
            assert all(c['ip_address'] == '127.0.0.1' for c in clients[-1]['clients'])
        finally:
            other.close()
        wait_for(lambda: counts[-1]['data'] == 1 and len(clients[-1]['clients']) == 1)
    finally:
        ros.close()


def test_a_client_serving_the_demos_add_two_ints_takes_it_over_until_it_goes(ros, gateway):
    """The sim's demo /add_two_ints steps aside for a client that serves the name (the ROS 2
    tutorial's server, run in the IDE page) and answers again once that client's service goes."""
    def add_and_mark(request, response):
        response['sum'] = request['a'] + request['b'] + 1000
        return True

    with client(gateway) as server:
        mine = roslibpy.Service(server, '/add_two_ints', 'example_interfaces/srv/AddTwoInts')
        mine.advertise(add_and_mark)
        caller = roslibpy.Service(ros, '/add_two_ints', 'example_interfaces/srv/AddTwoInts')

        def answer():
            try:
                return caller.call(roslibpy.ServiceRequest({'a': 1, 'b': 2}), timeout=5)['sum']
            except roslibpy.core.ServiceException:   # a call that met the change of server
                return None
        wait_for(lambda: answer() == 1003, what="the client's server answering")
        mine.unadvertise()
        wait_for(lambda: answer() == 3, what='the demo answering again')
