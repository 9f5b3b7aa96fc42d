"""A PostgreSQL server of the test's own (Debian's postgresql: initdb and pg_ctl in a temporary
folder, on a free loopback port): the store's PostgreSQL path and a fleet of gateways on it.
``postgres = pytest.fixture(scope='module')(postgres_server)`` in a test module."""

from __future__ import annotations

import glob
import os
import pwd
import shutil
import socket
import subprocess
import tempfile

import pytest

PG_BIN = sorted(glob.glob('/usr/lib/postgresql/*/bin'))


def free_port() -> int:
    with socket.socket() as s:
        s.bind(('127.0.0.1', 0))
        return s.getsockname()[1]


def postgres_server():
    """A PostgreSQL server of its own on 127.0.0.1 (as the postgres user when run by root: it
    refuses root), its data in a temporary folder; its URL, stopped at the end."""
    for pg in postgres():
        yield pg.url


class Postgres:
    """A test's PostgreSQL (``postgres()``): its URL, and the faults a lesson meets."""

    def __init__(self):
        if not PG_BIN:
            pytest.skip('Debian postgresql is not installed (tools/system-packages test)')
        self.bin = PG_BIN[-1]
        self.folder = tempfile.mkdtemp(prefix='rosgate-pg-')
        self.user = None
        if os.geteuid() == 0:
            self.user = 'postgres'
            pw = pwd.getpwnam(self.user)
            os.chown(self.folder, pw.pw_uid, pw.pw_gid)
        self.data, self.port = f'{self.folder}/data', free_port()
        self.url = f'postgresql+psycopg://rosgate@127.0.0.1:{self.port}/rosgate'
        # over its unix socket: for a gateway in another network namespace (tests/support/netlink.py)
        self.unix_url = f'postgresql+psycopg://rosgate@/rosgate?host={self.folder}&port={self.port}'

    def run(self, *cmd):
        cmd = [str(c) for c in cmd]
        return subprocess.run(['runuser', '-u', self.user, '--', *cmd] if self.user else cmd,
                              check=True, capture_output=True, text=True, timeout=120)

    def start(self) -> None:
        self.run(f'{self.bin}/pg_ctl', '-D', self.data, '-l', f'{self.folder}/log', '-w', '-t', '60', 'start',
                 '-o', f"-p {self.port} -c listen_addresses=127.0.0.1 -k {self.folder} -c fsync=off")

    def stop(self) -> None:
        self.run(f'{self.bin}/pg_ctl', '-D', self.data, '-m', 'fast', '-w', 'stop')

    def restart(self) -> None:
        """PostgreSQL restarted mid-lesson: every connection dropped, the server back with its data."""
        self.run(f'{self.bin}/pg_ctl', '-D', self.data, '-l', f'{self.folder}/log', '-m', 'fast', '-w', '-t', '60',
                 'restart')

    def sql(self, text: str, **params) -> list:
        import sqlalchemy as sa
        engine = sa.create_engine(self.url)
        try:
            with engine.begin() as c:
                result = c.execute(sa.text(text), params)
                return result.all() if result.returns_rows else []
        finally:
            engine.dispose()

    def kill(self, pid: int) -> int:
        """``pg_terminate_backend`` on every connection of the gateway process ``pid`` (its
        connections are named rosgate-PID-ROLE); how many."""
        rows = self.sql("SELECT pg_terminate_backend(pid) FROM pg_stat_activity WHERE application_name LIKE :name",
                        name=f'rosgate-{pid}-%')
        return sum(1 for r in rows if r[0])


def kill_ports(pg: Postgres, ports: list[int]) -> int:
    """``pg_terminate_backend`` on the connections that come from these client ports; how many."""
    if not ports:
        return 0
    rows = pg.sql('SELECT pg_terminate_backend(pid) FROM pg_stat_activity WHERE client_port = ANY(:ports)',
                  ports=list(ports))
    return sum(1 for r in rows if r[0])


def postgres():
    """A started ``Postgres`` (a generator for a fixture), stopped and removed at the end."""
    pg = Postgres()
    pg.run(f'{pg.bin}/initdb', '-D', pg.data, '-A', 'trust', '-U', 'rosgate', '--no-sync')
    pg.start()
    try:
        pg.run(f'{pg.bin}/createdb', '-h', '127.0.0.1', '-p', pg.port, '-U', 'rosgate', 'rosgate')
        yield pg
    finally:
        try:
            pg.stop()
        except subprocess.CalledProcessError:
            pass
        shutil.rmtree(pg.folder, ignore_errors=True)


