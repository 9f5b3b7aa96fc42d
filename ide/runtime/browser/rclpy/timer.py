"""rclpy.timer for Python in the IDE page: the executor calls it when its time comes."""

import time

from rclpy.clock import Clock

S_TO_NS = 1000 * 1000 * 1000


class Timer:
    def __init__(self, callback, callback_group, timer_period_ns, clock=None, *, context=None, autostart=True):
        self.callback = callback
        self.callback_group = callback_group
        self._period_ns = int(timer_period_ns)
        self._clock = clock or Clock()
        self._canceled = not autostart
        self._last = time.monotonic_ns()
        self._next = self._last + self._period_ns

    @property
    def timer_period_ns(self):
        return self._period_ns

    @timer_period_ns.setter
    def timer_period_ns(self, value):
        self._period_ns = int(value)
        self.reset()

    @property
    def clock(self):
        return self._clock

    @property
    def handle(self):
        return self

    def is_ready(self):
        return not self._canceled and time.monotonic_ns() >= self._next

    def is_canceled(self):
        return self._canceled

    def cancel(self):
        self._canceled = True

    def reset(self):
        self._canceled = False
        self._last = time.monotonic_ns()
        self._next = self._last + self._period_ns

    def time_since_last_call(self):
        return time.monotonic_ns() - self._last

    def time_until_next_call(self):
        if self._canceled:
            return None
        return self._next - time.monotonic_ns()

    def _take(self):
        now = time.monotonic_ns()
        self._last = now
        self._next += self._period_ns
        if self._next <= now:               # late (a long callback): the next call a period from now
            self._next = now + self._period_ns
        return self.callback

    def destroy(self):
        self._canceled = True


class Rate:
    """node.create_rate(hz): rate.sleep() keeps a loop at hz (the page's sleep lets messages in)."""

    def __init__(self, frequency):
        self._period = 1.0 / frequency
        self._next = time.monotonic() + self._period

    def sleep(self):
        now = time.monotonic()
        if self._next > now:
            time.sleep(self._next - now)
        self._next = max(self._next + self._period, time.monotonic())

    def destroy(self):
        pass
