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
    if not PG_BIN:
        pytest.skip('Debian postgresql is not installed (tools/system-packages test)')
    bin = PG_BIN[-1]
    folder = tempfile.mkdtemp(prefix='rosgate-pg-')
    user = None
    if os.geteuid() == 0:
        user = 'postgres'
        pw = pwd.getpwnam(user)
        os.chown(folder, pw.pw_uid, pw.pw_gid)

    def run(*cmd):
        cmd = [str(c) for c in cmd]
        return subprocess.run(['runuser', '-u', user, '--', *cmd] if user else cmd,
                              check=True, capture_output=True, text=True, timeout=120)

    data, port = f'{folder}/data', free_port()
    run(f'{bin}/initdb', '-D', data, '-A', 'trust', '-U', 'rosgate', '--no-sync')
    run(f'{bin}/pg_ctl', '-D', data, '-l', f'{folder}/log', '-w', '-t', '60', 'start',
        '-o', f"-p {port} -c listen_addresses=127.0.0.1 -k {folder} -c fsync=off")
    try:
        run(f'{bin}/createdb', '-h', '127.0.0.1', '-p', port, '-U', 'rosgate', 'rosgate')
        yield f'postgresql+psycopg://rosgate@127.0.0.1:{port}/rosgate'
    finally:
        run(f'{bin}/pg_ctl', '-D', data, '-m', 'fast', '-w', 'stop')
        shutil.rmtree(folder, ignore_errors=True)


