"""Behind Debian's nginx terminating TLS, configured exactly as docs/remote-lab.md says: a real page
at https://lab.localtest:P signs in, opens wss and drives its station; pages of another https
origin (other.localtest) and of another port are refused the websocket. nginx runs on loopback
with a certificate the test makes (cryptography), its config the guide's nginx block with the
test's name, ports and files put in; Chromium resolves the names to 127.0.0.1.

Also, without a browser: X-Forwarded-For counts per client for the sign-in brake only from a
trusted proxy, and the headers of anyone else change nothing.
"""

from __future__ import annotations

import datetime
import ipaddress
import urllib.error
import urllib.parse
import urllib.request
from pathlib import Path

import pytest
from cryptography import x509
from cryptography.hazmat.primitives import hashes, serialization
from cryptography.hazmat.primitives.asymmetric import ec
from cryptography.x509.oid import NameOID

from tests.support.http import http
from tests.support.ide import CHROMIUM, CHROMIUM_ARGS, drives_its_station, teleop_ready
from tests.support.nginx import NGINX, guide_block, nginx
from tests.support.postgres import free_port
from tests.support.wait import wait_for

TOKENS = {'operator': 'proxy-operator-token-1', 'admin': 'proxy-admin-token-2'}


def certificate(folder: Path) -> tuple[Path, Path]:
    key = ec.generate_private_key(ec.SECP256R1())
    name = x509.Name([x509.NameAttribute(NameOID.COMMON_NAME, 'lab.localtest')])
    now = datetime.datetime.now(datetime.timezone.utc)
    cert = (x509.CertificateBuilder().subject_name(name).issuer_name(name).public_key(key.public_key())
            .serial_number(x509.random_serial_number()).not_valid_before(now - datetime.timedelta(minutes=5))
            .not_valid_after(now + datetime.timedelta(days=1))
            .add_extension(x509.SubjectAlternativeName([x509.DNSName('lab.localtest'), x509.DNSName('other.localtest'),
                                                        x509.IPAddress(ipaddress.ip_address('127.0.0.1'))]), False)
            .sign(key, hashes.SHA256()))
    cert_path, key_path = folder / 'lab.pem', folder / 'lab.key'
    cert_path.write_bytes(cert.public_bytes(serialization.Encoding.PEM))
    key_path.write_bytes(key.private_bytes(serialization.Encoding.PEM, serialization.PrivateFormat.PKCS8,
                                           serialization.NoEncryption()))
    return cert_path, key_path


ELSEWHERE = """<!doctype html><title>elsewhere</title><script>
const ws = new WebSocket('wss://lab.localtest:%(lab)d/');
ws.onopen = () => { document.title = 'opened'; };
ws.onerror = ws.onclose = () => { if (document.title !== 'opened') document.title = 'refused'; };
</script>"""


@pytest.fixture(scope='module')
def proxied(start_gateway, tmp_path_factory):
    if not Path(NGINX).exists():
        pytest.fail('nginx not found: apt-get install nginx (tools/system-packages test)')
    folder = tmp_path_factory.mktemp('nginx')
    tokens = folder / 'tokens.toml'
    tokens.write_text(''.join(f'[[tokens]]\nname = "{r}"\nrole = "{r}"\ntoken = "{t}"\n\n' for r, t in TOKENS.items()))
    # as the guide starts it: on loopback (the tests' gateways are), the lab's name, the proxy trusted
    gw = start_gateway('--robot', 'turtlesim', '--fleet', '2', '--auth', str(tokens),
                       '--allowed-hosts', 'lab.localtest', '--trusted-proxies', '127.0.0.1')
    cert, key = certificate(folder)
    lab, other_port = free_port(), free_port()
    site = (guide_block()
            .replace('listen 443 ssl;', f'listen 127.0.0.1:{lab} ssl;')
            .replace('lab.school.example.pem', 'X').replace('/etc/ssl/X', str(cert))
            .replace('/etc/ssl/private/lab.school.example.key', str(key))
            .replace('lab.school.example', 'lab.localtest')
            .replace('127.0.0.1:9090', f'127.0.0.1:{gw.port}'))
    assert str(cert) in site and str(key) in site and f':{gw.port}' in site and f':{lab} ssl' in site
    page = (ELSEWHERE % {'lab': lab}).replace("'", "\\'").replace('\n', ' ')
    elsewhere = ''.join(f"""
    server {{
        listen 127.0.0.1:{port} ssl;
        server_name {name};
        ssl_certificate {cert};
        ssl_certificate_key {key};
        location / {{ default_type text/html; return 200 '{page}'; }}
    }}""" for port, name in ((lab, 'other.localtest'), (other_port, 'lab.localtest')))
    with nginx(folder, f'{site}\n{elsewhere}', lab):
        yield gw, lab, other_port


@pytest.fixture
def browser(chromium_resolving):
    ctx = chromium_resolving.new_context(ignore_https_errors=True, viewport={'width': 1180, 'height': 820})
    yield ctx
    ctx.close()


@pytest.fixture(scope='module')
def chromium_resolving(playwright):
    browser = playwright.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS + [
        '--host-resolver-rules=MAP lab.localtest 127.0.0.1, MAP other.localtest 127.0.0.1'])
    yield browser
    browser.close()


def test_a_page_through_nginx_signs_in_opens_wss_and_drives_its_station(proxied, browser):
    gw, lab, other_port = proxied
    base = f'https://lab.localtest:{lab}'
    page = browser.new_page()
    errors = []
    page.on('pageerror', lambda e: errors.append(str(e)))
    page.goto(f'{base}/login?next=/teleop')
    page.fill('input[name=token]', TOKENS['operator'])
    page.click('button[type=submit]')
    page.wait_for_url(f'{base}/teleop')
    # its station once it holds it (a page may show one station and reload into the one it is given)
    ns = teleop_ready(page, stations=r'^\/s0[12]$')
    cookie = next(c for c in browser.cookies() if c['name'] == 'rosgate_session')
    assert cookie['secure'] and cookie['httpOnly'] and cookie['sameSite'] == 'Lax'
    assert TOKENS['operator'] not in cookie['value']
    drives_its_station(page, gw, TOKENS['admin'], ns)
    assert not errors, errors

    # pages of another https origin and of another port, in the same signed-in browser: no websocket
    for url in (f'https://other.localtest:{lab}/', f'https://lab.localtest:{other_port}/'):
        other = browser.new_page()
        other.goto(url)
        other.wait_for_function("document.title === 'refused' || document.title === 'opened'", timeout=15000)
        assert other.title() == 'refused', url


def _post_login(gw, token: str, forwarded_for: str) -> int:
    form = urllib.parse.urlencode({'token': token, 'next': '/'}).encode()
    return http(gw, '/login', method='POST', data=form, headers={'X-Forwarded-For': forwarded_for}).status


@pytest.mark.parametrize('trusted, shared', [('127.0.0.1', False), ('127.0.0.2', True)])
def test_the_brake_counts_each_client_behind_a_trusted_proxy_only(start_gateway, tmp_path, trusted, shared):
    """Five typos of one student behind the proxy; another student's right token then passes.
    When the sender is not a trusted proxy, its X-Forwarded-For is ignored: all share one count."""
    tokens = tmp_path / 'tokens.toml'
    tokens.write_text(f'[[tokens]]\nname = "op"\nrole = "operator"\ntoken = "{TOKENS["operator"]}"\n')
    gw = start_gateway('--auth', str(tokens), '--trusted-proxies', trusted, '--auth-backoff', '5')
    statuses = [_post_login(gw, 'wrong-token-0000', '198.51.100.7') for _ in range(5)]
    assert statuses[-1] == 429, statuses
    other = _post_login(gw, TOKENS['operator'], '203.0.113.9')
    assert other == (429 if shared else 303)
