"""Fixtures for the security tests: token files, certificates, and gateways started with them."""

from __future__ import annotations

import subprocess
from contextlib import ExitStack

import pytest

from tests.support.auth import tokens_toml


@pytest.fixture(scope='session')
def tokens_file(tmp_path_factory):
    path = tmp_path_factory.mktemp('auth') / 'tokens.toml'
    path.write_text(tokens_toml())
    return str(path)


@pytest.fixture(scope='session')
def certificate(tmp_path_factory):
    """A self-signed certificate for 127.0.0.1, made here with the openssl command."""
    folder = tmp_path_factory.mktemp('tls')
    cert, key = folder / 'cert.pem', folder / 'key.pem'
    subprocess.run(['openssl', 'req', '-x509', '-newkey', 'ec', '-pkeyopt', 'ec_paramgen_curve:prime256v1',
                    '-nodes', '-keyout', str(key), '-out', str(cert), '-days', '1', '-subj', '/CN=127.0.0.1',
                    '-addext', 'subjectAltName=IP:127.0.0.1'],
                   check=True, capture_output=True, timeout=30)
    return str(cert), str(key)


@pytest.fixture(scope='module')
def launch(start_gateway):
    """start_gateway(*flags) for this module: every gateway it started is stopped at module end."""
    with ExitStack() as started:
        def start(*flags: str, env: dict | None = None):
            gw = start_gateway(*flags, env=env)
            started.callback(gw.stop)
            return gw

        yield start
