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
    group.add_argument('--robot', action='append', choices=KINDS, default=None,
                       help='robot to simulate; repeat for several (default: turtlesim)')
    group.add_argument('--world', default='arena', metavar='NAME|PATH',
                       help="the rover's world: arena, maze or a world .json file (default: arena)")
    group.add_argument('--twist-stamped', action='store_true',
                       help="the rover's cmd_vel is geometry_msgs/msg/TwistStamped instead of Twist")
    group.add_argument('--fleet', type=int, default=0, metavar='N',
                       help='N namespaced stations /s01../sNN, each with its own robots; '
                            'people claim one with the /fleet/claim service')
    group.add_argument('--sim-speed', type=float, default=1.0, metavar='F',
                       help='simulation speed factor, for tests (default: 1.0, real time)')


def specs_from_args(args) -> tuple:
    """Robot specs for SimBackend(robots=...). Exits with a message for a bad world or option."""
    kinds = tuple(dict.fromkeys(k for k in (args.robot or ['turtlesim']) if k != 'none'))
    if not kinds:
        return ()
    if not args.sim_speed > 0:
        raise SystemExit('rosgate: --sim-speed must be positive')
    if not 0 <= args.fleet <= 999:
        raise SystemExit('rosgate: --fleet must be between 0 and 999')
    world = None
    if 'rover' in kinds:
        try:
            world = World.load(args.world)
        except WorldError as e:
            raise SystemExit(f'rosgate: {e}') from None
        if world.clearance(*world.start[:2]) < ROVER_RADIUS:
            raise SystemExit(f'rosgate: the start of world {world.name!r} is inside or too close to a wall')
    options = {'speed': args.sim_speed, 'twist_stamped': args.twist_stamped}

    def station(namespace: str):
        async def spec(graph):
            return Station(graph, namespace, kinds, world, **options)
        return spec

    if not args.fleet:
        return (station('/'),)
    width = max(2, len(str(args.fleet)))
    namespaces = [f'/s{i:0{width}d}' for i in range(1, args.fleet + 1)]

    async def fleet(graph):
        return Fleet(graph, namespaces)

    return (*(station(ns) for ns in namespaces), fleet)


__all__ = ['add_arguments', 'specs_from_args']
