"""rclpy.task (Future, Task) for Python in the IDE page, as rclpy's: a coroutine callback is a
Task the executor steps; ``await future`` yields until the future is done."""

import inspect


class Future:
    """Represents the outcome of a task in the future."""

    def __init__(self, *, executor=None):
        self._state = "pending"
        self._result = None
        self._exception = None
        self._exception_fetched = False
        self._callbacks = []
        self._executor = executor

    def __await__(self):
        while self._state == "pending":
            yield self
        return self.result()

    def cancel(self):
        if not self.done():
            self._state = "cancelled"
            self._schedule_or_invoke_done_callbacks()

    def cancelled(self):
        return self._state == "cancelled"

    def done(self):
        return self._state != "pending"

    def result(self):
        if self._exception is not None:
            self._exception_fetched = True
            raise self._exception
        return self._result

    def exception(self):
        self._exception_fetched = True
        return self._exception

    def set_result(self, result):
        self._state = "finished"
        self._result = result
        self._schedule_or_invoke_done_callbacks()

    def set_exception(self, exception):
        self._state = "finished"
        self._exception = exception
        self._exception_fetched = False
        self._schedule_or_invoke_done_callbacks()

    def _schedule_or_invoke_done_callbacks(self):
        callbacks, self._callbacks = self._callbacks, []
        executor = self._executor
        for callback in callbacks:
            if executor is not None:
                executor.create_task(callback, self)
            else:
                callback(self)

    def _set_executor(self, executor):
        self._executor = executor

    def add_done_callback(self, callback):
        if self.done():
            if self._executor is not None:
                self._executor.create_task(callback, self)
            else:
                callback(self)
        else:
            self._callbacks.append(callback)

    def remove_done_callback(self, callback):
        try:
            self._callbacks.remove(callback)
            return True
        except ValueError:
            return False


class Task(Future):
    """A function or coroutine run by an executor; it is done when the handler returns."""

    def __init__(self, handler, args=None, kwargs=None, executor=None):
        super().__init__(executor=executor)
        self._handler = handler
        self._args = args or ()
        self._kwargs = kwargs or {}
        self._executing = False
        self._waiting_on = None          # the future a coroutine awaits
        if inspect.iscoroutine(handler):
            self._coroutine = handler
        elif inspect.iscoroutinefunction(handler):
            self._coroutine = handler(*self._args, **self._kwargs)
        else:
            self._coroutine = None

    def ready(self):
        """True when a step would make progress (not waiting on a future that is not done)."""
        return not self.done() and not self._executing and (self._waiting_on is None or self._waiting_on.done())

    def __call__(self):
        if self.done() or self._executing:
            return
        self._executing = True
        try:
            if self._coroutine is None:
                result = self._handler(*self._args, **self._kwargs)
                if inspect.iscoroutine(result):   # a function that returned a coroutine
                    self._coroutine = result
                else:
                    self.set_result(result)
                    return
            try:
                awaited = self._coroutine.send(None)
            except StopIteration as e:
                self.set_result(e.value)
                return
            self._waiting_on = awaited if isinstance(awaited, Future) else None
        except BaseException as e:   # noqa: BLE001: the task holds it; spin raises it
            self.set_exception(e)
        finally:
            self._executing = False

    def executing(self):
        return self._executing
