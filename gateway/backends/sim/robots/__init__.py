"""Simulated robots of the sim backend, and the command-line options that choose them.

Options (added by ``add_arguments``):
  --robot {turtlesim,rover,none}   repeatable; default turtlesim. Each kind once per station.
  --world NAME|PATH                the rover's world: ``arena``, ``maze`` or a JSON file (world.py).
  --twist-stamped                  the rover's ``cmd_vel`` is geometry_msgs/msg/TwistStamped.
  --fleet N                        N stations ``/s01`` .. ``/sNN``, each its own world and robots,
                                   handed out by the gateway (``/fleet/claim``).
  --sim-speed F                    test-only: simulated seconds per real second (default 1.0).

World view: every station publishes ``world/markers`` (visualization_msgs/msg/MarkerArray,
latched, frame "world", metres) as described in markers.py.
"""

from __future__ import annotations

import argparse

from .fleet import Fleet, Station
from .rover import RADIUS as ROVER_RADIUS
from .world import World, WorldError

KINDS = ('turtlesim', 'rover', 'none')


def add_arguments(parser: argparse.ArgumentParser) -> None:
    group = parser.add_argument_group('simulated robots (sim backend)')
    group.add_argument('--robot', dest='sim.robot', action='append', choices=KINDS,
                       help='robot to simulate; repeat for several (default: turtlesim)')
    group.add_argument('--world', dest='sim.world', metavar='NAME|PATH',
                       help="the rover's world: arena, maze or a world .json file (default: arena)")
    group.add_argument('--twist-stamped', dest='sim.twist_stamped', action='store_true',
                       help="the rover's cmd_vel is geometry_msgs/msg/TwistStamped instead of Twist")
    group.add_argument('--fleet', dest='sim.fleet', type=int, metavar='N',
                       help='N namespaced stations /s01../sNN, each with its own robots; '
                            'people claim one with the /fleet/claim service')
    group.add_argument('--sim-speed', dest='sim.sim_speed', type=float, metavar='F',
                       help='simulation speed factor, for tests (default: 1.0, real time)')


def specs_from(sim) -> tuple:
    """Robot specs for SimBackend(robots=...) from the settings' ``sim`` group. A bad world or
    option is a ValueError naming its flag (the CLI refuses to start with it)."""
    kinds = tuple(dict.fromkeys(k for k in (sim.robot or ['turtlesim']) if k != 'none'))
    if not kinds:
        return ()
    if not sim.sim_speed > 0:
        raise ValueError('--sim-speed: must be positive')
    if not 0 <= sim.fleet <= 999:
        raise ValueError('--fleet: must be between 0 and 999')
    world = None
    if 'rover' in kinds:
        try:
            world = World.load(sim.world)
        except WorldError as e:
            raise ValueError(f'--world: {e}') from None
        if world.clearance(*world.start[:2]) < ROVER_RADIUS:
            raise ValueError(f'--world: the start of world {world.name!r} is inside or too close to a wall')
    options = {'speed': sim.sim_speed, 'twist_stamped': sim.twist_stamped}

    def station(namespace: str):
        async def spec(graph):
            return Station(graph, namespace, kinds, world, **options)
        return spec

    if not sim.fleet:
        return (station('/'),)
    width = max(2, len(str(sim.fleet)))
    namespaces = [f'/s{i:0{width}d}' for i in range(1, sim.fleet + 1)]

    async def fleet(graph):
        return Fleet(graph, namespaces)

    return (*(station(ns) for ns in namespaces), fleet)


__all__ = ['add_arguments', 'specs_from']
