"""A station's names besides its commands, under ``--exclusive-control``: its holder's too.

The driver lease (``lease``) keeps a station's velocity commands for the client that holds it; a
station has more that moves or speaks for its robot. Tried as a class would: with the lease on, a
student who did not hold another's station teleported her turtle into the wall, killed, spawned
and reset it (services), and published poses on her pose topic that her subscribers took as her
robot's. So a station's services and actions (``name_refusal``, a keeper of ``rules.access``: asked
for every call, goal and advertise) and what is published on its other topics (``refusal``, at the
publish door, where the topic's type tells a command from the rest) are the holder's (any client
of the holder's person: her IDE, her teleop, her run), else the station's owner's (a walk-in's
where nobody owns it, as a command would take it), and the admins'; its services nobody's while
the teacher's stop holds (its topics stay its owner's: her page still reports its program). What
reads (``READS``: parameters' getters) and the gateway's own services (the stations' claims,
which know who calls) stay as they were.

``MOVERS``: the services that move a robot without driving it. A live exercise attempt refuses
them to everyone on its station (``rules.attempts``): a teleport passed a goal in a second.
"""

from __future__ import annotations

from collections.abc import Container

from .access import person_of
from .stations import person

KEPT = frozenset({'call', 'send_goal', 'advertise_service', 'advertise_action'})   # publish: at the door
READS = frozenset({'get_parameters', 'list_parameters', 'describe_parameters', 'get_parameter_types',
                   'get_type_description'})
MOVERS = frozenset({'teleport_absolute', 'teleport_relative', 'reset', 'spawn', 'kill', 'reset_world',
                    'reset_simulation', 'set_pose', 'set_entity_state', 'set_model_state', 'spawn_entity',
                    'delete_entity'})


def moves_robot(name: str) -> bool:
    """Whether service ``name`` (by its last part) moves a robot without driving it."""
    return name.rsplit('/', 1)[-1] in MOVERS


class StationNames:
    """The lease's keeper of its stations' other names."""

    def __init__(self, lease, *, own_services: Container[str]):
        """own_services: the names of the services the gateway answers itself (the stations' claims:
        they know who calls), none of them a station's."""
        self.lease, self.own_services = lease, own_services
        self._stations: tuple = ()
        self._groups: dict[str, str] = {}   # name -> its group, while the stations stay the same

    def _group(self, name: str) -> tuple[str, tuple]:
        """(name's group, the stations): remembered per name, as the door asks for every message
        (measured: the lookup over 30 stations was most of a non-command message's cost)."""
        stations = self.lease.stations()
        if stations is not self._stations:
            self._stations, self._groups = stations, {}
        group = self._groups.get(name)
        if group is None:
            if len(self._groups) > 4096:
                self._groups.clear()
            group = self._groups[name] = self.lease.group(name)
        return group, stations

    def name_refusal(self, asker, action: str, name: str) -> str | None:
        """Why ``asker`` may not call, send a goal to or advertise ``name`` (None: it may, or the
        name is no station's)."""
        if action not in KEPT or name in self.own_services or name.rsplit('/', 1)[-1] in READS:
            return None
        return self.refusal(asker, name, call=True)

    def refusal(self, asker, name: str, call: bool = False) -> str | None:
        """Why ``asker`` (a session, a sender or an Identity) may not use ``name`` of a station: a
        topic it publishes on, or (``call``) a service or action, which nobody calls while the
        teacher's stop holds (a teleport moves the robot; a program report does not)."""
        lease = self.lease
        group, stations = self._group(name)
        if group not in stations or lease.grants.exempt(asker):   # a signed-in admin
            return None
        holder = lease.holders.get(group)
        if holder is asker:
            return None
        key = person_of(asker) or person(asker)
        if holder is not None:
            if person(holder) == key:
                return None
            label = holder.attrs.get('name')
            driver = f'{label} (client {holder.id})' if label else f'client {holder.id}'
            return (f'{name}: {driver} is driving {group} (exclusive control), and its services and topics are '
                    f'theirs; {lease._way_out(asker, group)}')
        stopper = lease.halted.get(group) if call else None
        if stopper is not None:
            return f'{name}: {stopper} stopped {group}; send "take {group}" (the Take button) first'
        elsewhere = lease.elsewhere(group, key)
        if elsewhere is not None:
            return f'{name}: {elsewhere} is driving {group} through another gateway (exclusive control)'
        owner = lease.owners.owner(group)
        if owner is not None:
            return None if owner.person == key else (
                f'{name}: {group} is {owner.name}\'s station; press "Claim a robot" for your own, or ask the teacher')
        why = lease._walk_in_refusal(group, key)
        return f'{name}: {why}' if why is not None else None
