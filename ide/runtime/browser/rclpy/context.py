"""rclpy.context for Python in the IDE page: the one context of a run."""

from rclpy.exceptions import NotInitializedException


class Context:
    def __init__(self):
        self._initialized = False
        self._shut_down = False
        self._callbacks = []

    def init(self, args=None, *, initialize_logging=True, domain_id=None):
        if self._initialized and not self._shut_down:
            raise RuntimeError("Context.init() must only be called once")
        self._initialized = True
        self._shut_down = False
        return self

    def ok(self):
        return self._initialized and not self._shut_down

    def shutdown(self):
        if not self.ok():
            raise RuntimeError("Context must be initialized before it can be shutdown")
        self._shut_down = True
        callbacks, self._callbacks = self._callbacks, []
        for callback in callbacks:
            callback()

    def try_shutdown(self):
        if self.ok():
            self.shutdown()

    def on_shutdown(self, callback):
        if not callable(callback):
            raise TypeError("callback should be a callable, got {}".format(type(callback)))
        self._callbacks.append(callback)

    def get_domain_id(self):
        return 0

    def check(self):
        if not self._initialized:
            raise NotInitializedException()

    # with rclpy.init(): ... (rclpy's InitContextManager)
    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.try_shutdown()
        return False


_default = Context()


def default_context():
    return _default
