"""The program library: block programs stored as JSON files under one directory.

GET    /api/programs          -> {"programs": [{"name", "size", "modified"}, ...]}
GET    /api/programs/NAME     -> the stored program (JSON)
PUT    /api/programs/NAME     -> store the request body (a JSON object); 200 {"name", "size"}
DELETE /api/programs/NAME     -> 204

NAME: 1-64 characters of letters, digits, space, '_' and '-', not starting with a space.
Anything else is refused with 400 before the file system is touched.

Spaces: with auth on (``--auth``) every signed-in name has a space of its own, ``users/NAME/``
under the library directory. An operator reads and writes only its own space, a viewer only
reads its own, an admin sees every space: the list holds every program with its ``owner``
(null: the shared space at the top of the directory, where programs saved without auth live)
and ``?owner=NAME`` on any request picks a space. Without auth every request is an admin's.

Each space holds at most ``MAX_SPACE_BYTES`` (32 MiB: sixteen of the largest programs, hundreds
of ordinary ones); a save past it is refused with 507 and stores nothing.
"""

from __future__ import annotations

import errno
import hashlib
import json
import os
import pathlib
import re
import tempfile

import tornado.web

from ..rules.access import Action, Area, allowed
from .api import JsonHandler, body_json, check_origin, require
from ..settings import data_dir

MAX_PROGRAM_BYTES = 2 * 1024 * 1024
MAX_SPACE_BYTES = 32 * 1024 * 1024
_NAME = re.compile(r"[A-Za-z0-9_-][A-Za-z0-9 _-]{0,63}")
_OWNER = re.compile(r"[A-Za-z0-9_-][A-Za-z0-9_.@-]{0,63}")
USERS = "users"


def space_name(owner: str) -> str:
    """The directory of a signed-in name's space: the name itself when it is a safe file name,
    else u- and a digest of it."""
    return owner if _OWNER.fullmatch(owner) else "u-" + hashlib.sha256(owner.encode()).hexdigest()[:16]


def space_dir(programs_dir: pathlib.Path, owner: str | None) -> pathlib.Path:
    """The folder of a space (owner None: the shared space)."""
    return programs_dir if owner is None else programs_dir / USERS / space_name(owner)


def stored_program(programs_dir: pathlib.Path, name: str, owner: str | None) -> dict:
    """A stored program of a space, for the gateway's own use (runs by library name).
    ValueError for a bad name or a file that is not a program; FileNotFoundError if absent."""
    if not _NAME.fullmatch(name):
        raise ValueError("bad program name %r" % name[:80])
    try:
        program = json.loads(_read_no_follow(space_dir(pathlib.Path(programs_dir), owner) / (name + ".json")))
    except IsADirectoryError:
        raise FileNotFoundError(name) from None
    if not isinstance(program, dict):
        raise ValueError("%r is not a program" % name)
    return program


def write_whole(path: pathlib.Path, data: bytes) -> None:
    """``data`` as the file at ``path``, whole or not at all: written beside it, then renamed over
    it, so a reader never sees half a file and a full disk leaves the old one."""
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=".tmp-", suffix=".json")
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data)
        os.replace(tmp, path)
    except BaseException:
        os.unlink(tmp)
        raise


def space_owner(identity, asked: str | None, verb: str = "open") -> str | None:
    """Whose space a request is about: an admin (or anyone, with auth off) names it (None: the
    shared space); anyone else gets their own and may not name someone else's."""
    if allowed(identity, Action.MANAGE, Area.PROGRAMS):
        return asked
    if asked is not None and asked != identity.owner:
        raise tornado.web.HTTPError(403, "%s may %s only their own programs" % (identity.name, verb))
    return identity.owner


class _Base(JsonHandler):
    identity = None      # who asks (set in prepare when auth is on); None: an admin

    def initialize(self, programs_dir: pathlib.Path, policy) -> None:
        self.programs_dir, self.policy = programs_dir, policy

    def prepare(self) -> None:
        """With auth on, every request needs a valid token; each name keeps to its own space."""
        self.identity = require(self, self.policy, Area.PROGRAMS)

    def _admin(self) -> bool:
        return allowed(self.identity, Action.MANAGE, Area.PROGRAMS)

    def _owner(self) -> str | None:
        """The space this request is about: ?owner= for an admin (none: the shared space), the
        caller's own for anyone else."""
        return space_owner(self.identity, self.get_query_argument("owner", None) or None)

    def _space(self, owner: str | None) -> pathlib.Path:
        return space_dir(self.programs_dir, owner)

    def _may_write(self) -> None:
        check_origin(self, self.policy)
        if not allowed(self.identity, Action.CHANGE, Area.PROGRAMS):
            raise tornado.web.HTTPError(403, "role %s may not save or delete programs" % self.identity.role)

    def _path(self, name: str) -> pathlib.Path:
        if not _NAME.fullmatch(name):
            raise tornado.web.HTTPError(400, "bad program name %r" % name[:80])
        return self._space(self._owner()) / (name + ".json")


class ProgramListHandler(_Base):
    def get(self) -> None:
        if not self._admin():
            spaces = [(self.identity.owner, self._space(self.identity.owner))]
        else:
            spaces = [(None, self.programs_dir)]
            users = self.programs_dir / USERS
            if users.is_dir() and not users.is_symlink():
                spaces += [(d.name, d) for d in sorted(users.iterdir()) if d.is_dir() and not d.is_symlink()]
        programs = []
        for owner, folder in spaces:
            if not folder.is_dir():
                continue
            for p in sorted(folder.glob("*.json")):
                if not _NAME.fullmatch(p.stem) or p.is_symlink():
                    continue
                st = p.stat()
                programs.append({"name": p.stem, "owner": owner, "size": st.st_size, "modified": st.st_mtime})
        self.finish(json.dumps({"programs": programs}))


class ProgramHandler(_Base):
    def get(self, name: str) -> None:
        path = self._path(name)
        try:
            data = _read_no_follow(path)
        except (FileNotFoundError, IsADirectoryError):
            raise tornado.web.HTTPError(404, "no program named %r" % name)
        self.finish(data)

    def put(self, name: str) -> None:
        self._may_write()
        path = self._path(name)
        program = body_json(self, MAX_PROGRAM_BYTES)
        data = json.dumps(program, separators=(",", ":")).encode()
        used = space_bytes(path.parent, besides=path)
        if used + len(data) > MAX_SPACE_BYTES:
            raise tornado.web.HTTPError(507, "this space holds %d bytes of programs; %d more would pass its "
                                             "%d bytes: delete some first" % (used, len(data), MAX_SPACE_BYTES))
        write_whole(path, data)
        self.finish(json.dumps({"name": name, "size": len(data)}))

    post = put

    def delete(self, name: str) -> None:
        self._may_write()
        path = self._path(name)
        try:
            path.unlink()
        except FileNotFoundError:
            raise tornado.web.HTTPError(404, "no program named %r" % name)
        self.set_status(204)
        self.clear_header("Content-Type")
        self.finish()


def space_bytes(folder: pathlib.Path, besides: pathlib.Path | None = None) -> int:
    """Bytes of the files in a space (its programs and unfinished saves), but ``besides`` (the
    program a save replaces)."""
    if not folder.is_dir():
        return 0
    total = 0
    with os.scandir(folder) as entries:
        for entry in entries:
            if entry.is_file(follow_symlinks=False) and entry.path != str(besides):
                total += entry.stat(follow_symlinks=False).st_size
    return total


def _read_no_follow(path: pathlib.Path) -> bytes:
    """A stored program's bytes; a symlink in the library is not a program (it could point anywhere)."""
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NOFOLLOW)
    except OSError as e:
        if e.errno == errno.ELOOP:
            raise FileNotFoundError(path) from None
        raise
    with os.fdopen(fd, "rb") as f:
        return f.read(MAX_PROGRAM_BYTES + 1)


def program_routes(programs_dir: pathlib.Path, policy) -> list:
    """Tornado URL specs for the program library stored in `programs_dir`; `policy` decides
    which browser origins may change it."""
    kw = {"programs_dir": pathlib.Path(programs_dir), "policy": policy}
    return [
        tornado.web.url(r"/api/programs/?", ProgramListHandler, kw),
        tornado.web.url(r"/api/programs/([^/]+)", ProgramHandler, kw),
    ]


def default_programs_dir() -> pathlib.Path:
    """Where programs live when no --programs-dir is given (XDG data dir)."""
    return data_dir("programs")
