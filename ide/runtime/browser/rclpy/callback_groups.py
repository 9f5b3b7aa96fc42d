"""rclpy.callback_groups for Python in the IDE page: which callbacks may run while another of the
group waits (an ``async def`` callback awaiting a future), as rclpy's executors decide it."""


class CallbackGroup:
    def __init__(self):
        self.entities = set()

    def add_entity(self, entity):
        self.entities.add(entity)

    def has_entity(self, entity):
        return entity in self.entities

    def can_execute(self, entity):
        raise NotImplementedError()

    def beginning_execution(self, entity):
        raise NotImplementedError()

    def ending_execution(self, entity):
        raise NotImplementedError()


class ReentrantCallbackGroup(CallbackGroup):
    """Callbacks of this group may run side by side."""

    def can_execute(self, entity):
        return True

    def beginning_execution(self, entity):
        return True

    def ending_execution(self, entity):
        pass


class MutuallyExclusiveCallbackGroup(CallbackGroup):
    """One callback of this group at a time (a node's default group)."""

    def __init__(self):
        super().__init__()
        self._active_entity = None

    def can_execute(self, entity):
        return self._active_entity is None

    def beginning_execution(self, entity):
        if self._active_entity is None:
            self._active_entity = entity
            return True
        return False

    def ending_execution(self, entity):
        self._active_entity = None
