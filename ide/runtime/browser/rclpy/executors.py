"""rclpy.executors for Python in the IDE page: a single-threaded executor, as rclpy's
SingleThreadedExecutor runs its callbacks (one at a time, coroutine callbacks stepped as tasks,
a callback group's rule kept). MultiThreadedExecutor is the same here: the page has one thread,
so callbacks that would run side by side take turns at their awaits instead.

Waiting for work is where the gateway's messages come in (rclpy._engine.pump): it ends at the
next timer's time, when a message for the program arrives, or at the timeout.
"""

import time

from rclpy import _engine
from rclpy.context import default_context
from rclpy.task import Task


class ExternalShutdownException(Exception):
    """The context was shut down while an executor waited."""


class ShutdownException(Exception):
    """The executor was shut down."""


class TimeoutException(Exception):
    """spin_once_until_future_complete saw no work in time."""


class ConditionReachedException(Exception):
    pass


class Executor:
    def __init__(self, *, context=None):
        self._context = default_context() if context is None else context
        self._nodes = []
        self._tasks = []
        self._is_shutdown = False

    @property
    def context(self):
        return self._context

    def add_node(self, node):
        if node in self._nodes:
            return False
        self._nodes.append(node)
        node.executor = self
        return True

    def remove_node(self, node):
        if node in self._nodes:
            self._nodes.remove(node)

    def get_nodes(self):
        return list(self._nodes)

    def wake(self):
        pass

    def shutdown(self, timeout_sec=None):
        self._is_shutdown = True
        for node in list(self._nodes):
            self.remove_node(node)
        return True

    def create_task(self, callback, *args, **kwargs):
        task = Task(callback, args, kwargs, executor=self)
        self._tasks.append(task)
        return task

    # ---- spinning
    def spin(self):
        while self._context.ok() and not self._is_shutdown:
            self.spin_once()

    def spin_until_future_complete(self, future, timeout_sec=None):
        if isinstance(future, Task) and future not in self._tasks and not future.done():
            future._set_executor(self)
            self._tasks.append(future)
        if timeout_sec is None or timeout_sec < 0:
            while self._context.ok() and not future.done() and not self._is_shutdown:
                self.spin_once_until_future_complete(future)
            return
        end = time.monotonic() + timeout_sec
        while self._context.ok() and not future.done() and not self._is_shutdown:
            left = end - time.monotonic()
            if left <= 0:
                return
            self.spin_once_until_future_complete(future, left)

    def spin_once_until_future_complete(self, future, timeout_sec=None):
        self._spin_once(timeout_sec, until=future.done)

    def spin_once(self, timeout_sec=None):
        self._spin_once(timeout_sec)

    def _spin_once(self, timeout_sec, until=None):
        work = self._next_work()
        if work is None:
            end = None if timeout_sec is None or timeout_sec < 0 else time.monotonic() + timeout_sec
            engine = _engine.engine()
            heard = engine.wakeups
            while work is None and self._context.ok() and not self._is_shutdown:
                if until is not None and until():
                    return
                if engine.wakeups != heard:
                    return      # a reply completed a future: what rclpy's executor counts as a client's work
                left = None if end is None else end - time.monotonic()
                if left is not None and left <= 0:
                    return
                due = self._next_timer_in()
                if due is not None:
                    left = due if left is None else min(left, due)
                _engine.pump(left)
                work = self._next_work()
        if work is not None:
            work()

    # ---- what is ready
    def _next_timer_in(self):
        soonest = None
        for node in self._nodes:
            for timer in node._timers:
                if not timer.is_canceled():
                    left = timer.time_until_next_call() / 1e9
                    soonest = left if soonest is None else min(soonest, left)
        return None if soonest is None else max(0.0, soonest)

    def _next_work(self):
        self._tasks = [t for t in self._tasks if not t.done()]
        for task in self._tasks:
            if task.ready():
                return lambda task=task: self._step(task)
        for node in self._nodes:
            for timer in node._timers:
                if timer.is_ready() and timer.callback_group.can_execute(timer):
                    return lambda timer=timer: self._execute(timer, timer._take())
            for entity in node._subscriptions + node._services + node._action_servers:
                if entity._has_work() and entity.callback_group.can_execute(entity):
                    return lambda entity=entity: self._execute(entity, entity._take())
        return None

    def _execute(self, entity, job):
        """Runs job() (an entity's callback, maybe a coroutine) under its callback group's rule."""
        if job is None:
            return
        group = entity.callback_group
        if not group.beginning_execution(entity):
            return
        task = Task(job, executor=self)
        task._group = (group, entity)
        self._step(task)
        if not task.done():
            self._tasks.append(task)

    def _step(self, task):
        task()
        if task.done():
            group = getattr(task, "_group", None)
            if group is not None:
                group[0].ending_execution(group[1])
            if task.exception() is not None:
                raise task.exception()


class SingleThreadedExecutor(Executor):
    pass


class MultiThreadedExecutor(Executor):
    def __init__(self, num_threads=None, *, context=None):
        super().__init__(context=context)
        self._num_threads = num_threads or 1


class EventsExecutor(Executor):
    pass
