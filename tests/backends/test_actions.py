"""Actions both ways: goals to the Fibonacci server, and an action served through the backend."""

from __future__ import annotations

import asyncio
import functools
import time
import uuid

import pytest

from gateway.backends.base import (
    SERVER_WAIT, STATUS_ABORTED, STATUS_CANCELED, STATUS_SUCCEEDED, STATUS_UNKNOWN, ActionServerCallbacks,
    BackendError,
)

from tests.support.wait import until

pytestmark = pytest.mark.asyncio(loop_scope='session')


async def test_fibonacci_with_feedback(world):
    feedback: list = []
    goal = await world.backend.send_goal('/fibonacci', world.fib_type, {'order': 5}, feedback.append)
    assert isinstance(goal.goal_id, str) and goal.goal_id
    result = await asyncio.wait_for(goal.result(), 10)
    assert result.status == STATUS_SUCCEEDED
    assert result.result == {'sequence': [0, 1, 1, 2, 3, 5]}
    await until(lambda: feedback and feedback[-1]['sequence'] == [0, 1, 1, 2, 3, 5], what='last feedback')
    assert feedback[0]['sequence'][:2] == [0, 1]


async def test_fibonacci_cancel(world):
    first = asyncio.Event()
    goal = await world.backend.send_goal('/fibonacci', world.fib_type, {'order': 46},
                                         lambda fb: first.set())
    await asyncio.wait_for(first.wait(), 5)
    await goal.cancel()
    result = await asyncio.wait_for(goal.result(), 10)
    assert result.status == STATUS_CANCELED
    assert len(result.result['sequence']) < 47


async def test_unknown_action(world):
    started = time.monotonic()
    with pytest.raises(BackendError, match='/no_such_action'):
        await world.backend.send_goal('/no_such_action', world.fib_type, {'order': 1}, None)
    assert SERVER_WAIT - 0.05 <= time.monotonic() - started < 4   # not the 5 s wait for a ready server: busy machines vary


async def test_an_action_server_that_appears_while_the_goal_waits_takes_it(world, topic):
    action = topic + '/late_fib'
    send = asyncio.ensure_future(world.backend.send_goal(action, world.fib_type, {'order': 4}, None))
    await asyncio.sleep(0)      # the goal is under way before the server exists
    assert not send.done()
    stop = world.late_server('action', action)
    try:
        goal = await asyncio.wait_for(send, 10)
        result = await asyncio.wait_for(goal.result(), 10)
        assert (result.status, result.result) == (STATUS_SUCCEEDED, {'sequence': [0, 1, 1, 2, 3]})
    finally:
        stop()


class Served:
    """ActionServerCallbacks recording what the backend hands over."""

    def __init__(self):
        self.goals: asyncio.Queue = asyncio.Queue()
        self.cancels: asyncio.Queue = asyncio.Queue()
        self.callbacks = ActionServerCallbacks(self.goals.put_nowait, self.cancels.put_nowait)


async def test_advertise_action(world, topic):
    backend, action, served = world.backend, topic + '/fib', Served()
    handle = backend.advertise_action(action, world.fib_type, served.callbacks)
    try:
        await until(lambda: action in dict(backend.actions()), what='action in graph')
        assert dict(backend.actions())[action] == world.fib_type
        feedback: list = []
        client_goal = await backend.send_goal(action, world.fib_type, {'order': 3}, feedback.append)
        server_goal = await asyncio.wait_for(served.goals.get(), 5)
        assert server_goal.request == {'order': 3}
        assert server_goal.goal_id == client_goal.goal_id
        server_goal.publish_feedback({'sequence': [0, 1]})
        await until(lambda: feedback, what='feedback relayed')
        assert feedback[0] == {'sequence': [0, 1]}
        server_goal.finish(STATUS_SUCCEEDED, {'sequence': [0, 1, 1, 2]})
        result = await asyncio.wait_for(client_goal.result(), 5)
        assert (result.status, result.result) == (STATUS_SUCCEEDED, {'sequence': [0, 1, 1, 2]})

        # a cancel reaches the server, which finishes the goal as canceled
        client_goal = await backend.send_goal(action, world.fib_type, {'order': 9}, None)
        server_goal = await asyncio.wait_for(served.goals.get(), 5)
        await client_goal.cancel()
        canceled = await asyncio.wait_for(served.cancels.get(), 5)
        assert canceled.goal_id == server_goal.goal_id
        server_goal.finish(STATUS_CANCELED, {'sequence': [0]})
        result = await asyncio.wait_for(client_goal.result(), 5)
        assert (result.status, result.result) == (STATUS_CANCELED, {'sequence': [0]})

        # a goal still running when the server goes is aborted
        client_goal = await backend.send_goal(action, world.fib_type, {'order': 2}, None)
        await asyncio.wait_for(served.goals.get(), 5)
    finally:
        handle.destroy()
    result = await asyncio.wait_for(client_goal.result(), 5)
    assert result.status == STATUS_ABORTED
    await until(lambda: action not in dict(backend.actions()), what='action gone')

    # the name is free again at once
    again = Served()
    handle = backend.advertise_action(action, world.fib_type, again.callbacks)
    try:
        client_goal = await backend.send_goal(action, world.fib_type, {'order': 1}, None)
        (await asyncio.wait_for(again.goals.get(), 5)).finish(STATUS_SUCCEEDED, {'sequence': [0, 1]})
        result = await asyncio.wait_for(client_goal.result(), 5)
        assert (result.status, result.result) == (STATUS_SUCCEEDED, {'sequence': [0, 1]})
    finally:
        handle.destroy()


async def test_advertise_taken_action(world):
    with pytest.raises(BackendError, match='/fibonacci'):
        world.backend.advertise_action('/fibonacci', world.fib_type, Served().callbacks)


async def test_advertise_action_twice(world, topic):
    backend, action = world.backend, topic + '/fib'
    handle = backend.advertise_action(action, world.fib_type, Served().callbacks)
    try:
        with pytest.raises(BackendError):
            backend.advertise_action(action, world.fib_type, Served().callbacks)
    finally:
        handle.destroy()


# --- the hidden endpoints of an action server, as ROS 2 names and types them ----------------------

OTHER_FIB = 'action_tutorials_interfaces/action/Fibonacci'   # another package's Fibonacci
CANCEL = 'action_msgs/srv/CancelGoal'
ERROR_NONE, ERROR_UNKNOWN_GOAL_ID, ERROR_GOAL_TERMINATED = 0, 2, 3


def hidden_of(world, action: str) -> tuple[dict, dict]:
    """(services, topics) a ROS 2 action server ``action`` of the world's Fibonacci type has."""
    fib = world.fib_type
    return ({f'{action}/_action/send_goal': f'{fib}_SendGoal', f'{action}/_action/get_result': f'{fib}_GetResult',
             f'{action}/_action/cancel_goal': CANCEL},
            {f'{action}/_action/feedback': f'{fib}_FeedbackMessage',
             f'{action}/_action/status': 'action_msgs/msg/GoalStatusArray'})


async def check_hidden(world, action: str) -> None:
    backend = world.backend
    services, topics = hidden_of(world, action)
    await until(lambda: services.items() <= dict(backend.services(hidden=True)).items()
                and topics.items() <= dict(backend.topics(hidden=True)).items(), what='hidden endpoints')
    assert not services.keys() & dict(backend.services()).keys()   # listed only when asked
    assert not topics.keys() & dict(backend.topics()).keys()


def cancel_request(goal_id: bytes = bytes(16), sec: int = 0, nanosec: int = 0) -> dict:
    return {'goal_info': {'goal_id': {'uuid': goal_id}, 'stamp': {'sec': sec, 'nanosec': nanosec}}}


def canceling(response: dict) -> set[str]:
    return {str(uuid.UUID(bytes=bytes(g['goal_id']['uuid']))) for g in response['goals_canceling']}


async def running(world, order: int = 46):
    """A Fibonacci goal on /fibonacci, once its first feedback has come (it is executing)."""
    first = asyncio.Event()
    goal = await world.backend.send_goal('/fibonacci', world.fib_type, {'order': order}, lambda fb: first.set())
    await asyncio.wait_for(first.wait(), 5)
    return goal


async def test_an_action_server_has_the_hidden_services_and_topics_of_ros2(world):
    await check_hidden(world, '/fibonacci')


async def test_cancel_all_through_the_hidden_cancel_goal_service(world):
    """roslibjs's Action.cancelAllGoals(): a zero goal id and a zero stamp cancel every goal."""
    goals = [await running(world), await running(world)]
    response = await world.backend.call_service('/fibonacci/_action/cancel_goal', CANCEL, cancel_request(), 5)
    assert response['return_code'] == ERROR_NONE
    assert canceling(response) == {g.goal_id for g in goals}
    for goal in goals:
        result = await asyncio.wait_for(goal.result(), 10)
        assert result.status == STATUS_CANCELED and len(result.result['sequence']) < 47


async def test_cancel_goal_by_id_and_by_stamp_with_the_return_codes_of_rcl(world):
    backend = world.backend
    cancel = functools.partial(backend.call_service, '/fibonacci/_action/cancel_goal', CANCEL, timeout=5)
    older = await running(world)
    sec, nanosec = backend.now()     # after the older goal was accepted, before the newer one
    newer = await running(world)
    response = await cancel(cancel_request(sec=sec, nanosec=nanosec))   # goals accepted at or before
    assert (response['return_code'], canceling(response)) == (ERROR_NONE, {older.goal_id})
    assert (await asyncio.wait_for(older.result(), 10)).status == STATUS_CANCELED

    newer_id = uuid.UUID(newer.goal_id).bytes
    response = await cancel(cancel_request(newer_id))
    assert (response['return_code'], canceling(response)) == (ERROR_NONE, {newer.goal_id})
    assert (await asyncio.wait_for(newer.result(), 10)).status == STATUS_CANCELED
    response = await cancel(cancel_request(newer_id))
    assert (response['return_code'], response['goals_canceling']) == (ERROR_GOAL_TERMINATED, [])
    response = await cancel(cancel_request(uuid.uuid4().bytes))
    assert (response['return_code'], response['goals_canceling']) == (ERROR_UNKNOWN_GOAL_ID, [])
    response = await cancel(cancel_request())                            # nothing left to cancel
    assert (response['return_code'], response['goals_canceling']) == (ERROR_NONE, [])


async def test_a_goal_through_the_hidden_send_goal_and_get_result_services(world):
    backend, fib = world.backend, world.fib_type
    goal_id = uuid.uuid4().bytes
    sent = await backend.call_service('/fibonacci/_action/send_goal', f'{fib}_SendGoal',
                                      {'goal_id': {'uuid': goal_id}, 'goal': {'order': 4}}, 5)
    assert sent['accepted'] is True and sent['stamp']['sec'] > 0
    again = await backend.call_service('/fibonacci/_action/send_goal', f'{fib}_SendGoal',
                                       {'goal_id': {'uuid': goal_id}, 'goal': {'order': 4}}, 5)
    assert again['accepted'] is False          # a goal id the server tracks is refused
    result = await backend.call_service('/fibonacci/_action/get_result', f'{fib}_GetResult',
                                        {'goal_id': {'uuid': goal_id}}, 10)
    assert (result['status'], result['result']) == (STATUS_SUCCEEDED, {'sequence': [0, 1, 1, 2, 3]})
    unknown = await backend.call_service('/fibonacci/_action/get_result', f'{fib}_GetResult',
                                         {'goal_id': {'uuid': uuid.uuid4().bytes}}, 5)
    assert unknown['status'] == STATUS_UNKNOWN


async def test_the_hidden_feedback_and_status_topics_carry_a_goal(world):
    backend, fib = world.backend, world.fib_type
    feedback: list = []
    statuses: list = []
    handles = [backend.subscribe('/fibonacci/_action/feedback', f'{fib}_FeedbackMessage', feedback.append),
               backend.subscribe('/fibonacci/_action/status', 'action_msgs/msg/GoalStatusArray', statuses.append)]
    try:
        await until(lambda: backend.publishers('/fibonacci/_action/status')
                    and backend.subscribers('/fibonacci/_action/feedback'), what='subscriptions matched')
        goal = await backend.send_goal('/fibonacci', fib, {'order': 3}, None)
        assert (await asyncio.wait_for(goal.result(), 10)).status == STATUS_SUCCEEDED
        goal_id = uuid.UUID(goal.goal_id).bytes

        def final_status():
            return any(s['goal_info']['goal_id']['uuid'] == goal_id and s['status'] == STATUS_SUCCEEDED
                       for msg in statuses for s in msg['status_list'])
        await until(final_status, what='SUCCEEDED in the status topic')
        await until(lambda: any(m['goal_id']['uuid'] == goal_id and m['feedback']['sequence'] == [0, 1, 1, 2]
                                for m in feedback), what='the last feedback of the goal')
    finally:
        for handle in handles:
            handle.destroy()


async def test_a_goal_of_another_action_type_is_refused_naming_both_types(world):
    with pytest.raises(BackendError) as refused:
        await world.backend.send_goal('/fibonacci', OTHER_FIB, {'order': 3}, None)
    assert world.fib_type in str(refused.value) and OTHER_FIB in str(refused.value)


async def test_an_advertised_action_has_the_hidden_endpoints_and_a_cancel_all_reaches_it(world, topic):
    backend, action, served = world.backend, topic + '/fib', Served()
    handle = backend.advertise_action(action, world.fib_type, served.callbacks)
    try:
        await check_hidden(world, action)
        client_goal = await backend.send_goal(action, world.fib_type, {'order': 9}, None)
        server_goal = await asyncio.wait_for(served.goals.get(), 5)
        response = await backend.call_service(f'{action}/_action/cancel_goal', CANCEL, cancel_request(), 5)
        assert (response['return_code'], canceling(response)) == (ERROR_NONE, {client_goal.goal_id})
        assert (await asyncio.wait_for(served.cancels.get(), 5)).goal_id == server_goal.goal_id
        server_goal.finish(STATUS_CANCELED, {'sequence': [0]})
        result = await asyncio.wait_for(client_goal.result(), 5)
        assert (result.status, result.result) == (STATUS_CANCELED, {'sequence': [0]})
    finally:
        handle.destroy()
    await until(lambda: f'{action}/_action/cancel_goal' not in dict(backend.services(hidden=True)),
                what='hidden services gone with the server')
