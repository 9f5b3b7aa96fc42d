"""The robot's description for the 3D twin, in one answer that is always there (``/api/description``
and ``/urdf``: ``web.description``).

Found in this order: the ``--urdf`` file; else ``NS/robot_description`` where something publishes
it (its retained message, taken through the topic's shared fan-out as any subscriber's); else the
``robot_description`` parameter of ``NS/robot_state_publisher`` when that node is on the graph.
A page no longer asks for ``/urdf`` on every start: without --urdf that was a 404 (and a console
error) on every load of /twin.

**xacro.** A description that is xacro (an ``xmlns:xacro`` declaration or an ``<xacro:...>``
element) is expanded by PyPI's xacro, in a child process (``xacro_child.py``) with ``$(find PKG)``
resolved through the package roots (AMENT_PREFIX_PATH's share folders, then ``--mesh-path``: the
folders /package/ serves) and only files under those roots (and the --urdf file's folder) readable.
The --urdf file is the operator's: it is expanded at start-up (``check_urdf``: a file xacro cannot
expand stops the start, naming the flag) with the gateway's environment. A description from the
graph is anyone's who may publish there: its child gets an empty environment, a CPU and memory cap
and a deadline (its expressions are Python under xacro's own guard). Expansions are kept by their
text (``CACHE`` of them), so pages reloading do not start children; at most ``CHILDREN`` run at once.
"""

from __future__ import annotations

import asyncio
import hashlib
import json
import logging
import os
import re
import subprocess
import sys
import tempfile
from collections import OrderedDict
from pathlib import Path

from ..backends.base import BackendError
from ..rules.errors import Refusal
from ..rules.access import may
from .packages import package_roots
from .ports import Backend, Names, Taps

log = logging.getLogger('rosgate.description')
CHILD = Path(__file__).with_name('xacro_child.py')
XACRO = re.compile(r'xmlns:xacro\s*=|<xacro:')
LIMITS = (10, 1 << 30)       # the child's CPU seconds and address space (bytes)
DEADLINE = 20.0              # s the child may take, whatever its CPU time (it may wait on a disk)
MAX_TEXT = 8 * 2**20         # bytes of xacro a child is given
MAX_ANSWER = 32 * 2**20      # bytes of URDF read back
CACHE = 16                   # expansions kept
CHILDREN = 2                 # children at once
RETAINED_WAIT = 3.0          # s to wait for a robot_description topic's retained message


class XacroError(Exception):
    """A description xacro could not expand; the message is xacro's."""


def is_xacro(text: str) -> bool:
    return bool(XACRO.search(text))


def _request(text: str, filename: str | None, roots: list[Path], readable: list[Path]) -> bytes:
    if len(text.encode()) > MAX_TEXT:
        raise XacroError(f'the description is larger than {MAX_TEXT // 2**20} MB')
    return json.dumps({'text': text, 'filename': filename, 'roots': [str(r) for r in roots],
                       'readable': [str(r) for r in readable], 'limits': LIMITS}).encode()


def _answer(out: bytes, failed: str) -> str:
    if len(out) > MAX_ANSWER:
        raise XacroError(f'the expanded description is larger than {MAX_ANSWER // 2**20} MB')
    try:
        answer = json.loads(out)
    except ValueError:
        raise XacroError(failed) from None
    if 'urdf' not in answer:
        raise XacroError(str(answer.get('error', failed)))
    return answer['urdf']


def expand_file(path: Path, roots: list[Path]) -> str:
    """The --urdf file's text, expanded when it is xacro (the operator's file: the gateway's
    environment, its folder readable); XacroError or OSError saying why not."""
    path = Path(os.path.realpath(path))
    text = path.read_text()
    if not is_xacro(text):
        return text
    try:
        done = subprocess.run([sys.executable, '-I', str(CHILD)], cwd=path.parent, capture_output=True,
                              input=_request(text, str(path), roots, [*roots, path.parent]), timeout=DEADLINE)
    except subprocess.TimeoutExpired:
        raise XacroError(f'xacro took longer than {DEADLINE:g} s') from None
    return _answer(done.stdout, f'xacro failed (exit {done.returncode}): {done.stderr.decode()[-500:]}')


async def expand(text: str, roots: list[Path]) -> str:
    """A description from the graph, expanded in a child with no environment (see the module's doc)."""
    data = _request(text, None, roots, roots)
    with tempfile.TemporaryDirectory(prefix='rosgate-xacro-') as empty:   # relative includes lead nowhere
        proc = await asyncio.create_subprocess_exec(
            sys.executable, '-I', str(CHILD), cwd=empty, env={}, stdin=subprocess.PIPE,
            stdout=subprocess.PIPE, stderr=subprocess.DEVNULL)
        try:
            out = await asyncio.wait_for(_talk(proc, data), DEADLINE)
        except asyncio.TimeoutError:
            raise XacroError(f'xacro took longer than {DEADLINE:g} s') from None
        finally:
            if proc.returncode is None:
                proc.kill()
                await proc.wait()
    return _answer(out, f'xacro failed (exit {proc.returncode})')


async def _talk(proc, data: bytes) -> bytes:
    proc.stdin.write(data)
    await proc.stdin.drain()
    proc.stdin.close()
    out = await proc.stdout.read(MAX_ANSWER + 1)
    await proc.wait()
    return out


def check_urdf(urdf: Path | None, mesh_path) -> None:
    """At start-up: the --urdf file is readable and, when xacro, expands (ValueError saying why not)."""
    if urdf is None:
        return
    try:
        expand_file(Path(urdf).expanduser(), package_roots(mesh_path))
    except (OSError, XacroError) as e:
        raise ValueError(str(e)) from None


class Descriptions:
    """Where a namespace's description comes from (the --urdf file; else the graph's, read through
    the topic's fan-out, ``taps``, or a node's parameter, as far as ``names`` lets the asker), and
    the expansions made (by their text)."""

    def __init__(self, urdf: Path | None, roots: list[Path], *, taps: Taps, graph: Backend, names: Names):
        self.urdf, self.roots = urdf, roots
        self.taps, self.graph, self.names = taps, graph, names
        self.cache: OrderedDict[str, asyncio.Future] = OrderedDict()
        self.children = asyncio.Semaphore(CHILDREN)
        self.file: tuple | None = None   # ((mtime, size), text) of the --urdf file

    def file_text(self) -> str:
        """The --urdf file as the twin draws it: expanded when xacro, again when it changes."""
        stat = self.urdf.stat()
        stamp = (stat.st_mtime_ns, stat.st_size)
        if self.file is None or self.file[0] != stamp:
            self.file = (stamp, expand_file(self.urdf, self.roots))
        return self.file[1]

    async def expanded(self, text: str) -> str:
        if not is_xacro(text):
            return text
        key = hashlib.sha256(text.encode()).hexdigest()
        found = self.cache.get(key)
        if found is None or (found.done() and found.exception() is not None):
            found = self.cache[key] = asyncio.ensure_future(self._expand(text))
            while len(self.cache) > CACHE:
                self.cache.popitem(last=False)
        self.cache.move_to_end(key)
        return await asyncio.shield(found)

    async def _expand(self, text: str) -> str:
        async with self.children:
            return await expand(text, self.roots)

    async def retained(self, topic: str) -> str | None:
        """The topic's latest message's text (its retained one for a new subscriber), or None."""
        type_ = self.taps.topic_type(topic)
        if type_ not in ('std_msgs/msg/String', 'std_msgs/String'):
            return None
        fan = self.taps.fanout(topic, 'std_msgs/msg/String')
        if fan.last is not None:
            return fan.last.get('data')
        loop = asyncio.get_running_loop()
        got = loop.create_future()
        key = ('description', id(got))
        latest: list = []

        def take(msg, _image) -> None:   # the newest of what a late subscriber is handed at once
            if not latest:
                loop.call_soon(lambda: got.done() or got.set_result(latest[-1]))
            latest.append(msg)
        fan.watch(key, take)
        try:
            msg = await asyncio.wait_for(got, RETAINED_WAIT)
        except asyncio.TimeoutError:
            return None
        finally:
            fan.unwatch(key)
        return msg.get('data') if isinstance(msg, dict) else None

    async def find(self, who, ns: str) -> dict:
        if self.urdf is not None:
            return {'urdf': await self._or_502(asyncio.to_thread(self.file_text), '--urdf'), 'from': '--urdf'}
        graph = self.graph
        topic = f'{ns}/robot_description'
        if may(self.names, who, 'subscribe', topic) is None and graph.publishers(topic):
            text = await self.retained(topic)
            if text and text.strip():
                return {'urdf': await self._or_502(self.expanded(text), 'topic'), 'from': 'topic'}
        node = f'{ns}/robot_state_publisher'
        if node in graph.nodes() and self.names.visible(who, 'params', f'{node}:robot_description'):
            try:
                text = await graph.get_param(node, 'robot_description')
            except (KeyError, BackendError):
                text = None
            if isinstance(text, str) and text.strip():
                return {'urdf': await self._or_502(self.expanded(text), 'parameter'), 'from': 'parameter'}
        return {'urdf': '', 'from': None}

    @staticmethod
    async def _or_502(work, source: str) -> str:
        try:
            return await work
        except (XacroError, OSError) as e:
            log.warning('the robot description (%s) cannot be read: %s', source, e)
            raise Refusal(502, f'the robot description ({source}) cannot be expanded: {e}') from None
