"""Debian's nginx of a test's own: in the foreground, in a folder of its own (its pid, logs and
temporary files), with the http block's servers the caller gives; ``nginx(...)`` as a context
manager, once it accepts connections on the port given. The TLS proxy of docs/remote-lab.md
(tests/ide/test_nginx_proxy.py) and a fleet's gateways behind one proxy (tests/bench/scale.py)."""

from __future__ import annotations

import re
import shutil
import socket
import subprocess
from contextlib import contextmanager
from pathlib import Path

from .wait import wait_for

NGINX = shutil.which('nginx') or '/usr/sbin/nginx'
ROOT = Path(__file__).resolve().parents[2]


def guide_block() -> str:
    """The nginx block of docs/remote-lab.md, as the guide gives it (a test puts its names in)."""
    text = (ROOT / 'docs' / 'remote-lab.md').read_text()
    return re.search(r'```nginx\n(.*?)```', text, re.S).group(1)


@contextmanager
def nginx(folder: Path, servers: str, port: int, workers: int = 1):
    """nginx serving ``servers`` (server and upstream blocks) until the block ends; the Popen."""
    if not Path(NGINX).exists():
        raise AssertionError('nginx not found: apt-get install nginx (tools/system-packages test)')
    conf = folder / 'nginx.conf'
    conf.write_text(f"""daemon off;
pid {folder}/nginx.pid;
error_log {folder}/error.log;
worker_processes {workers};
events {{ worker_connections 1024; }}
http {{
    access_log {folder}/access.log;
    client_body_temp_path {folder}/body;
    proxy_temp_path {folder}/proxy;
    fastcgi_temp_path {folder}/fastcgi;
    uwsgi_temp_path {folder}/uwsgi;
    scgi_temp_path {folder}/scgi;
{servers}
}}
""")
    proc = subprocess.Popen([NGINX, '-p', str(folder), '-c', str(conf)], stdout=subprocess.PIPE,
                            stderr=subprocess.STDOUT)
    try:
        def up():
            if proc.poll() is not None:
                raise AssertionError(f'nginx exited: {proc.stdout.read().decode()}')
            with socket.socket() as s:
                return s.connect_ex(('127.0.0.1', port)) == 0
        wait_for(up, timeout=15, what='nginx listening')
        yield proc
    finally:
        proc.terminate()
        proc.wait(10)
