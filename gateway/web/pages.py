"""What the HTTP side lets through, before any handler runs.

- Behind a TLS reverse proxy listed in ``--trusted-proxies``, its X-Forwarded-Proto/Host/For
  replace what the gateway sees of the request (``rules.names.forwarded``), before anything else.
- ``Application`` checks the ``Host`` header of every request, websocket upgrades included,
  against ``Policy.host_allowed``: a page on a rebound domain (``evil.example`` resolving to this
  machine) sends its own name as Host and is refused with 421, on every route.
- Request bodies are judged by their headers before a byte of them is read: over
  ``MAX_HTTP_BODY`` they get 413, and bodies the policy refuses (over ``SMALL_BODY`` without a
  valid token, when auth is on) get 401; the connection is closed after the answer.
- ``ide_problem`` says whether the IDE can be served from a directory at all.
- ``PublicFileHandler`` serves only what the pages load from the IDE directory: the pages, their
  scripts, styles and block files, and the built ``vendor/`` bundles, never ``node_modules/``,
  the build script or package files; with ``ISOLATION``'s headers (the IDE's Python needs them);
  Pyodide's versioned files as immutable (``VERSIONED``), everything else revalidated.
"""

from __future__ import annotations

import os
import re
from pathlib import Path

import tornado.web

from ..rules.names import forwarded
from ..rules.policy import Policy

# Top-level entries of ide/ that anyone may load; everything else there (node_modules/, package
# files, the build script) is for building them, and class.html only goes out through /class,
# which checks who asks.
PUBLIC_DIRS = frozenset({'blocks', 'css', 'generators', 'i18n', 'js', 'runtime', 'vendor'})
PUBLIC_FILES = frozenset({'index.html', 'teleop.html', 'twin.html', 'inspect.html', 'toolbox.json', 'blockschema.json'})
# The IDE page is cross-origin isolated, so its Python worker may share memory with it
# (SharedArrayBuffer: a blocked program wakes on the gateway's messages, ide/js/run/pyrun.js). Everything
# the page loads is from the gateway itself; a page of another origin cannot embed these files.
ISOLATION = {'Cross-Origin-Opener-Policy': 'same-origin', 'Cross-Origin-Embedder-Policy': 'require-corp',
             'Cross-Origin-Resource-Policy': 'same-origin'}
# A program from another person's share link runs in a worker of its own whose policy gives it no
# way to the gateway but the page's (ide/js/run/foreign.js): the scripts it needs and nothing else, no
# fetch, no XMLHttpRequest, no websocket (connect-src), and no import() of a page or an API (a JSON
# module reads the opener's data with her cookies: script-src and connect-src by path). Paths are
# given without a scheme (the page's own, behind a TLS proxy too). path -> (scripts, connections)
GUEST_WORKERS = {
    'js/run/guestworker.js': (('js/run/guestworker.js', 'vendor/roslib.mjs', 'runtime/'), ()),
    'js/run/pyworker.js': (('js/run/pyworker.js', 'vendor/pyodide/'), ('vendor/pyodide/', 'runtime/')),   # ?guest=1
}


def guest_policy(host: str, allowed: tuple) -> str:
    scripts, connections = allowed
    if not re.fullmatch(r'[A-Za-z0-9.\-]+(:\d+)?', host):
        host = ''          # a name CSP cannot say (an IPv6 literal): nothing is allowed, the guest fails closed
    where = lambda paths: ' '.join(f'{host}/{p}' for p in paths if host) or "'none'"   # noqa: E731
    return (f"default-src 'none'; script-src {where(scripts)} 'unsafe-eval' 'wasm-unsafe-eval'; "
            f"connect-src {where(connections)}")


# Pyodide's files under their version (ide/build.mjs): their content never changes at that path.
VERSIONED = re.compile(r'^vendor/pyodide/\d+\.\d+[\w.-]*/[^/]+$')
IMMUTABLE = 'public, max-age=31536000, immutable'
MAX_HTTP_BODY = 4 * 2**20   # the largest request body any route takes (a program is at most 2 MiB)
# What the pages cannot work without (the bundles come from `npm run build` in ide/).
IDE_REQUIRED = ('index.html', 'teleop.html', 'vendor/roslib.mjs', 'vendor/blockly/blockly_compressed.js')


@tornado.web.stream_request_body
class RefusedHandler(tornado.web.RequestHandler):
    """Answers from the headers alone; the body (if any) is discarded unread, then the connection closes."""

    def initialize(self, status: int, reason: str) -> None:
        self.status, self.reason = status, reason

    def prepare(self) -> None:
        self.set_status(self.status)
        self.set_header('Content-Type', 'text/plain; charset=UTF-8')
        self.finish(f'{self.status} {self._reason}: {self.reason}\n')

    def data_received(self, chunk: bytes) -> None:
        pass


class Application(tornado.web.Application):
    """A tornado Application that refuses requests whose Host the gateway's policy does not know;
    its handlers' ``@authorized`` asks the same policy (``api.policy_of``)."""

    def __init__(self, policy: Policy, *args, **kwargs) -> None:
        self.policy = policy
        super().__init__(*args, **kwargs)

    def find_handler(self, request, **kwargs):
        policy = self.policy
        forwarded(request, policy.trusted_proxies)   # first: every check below sees the browser's view
        if not policy.host_allowed(request.host):
            return self._refuse(request, 421, f'this gateway does not answer to the name {request.host[:100]!r}; '
                                              'start it with --allowed-hosts to add names')
        size = body_size(request)
        if size is not None:
            if size > MAX_HTTP_BODY:
                return self._refuse(request, 413, f'request bodies are at most {MAX_HTTP_BODY} bytes')
            refusal = policy.body_refusal(request, size)
            if refusal is not None:
                return self._refuse(request, *refusal)
            request.connection.set_max_body_size(MAX_HTTP_BODY)   # chunked bodies too
        return super().find_handler(request, **kwargs)

    def _refuse(self, request, status: int, reason: str):
        return self.get_handler_delegate(request, RefusedHandler, {'status': status, 'reason': reason})


def body_size(request) -> int | None:
    """The announced size of the request body: None when there is none, -1 when chunked."""
    length = request.headers.get('Content-Length')
    if length is not None:
        try:
            size = int(length)
        except ValueError:
            return MAX_HTTP_BODY + 1   # tornado would refuse it too
        return size if size > 0 else None
    if 'chunked' in request.headers.get('Transfer-Encoding', '').lower():
        return -1
    return None


class PublicFileHandler(tornado.web.StaticFileHandler):
    """The IDE's public files; vendored files may change between installs, so revalidate them."""

    def validate_absolute_path(self, root: str, absolute_path: str) -> str | None:
        relative = os.path.relpath(absolute_path, os.path.abspath(root))
        top = relative.replace(os.sep, '/').split('/', 1)
        public = top[0] in PUBLIC_FILES if len(top) == 1 else top[0] in PUBLIC_DIRS
        if not public:
            if relative != '.':   # '.' is the root: StaticFileHandler redirects to index.html
                raise tornado.web.HTTPError(404)
        return super().validate_absolute_path(root, absolute_path)

    def set_extra_headers(self, path: str) -> None:
        # a versioned Pyodide file never changes: the browser keeps it, and the WebAssembly it
        # compiled from it, without asking again (a page load starts Python from its cache)
        self.set_header('Cache-Control', IMMUTABLE if VERSIONED.match(path.replace(os.sep, '/')) else 'no-cache')
        for name, value in ISOLATION.items():
            self.set_header(name, value)
        guest = GUEST_WORKERS.get(path.replace(os.sep, '/'))
        if guest is not None and (path.endswith('guestworker.js') or self.get_query_argument('guest', '') == '1'):
            self.set_header('Content-Security-Policy', guest_policy(self.request.host or '', guest))

    async def get(self, path: str, include_body: bool = True) -> None:
        # Pyodide's 9.6 MB wasm goes out as the build's gzip of it (3.5 MB) to browsers that take
        # gzip: tornado compresses text types only, and would do it again on every request
        if path.endswith('.wasm'):
            self.set_header('Vary', 'Accept-Encoding')
            if ('gzip' in self.request.headers.get('Accept-Encoding', '')
                    and os.path.isfile(os.path.join(self.root, path + '.gz'))):
                self.set_header('Content-Encoding', 'gzip')
                path += '.gz'
        await super().get(path, include_body)

    def get_content_type(self) -> str:
        if self.absolute_path.endswith(('.wasm', '.wasm.gz')):   # streaming compilation needs it
            return 'application/wasm'
        return super().get_content_type()


def write_page(handler: tornado.web.RequestHandler, page, cache: str = 'no-cache', isolated: bool = False) -> None:
    """One of the IDE's pages as the response (404 when the IDE is not built); ``isolated``: with
    ``ISOLATION``'s headers (the IDE, whose Python worker shares memory with it)."""
    if not page.is_file():
        raise tornado.web.HTTPError(404)
    handler.set_header('Content-Type', 'text/html; charset=UTF-8')
    handler.set_header('Cache-Control', cache)
    for name, value in (ISOLATION.items() if isolated else ()):
        handler.set_header(name, value)
    handler.write(page.read_bytes())


def ide_problem(ide: Path) -> str | None:
    """None when the pages can be served from `ide`, else a sentence saying what is missing."""
    missing = [f for f in IDE_REQUIRED if not (ide / f).is_file()]
    if not missing:
        return None
    if not (ide / 'index.html').is_file():
        return f'no IDE pages in {ide}'
    return (f'the IDE in {ide} is not built (missing {", ".join(missing)}): '
            'run `make ide` (npm ci && npm run build in ide/)')
