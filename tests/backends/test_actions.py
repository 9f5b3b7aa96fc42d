"""Actions both ways: goals to the Fibonacci server, and an action served through the backend."""

from __future__ import annotations

import asyncio
import time

import pytest

from gateway.backends.base import (
    SERVER_WAIT, STATUS_ABORTED, STATUS_CANCELED, STATUS_SUCCEEDED, ActionServerCallbacks, BackendError,
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
