"""A block program that serves a service and an action (the server blocks), and the roslibpy checks
that it answers: used in the browser (JavaScript), the roslibpy script and the ROS 2 node."""

from __future__ import annotations

import threading

import roslibpy

from tests.support.wait import wait_for

ADD, COUNT, TICKS = '/add_served', '/count_served', '/served_ticks'
# the adder's type and its fields (a, b, sum); where example_interfaces is not installed (the
# Jazzy wheels) test_msgs stands in, as in tests/backends/rclpy_nodes.py
ADDERS = {'example_interfaces/srv/AddTwoInts': ('a', 'b', 'sum'),
          'test_msgs/srv/BasicTypes': ('int64_value', 'int32_value', 'int64_value')}


def _num(n):
    return {'shadow': {'type': 'math_number', 'fields': {'NUM': n}}}


def _field(name, var):
    return {'block': {'type': 'ros_field', 'fields': {'FIELD': name},
                      'inputs': {'OBJ': {'block': {'type': 'variables_get', 'fields': {'VAR': {'id': var}}}}}}}


def _message(type_, fields: dict):
    """A ros_message block: {field: (ROS type, array?, input)}."""
    return {'block': {'type': 'ros_message', 'fields': {'TYPE': type_},
                      'inputs': {f'F_{k}': v for k, (_, _, v) in fields.items()},
                      'extraState': {'kind': 'msg', 'type': type_, 'fields': [
                          {'name': k, 'type': t, 'array': 0 if arr else -1} for k, (t, arr, _) in fields.items()]}}}


def _list(*items):
    return {'block': {'type': 'lists_create_with', 'extraState': {'itemCount': len(items)},
                      'inputs': {f'ADD{i}': item for i, item in enumerate(items)}}}


def program(add_type: str = 'example_interfaces/srv/AddTwoInts',
            count_type: str = 'example_interfaces/action/Fibonacci') -> dict:
    """/add_served answers a + b after a 0.2 s sleep (its wait holds up nothing else); /count_served
    sends feedback [1], [2] ... [order] (0.05 s apart) and the result [order, 10 * order]; every
    0.1 s the program publishes 'tick' on /served_ticks."""
    a, b, total = ADDERS[add_type]
    return _program(add_type, count_type, a, b, total)


def _program(add_type, count_type, a, b, total):
    return {
    'format': 'rosgate-program', 'version': 1, 'name': 'served', 'robot': 'turtlesim', 'blocks': [],
    'workspace': {'blocks': {'languageVersion': 0, 'blocks': [
        {'type': 'ros_serve_service', 'x': 20, 'y': 20,
         'fields': {'SERVICE': ADD, 'TYPE': add_type, 'VAR': {'id': 'var-request'}},
         'inputs': {
             'DO': {'block': {'type': 'ros_sleep', 'inputs': {'SECONDS': _num(0.2)}}},
             'RESPONSE': _message(add_type, {total: ('int64', False, {'block': {
                 'type': 'math_arithmetic', 'fields': {'OP': 'ADD'},
                 'inputs': {'A': _field(a, 'var-request'), 'B': _field(b, 'var-request')}}})})}},
        {'type': 'ros_every', 'x': 400, 'y': 20, 'inputs': {
            'SECONDS': _num(0.1),
            'DO': {'block': {'type': 'ros_publish', 'fields': {'TOPIC': TICKS, 'TYPE': 'std_msgs/msg/String'},
                             'inputs': {'MSG': _message('std_msgs/msg/String', {'data': ('string', False, {
                                 'shadow': {'type': 'text', 'fields': {'TEXT': 'tick'}}})})}}}}},
        {'type': 'ros_serve_action', 'x': 20, 'y': 300,
         'fields': {'ACTION': COUNT, 'TYPE': count_type, 'VAR': {'id': 'var-goal'}},
         'inputs': {
             'DO': {'block': {'type': 'controls_for', 'fields': {'VAR': {'id': 'var-i'}},
                              'inputs': {'FROM': _num(1), 'TO': _field('order', 'var-goal'), 'BY': _num(1),
                                         'DO': {'block': {'type': 'ros_action_feedback', 'inputs': {'VALUE': _message(
                                             count_type, {'sequence': ('int32', True, _list(
                                                 {'block': {'type': 'variables_get', 'fields': {'VAR': {'id': 'var-i'}}}}))})},
                                             'next': {'block': {'type': 'ros_sleep', 'inputs': {'SECONDS': _num(0.05)}}}}}}}},
             'RESULT': _message(count_type, {'sequence': ('int32', True, _list(
                 _field('order', 'var-goal'),
                 {'block': {'type': 'math_arithmetic', 'fields': {'OP': 'MULTIPLY'},
                            'inputs': {'A': _num(10), 'B': _field('order', 'var-goal')}}}))})}},
    ]}, 'variables': [{'name': 'request', 'id': 'var-request'}, {'name': 'goal', 'id': 'var-goal'},
                      {'name': 'i', 'id': 'var-i'}]},
}


def _answers(service, a, b, total) -> bool:
    try:
        return service.call(roslibpy.ServiceRequest({a: 1, b: 1}), timeout=5)[total] == 2
    except Exception:   # roslibpy's ServiceException: no server (yet)
        return False


def check_served(ros: roslibpy.Ros, add_type: str = 'example_interfaces/srv/AddTwoInts',
                 count_type: str = 'example_interfaces/action/Fibonacci', timeout: float = 20.0) -> None:
    """The program's service answers 2 + 40 (twice at once: 0.2 s each, both within 0.2 s of the
    other) and its action counts to 3 with feedback, through the roslibpy client ``ros``."""
    ticks = []
    topic = roslibpy.Topic(ros, TICKS, 'std_msgs/msg/String')
    topic.subscribe(lambda m: ticks.append(m['data']))
    a, b, total = ADDERS[add_type]
    service = roslibpy.Service(ros, ADD, add_type)
    # the program advertises once it has started: the first call may find no server yet
    wait_for(lambda: _answers(service, a, b, total), timeout, 0.1)
    answers, errors = [], []
    calls = [threading.Thread(target=lambda: answers.append(service.call(roslibpy.ServiceRequest({a: 2, b: 40}),
                                                                         timeout=timeout)[total])) for _ in range(2)]
    for c in calls:
        c.start()
    for c in calls:
        c.join(timeout)
    assert answers == [42, 42], (answers, errors)

    client = roslibpy.ActionClient(ros, COUNT, count_type)
    done = threading.Event()
    feedback, result = [], {}

    def on_result(r):
        result.update(r)
        done.set()

    def on_error(e):
        result['error'] = e
        done.set()

    client.send_goal({'order': 3}, on_result, lambda f: feedback.append(list(f['sequence'])), on_error)
    assert done.wait(timeout), 'no result'
    assert 'error' not in result, result
    assert int(getattr(result.get('status'), 'value', result.get('status'))) == 4, result
    assert list(result['values']['sequence']) == [3, 30], result
    assert feedback == [[1], [2], [3]], feedback
    wait_for(lambda: len(ticks) >= 3, timeout, 0.05, "3 ticks of 'every 0.1 s'")
    topic.unsubscribe()
    assert set(ticks) == {'tick'}, ticks
