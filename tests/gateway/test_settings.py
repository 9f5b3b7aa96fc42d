"""One configuration: every flag is one field of ``gateway.settings.Settings`` with its one default,
and the start-up check refuses one way (a line naming the flags on stderr, exit status 2)."""

from __future__ import annotations

import logging
import subprocess
import sys

import pytest

from gateway.cli import build_parser, settings_from
from gateway.rules.hooks import Hook, Hooks
from gateway.settings import Settings, flat, from_flat
from tests.support.process import ROOT


def test_every_flag_is_one_field_and_every_field_a_flag():
    dests = {a.dest for a in build_parser()._actions if a.dest != 'help'}
    fields = set(flat(Settings()))
    assert dests - fields == set(), 'flags without a field'
    # package data, and the queue of a subscription that asks for none: not flags
    assert fields - dests == {'ide_dir', 'examples_dir', 'default_queue_length'}, 'fields without a flag'
    with pytest.raises(KeyError):
        from_flat({**flat(Settings()), 'security.no_such_flag': 1})


def test_the_defaults_are_the_fields():
    assert settings_from(build_parser().parse_args([])) == Settings()


def test_flags_land_in_their_groups():
    args = build_parser().parse_args(['--auth-backoff', '2', '--max-runs', '3', '--robot', 'rover', '--robot',
                                      'turtlesim', '--stop-types', 'a/msg/B, c/msg/D', '--booking', '--opcua', '0'])
    s = settings_from(args)
    assert (s.security.auth_backoff, s.runs.max_runs, s.lab.booking, s.twin.opcua) == (2.0, 3, True, 0)
    assert s.sim.robot == ('rover', 'turtlesim') and s.safety.stop_types == ('a/msg/B', 'c/msg/D')
    assert s.sim.sim_speed == Settings().sim.sim_speed


def refused(*flags: str, prelude: str = '') -> subprocess.CompletedProcess:
    code = f'{prelude}import sys; from gateway.cli import main; sys.exit(main(sys.argv[1:]))'
    return subprocess.run([sys.executable, '-c', code, '--port', '0', '--address', '127.0.0.1', *flags],
                          cwd=ROOT, capture_output=True, text=True, timeout=60)


@pytest.mark.parametrize('flags, prelude, said', [
    (['--trusted-runs'], '', 'rosgate: --trusted-runs: it is a kind of run: give --allow-runs too'),
    (['--opcua', '0', '--history', 'none'], '', 'rosgate: --opcua, --history: '),
    (['--opcua', '0'], 'import sys; sys.modules["asyncua"] = None; ',
     'rosgate: --opcua: it needs asyncua: pip install "rosgate[opcua]"'),
    (['--auth', '/no/such/tokens.toml'], '', 'rosgate: --auth: '),
    (['--trusted-proxies', 'not-an-address'], '', 'rosgate: --trusted-proxies: '),
    (['--sim-speed', '0'], '', 'rosgate: --sim-speed: must be positive'),
    (['--gauges', '/no/such/gauges.toml'], '', 'rosgate: --gauges: '),
    (['--gauges', str(ROOT / 'pyproject.toml')], '', "rosgate: --gauges: "),   # TOML, but not of limits
])
def test_a_refusal_names_the_flags_and_exits_2(flags, prelude, said):
    done = refused(*flags, prelude=prelude)
    assert done.returncode == 2, done.stderr[-2000:]
    assert said in done.stderr and done.stdout == '', done.stderr[-2000:]


def test_hooks_hear_every_event_in_order_and_a_failing_one_is_logged(caplog):
    heard = []

    class Broken(Hook):
        def on_close(self, who):
            raise RuntimeError('broken part')

    class Listening(Hook):
        def on_close(self, who):
            heard.append(('close', who))

        def on_slot_ended(self, station, person, why):
            heard.append(('slot', station, person, why))

    hooks = Hooks()
    with pytest.raises(TypeError):
        hooks.seal((Broken(), object()))
    hooks.close('before the seal')                # nobody hears it yet
    hooks.seal((Broken(), None, Listening()))     # None: a part not built (no --opcua ...)
    with pytest.raises(RuntimeError):
        hooks.seal((Listening(),))                # once
    with caplog.at_level(logging.ERROR, logger='rosgate'):
        hooks.close('a session')
        hooks.slot_ended('/s01', 'ann', 'ended')
        hooks.connect('a session', None)          # no part takes it: nothing happens
    assert heard == [('close', 'a session'), ('slot', '/s01', 'ann', 'ended')]
    assert 'on_close hook of Broken failed' in caplog.text and 'broken part' in caplog.text


async def test_the_rules_are_composed_in_their_documented_order(tmp_path):
    """The publish door: the runs' guard, the lease, safety; installed once, not assigned piecemeal."""
    from dataclasses import replace

    from gateway import rules
    from gateway.backends.sim import SimBackend
    from gateway.bridge.gateway import Gateway
    from gateway.runs import RunManager
    from gateway.settings import LabSettings, SafetySettings, StorageSettings

    backend = SimBackend(demo=False)
    await backend.start()
    settings = replace(Settings(), safety=SafetySettings(exclusive_control=True), lab=LabSettings(booking=True),
                       storage=StorageSettings(db_url=f'sqlite:///{tmp_path / "db.sqlite"}'))
    gateway = Gateway(settings, backend)
    runs = RunManager(settings, announce=gateway, graph=backend, rules=lambda: gateway.ruleset, allowed=False,
                      runs_dir=tmp_path)
    composed = rules.compose(gateway.rule_doors(), runs=runs)
    try:
        assert composed.publish == (runs.publish_hook, composed.lease.publish_hook, composed.reports.publish_hook,
                                    composed.safety.publish_hook)
        assert composed.policy.keepers == (composed.reports.keeper, composed.lease.names.name_refusal)
        assert composed.guards == ()
        assert composed.hooks == (composed.stations, composed.lease, composed.safety, composed.slots, runs)
        gateway.install(composed)
        assert gateway.policy is composed.policy and gateway.rules == composed.publish
        assert list(gateway.hooks) == []          # heard once sealed, with the other parts (server.start)
        gateway.hooks.seal(composed.hooks)
        assert list(gateway.hooks) == list(composed.hooks)
        with pytest.raises(RuntimeError):
            gateway.install(composed)
    finally:
        await gateway.shutdown()
        await backend.stop()
