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
of ordinary ones); a save past it is refused with 507 and stores nothing. The files themselves
(names, spaces, whole writes) are ``lab.programs``'.
"""

from __future__ import annotations

import json
import pathlib

import tornado.web

from ..lab.programs import (MAX_PROGRAM_BYTES, MAX_SPACE_BYTES, NAME, USERS, read_no_follow, space_bytes, space_dir,
                            write_whole)
from ..rules.access import Action, Area, allowed
from .api import JsonHandler, body_json, check_origin, require


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
        if not NAME.fullmatch(name):
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
                if not NAME.fullmatch(p.stem) or p.is_symlink():
                    continue
                st = p.stat()
                programs.append({"name": p.stem, "owner": owner, "size": st.st_size, "modified": st.st_mtime})
        self.finish(json.dumps({"programs": programs}))


class ProgramHandler(_Base):
    def get(self, name: str) -> None:
        path = self._path(name)
        try:
            data = read_no_follow(path)
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


def program_routes(programs_dir: pathlib.Path, policy) -> list:
    """Tornado URL specs for the program library stored in `programs_dir`; `policy` decides
    which browser origins may change it."""
    kw = {"programs_dir": pathlib.Path(programs_dir), "policy": policy}
    return [
        tornado.web.url(r"/api/programs/?", ProgramListHandler, kw),
        tornado.web.url(r"/api/programs/([^/]+)", ProgramHandler, kw),
    ]
