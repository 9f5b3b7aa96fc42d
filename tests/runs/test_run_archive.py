"""Every run kept (gateway/runs/archive.py): its source, output past the cap, recording, kept across
a restart of the gateway on the same store, private to its starter and the admins, and deleted by
the retention flags. Real gateway processes, real runs, the MCAP read back with rosbags."""

from __future__ import annotations

import tempfile
import time

import pytest

from tests.support.auth import TOKENS, tokens_toml
from tests.support.http import api, http
from tests.support.runs import ended, program
from tests.support.wait import wait_for

TWIST = 'geometry_msgs/msg/Twist'
ALICE, BOB, ADMIN = TOKENS['operator'], TOKENS['operator2'], TOKENS['admin']


def start_run(gw, body: dict, token: str | None = None) -> str:
    status, reply = api(gw, 'POST', '/api/runs', {'name': 'kept', **body}, token=token)
    assert status == 201, reply
    return reply['id']


def kept(gw, token: str | None = None) -> list[dict]:
    status, body = api(gw, 'GET', '/api/runs?all=1', token=token)
    assert status == 200, body
    return body['runs']


def test_a_kept_run_its_output_and_recording_survive_a_restart_and_stay_private(start_gateway, tmp_path):
    (tmp_path / 'tokens.toml').write_text(tokens_toml())
    env = {'XDG_DATA_HOME': str(tmp_path / 'data')}      # one store, runs and recordings for both lives
    flags = ('--robot', 'turtlesim', '--fleet', '2', '--allow-runs', '--auth', str(tmp_path / 'tokens.toml'),
             '--run-output-cap', '4K')
    gw = start_gateway(*flags, env=env)
    source = program(f'''
for i in range(2000):
    print("line %04d of the output" % i)
rt.drive("/s01/turtle1/cmd_vel", "{TWIST}", {{"linear": {{"x": 1.0}}}}, 1.0)
''')
    run_id = start_run(gw, {'source': source, 'ns': '/s01', 'record': True}, ALICE)
    final = ended(gw, run_id, token=ALICE)
    assert final['state'] == 'finished', final
    status, body = api(gw, 'GET', f'/api/runs/{run_id}', token=BOB)
    assert status == 403 and 'alice' in body['error'], body

    # bob's run is still going when the gateway stops: it is stopped, and kept as such
    going = start_run(gw, {'source': program('print("before the restart")\n'
                                             'rt.wait_for_message("/archive_test/go", "std_msgs/msg/String")'),
                           'ns': '/s02'}, BOB)
    wait_for(lambda: 'before the restart' in api(gw, 'GET', f'/api/runs/{going}', token=BOB)[1]['output'], 60, 0.1)

    gw.stop()
    gw = start_gateway(*flags, env=env)       # the same store, a new process

    bobs = kept(gw, BOB)
    assert [(r['id'], r['state'], r['owner']) for r in bobs] == [(going, 'stopped', 'bob')], bobs
    assert http(gw, f'/api/runs/{going}/output', token=BOB).body.decode().startswith('before the restart\n')

    mine = [r for r in kept(gw, ALICE) if r['id'] == run_id]
    assert len(mine) == 1, kept(gw, ALICE)
    row = mine[0]
    assert (row['state'], row['exit_code'], row['ns'], row['owner'], row['kind']) == \
        ('finished', 0, '/s01', 'alice', 'python')
    assert row['cut'] and row['output_bytes'] <= 4096 < 2000 * 24 <= row['output_seen'], row
    assert row['recorded'] and row['recording_bytes'] > 0 and row['ended'] >= row['started']

    out = http(gw, f'/api/runs/{run_id}/output', token=ALICE)
    assert out.status == 200 and out.headers['Content-Type'].startswith('text/plain')
    text = out.body.decode()
    assert text.startswith('line 0000 of the output\n') and len(out.body) <= 4096
    assert text.rstrip('\n').splitlines()[-1].startswith('[output cut here after ')
    assert '--run-output-cap 4096' in text
    got = http(gw, f'/api/runs/{run_id}/source', token=ALICE)
    assert got.status == 200 and got.body.decode() == source

    mcap = http(gw, f'/api/runs/{run_id}/recording.mcap', token=ALICE)
    assert mcap.status == 200 and len(mcap.body) == row['recording_bytes']
    (tmp_path / 'run.mcap').write_bytes(mcap.body)
    from rosbags.highlevel import AnyReader
    with AnyReader([tmp_path / 'run.mcap']) as reader:
        topics = {c.topic for c in reader.connections}
        poses = [reader.deserialize(raw, c.msgtype) for c, _, raw in reader.messages()
                 if c.topic == '/s01/turtle1/pose']
    assert '/s01/turtle1/pose' in topics and '/s01/turtle1/cmd_vel' in topics, topics
    assert all(t.startswith('/s01/') for t in topics), topics     # the station's topics alone
    assert len(poses) > 10 and poses[-1].x > poses[0].x + 0.5     # the run drove it, and it was recorded

    # another person: not listed, every read refused; an admin sees and reads it
    for path in ('', '/output', '/source', '/recording.mcap'):
        reply = http(gw, f'/api/runs/{run_id}{path}', token=BOB)
        assert reply.status == 403, (path, reply)
        assert 'alice' in reply.json()['error']
    assert run_id in {r['id'] for r in kept(gw, ADMIN)}
    assert http(gw, f'/api/runs/{run_id}/output', token=ADMIN).body == out.body

    # a person's runs go with them: an admin deletes them (an operator may not)
    assert api(gw, 'DELETE', '/api/runs?person=alice', token=ALICE)[0] == 403
    status, body = api(gw, 'DELETE', '/api/runs?person=alice', token=ADMIN)
    assert status == 200 and body['deleted'] == 1, body
    assert http(gw, f'/api/runs/{run_id}/output', token=ALICE).status == 404
    assert kept(gw, ALICE) == []


def quick(gw, n: int) -> list[str]:
    ids = []
    for i in range(n):
        ids.append(start_run(gw, {'source': program(f'print("run {i}")'), 'name': f'run{i}'}))
        assert ended(gw, ids[-1])['state'] == 'finished'
    return ids


def test_retention_by_count_and_age_and_the_size_cap_refuses(start_gateway):
    data = tempfile.mkdtemp(prefix='rosgate-archive-')
    env = {'XDG_DATA_HOME': data}
    gw = start_gateway('--robot', 'turtlesim', '--allow-runs', '--runs-keep-count', '2', env=env)
    ids = quick(gw, 4)
    # pruned at each run's start: the runs ended before the 4th began, past the newest 2, are gone
    listed = [r['id'] for r in kept(gw)]
    assert ids[0] not in listed and ids[-1] in listed and len(listed) <= 3, (ids, listed)
    gw.stop()
    gw = start_gateway('--robot', 'turtlesim', '--allow-runs', '--runs-keep-count', '2', env=env)
    assert [r['id'] for r in kept(gw)] == ids[:1:-1]       # at the start too: the newest 2, newest first
    text = http(gw, f'/api/runs/{ids[-1]}/output').body.decode()
    assert text.startswith('run 3\n') and '[run finished]' in text
    gw.stop()
    gw = start_gateway('--robot', 'turtlesim', '--allow-runs', '--runs-keep-days', '0.00001', env=env)
    assert kept(gw) == []                                  # older than a second: all gone
    assert http(gw, f'/api/runs/{ids[-1]}/output').status == 404
    gw.stop()

    # the size cap: one run going takes its output cap of the archive's bytes; a second would not fit
    gw = start_gateway('--robot', 'turtlesim', '--fleet', '2', '--allow-runs', '--runs-keep-bytes', '100K',
                       '--run-output-cap', '64K', env=env)
    first = start_run(gw, {'source': program('rt.wait_for_message("/archive_test/go", "std_msgs/msg/String")'),
                           'ns': '/s01'})
    status, body = api(gw, 'POST', '/api/runs', {'source': program('print(1)'), 'ns': '/s02'})
    assert status == 507 and '--runs-keep-bytes' in body['error'], body
    assert api(gw, 'DELETE', f'/api/runs/{first}')[0] in (200, 202)
    assert ended(gw, first)['state'] == 'stopped'
    second = wait_for(lambda: (lambda r: r[1]['id'] if r[0] == 201 else None)(
        api(gw, 'POST', '/api/runs', {'source': program('print(2)'), 'ns': '/s02'})), 10, 0.1)
    assert ended(gw, second)['state'] == 'finished'


def test_bad_bodies_are_refused(start_gateway):
    gw = start_gateway('--robot', 'none', '--allow-runs')
    status, body = api(gw, 'POST', '/api/runs', {'source': 'print(1)', 'kind': 'Not A Kind'})
    assert status == 400 and '"kind"' in body['error'], body
    status, body = api(gw, 'POST', '/api/runs', {'source': 'print(1)', 'record': 'yes'})
    assert status == 400 and '"record"' in body['error'], body
    status, body = api(gw, 'DELETE', '/api/runs')
    assert status == 400 and 'person' in body['error'], body
    assert http(gw, '/api/runs/r00000000/output').status == 404


def test_retention_by_size_keeps_the_newest_that_fit_and_ends_runs_a_dead_gateway_left(tmp_path):
    """The archive on a real SQLite store, in this process: rows as the supervisor leaves them."""
    import sqlalchemy as sa

    from gateway.runs.archive import OUTPUT, RUNS, Archive
    from gateway.store import Store

    store = Store(f'sqlite:///{tmp_path}/rosgate.db')
    now = time.time()

    def row(i: int, started: float, output: int, ended: bool = True) -> dict:
        return dict(id=f'r{i:08x}', name=f'run {i}', kind='python', owner='ada', who='ada', ns='', started=started,
                    ended=started + 1 if ended else None, state='finished' if ended else 'running', source='x' * 100,
                    output_bytes=output, output_seen=output, cut=False, recording_bytes=0)
    rows = [row(i, now - 1000 + i, 10_000) for i in range(10)] + [row(99, now - 3 * 3600, 0, ended=False)]
    store.run_now(lambda c: (c.execute(RUNS.insert(), rows),
                             c.execute(OUTPUT.insert(), [{'run': r['id'], 'seq': 0, 'text': 'out\n'} for r in rows])))
    Archive(store, cap=2**20, keep_days=1, keep_count=100, keep_bytes=35_000)   # prunes as it opens
    left = store.run_now(lambda c: {r.id: r.state for r in c.execute(sa.select(RUNS.c.id, RUNS.c.state))})
    # 10,100 bytes a run: the newest three fit in 35,000 (with the interrupted one, 100 bytes)
    assert left == {'r00000009': 'finished', 'r00000008': 'finished', 'r00000007': 'finished',
                    'r00000063': 'interrupted'}, left
    outputs = store.run_now(lambda c: set(c.execute(sa.select(OUTPUT.c.run)).scalars()))
    assert outputs == set(left)
    store.close()


def test_a_run_in_the_root_records_the_graph_but_not_the_gateways_own_topics(start_gateway, tmp_path):
    gw = start_gateway('--robot', 'turtlesim', '--allow-runs')
    run_id = start_run(gw, {'source': program('rt.log("recorded")\nrt.sleep(1.0)'), 'record': True})
    status, body = api(gw, 'GET', f'/api/runs/{run_id}/recording.mcap')
    assert status in (404, 409), body            # not before it ends
    assert ended(gw, run_id)['state'] == 'finished'
    mcap = http(gw, f'/api/runs/{run_id}/recording.mcap')
    assert mcap.status == 200 and mcap.headers['Content-Disposition'].endswith(f'-{run_id}.mcap"')
    (tmp_path / 'root.mcap').write_bytes(mcap.body)
    from rosbags.highlevel import AnyReader
    with AnyReader([tmp_path / 'root.mcap']) as reader:
        topics = {c.topic for c in reader.connections}
        counts = {t: 0 for t in topics}
        for c, _, _ in reader.messages():
            counts[c.topic] += 1
    assert counts.get('/turtle1/pose', 0) > 10, counts
    assert not any(t.startswith('/rosgate/') for t in topics), topics   # no run's output, not even its own
