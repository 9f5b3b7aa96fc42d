"""The program library: block programs stored as JSON files under one directory.

GET    /api/programs          -> {"programs": [{"name", "size", "modified"}, ...]}
GET    /api/programs/NAME     -> the stored program (JSON)
PUT    /api/programs/NAME     -> store the request body (a JSON object); 200 {"name", "size"}
DELETE /api/programs/NAME     -> 204

NAME: 1-64 characters of letters, digits, space, '_' and '-', not starting with a space.
Anything else is refused with 400 before the file system is touched.
"""

from __future__ import annotations

import errno
import json
import os
import pathlib
import re
import tempfile

import tornado.web

MAX_PROGRAM_BYTES = 2 * 1024 * 1024
_NAME = re.compile(r"[A-Za-z0-9_-][A-Za-z0-9 _-]{0,63}")


class _Base(tornado.web.RequestHandler):
    def initialize(self, programs_dir: pathlib.Path) -> None:
        self.programs_dir = programs_dir

    def set_default_headers(self) -> None:
        self.set_header("Content-Type", "application/json; charset=utf-8")
        self.set_header("Cache-Control", "no-store")

    def write_error(self, status_code: int, **kwargs) -> None:
        reason = self._reason
        exc = kwargs.get("exc_info")
        if exc and isinstance(exc[1], tornado.web.HTTPError) and exc[1].log_message:
            reason = exc[1].log_message
        self.finish(json.dumps({"error": reason, "status": status_code}))

    def _path(self, name: str) -> pathlib.Path:
        if not _NAME.fullmatch(name):
            raise tornado.web.HTTPError(400, "bad program name %r" % name[:80])
        return self.programs_dir / (name + ".json")


class ProgramListHandler(_Base):
    def get(self) -> None:
        programs = []
        if self.programs_dir.is_dir():
            for p in sorted(self.programs_dir.glob("*.json")):
                if not _NAME.fullmatch(p.stem) or p.is_symlink():
                    continue
                st = p.stat()
                programs.append({"name": p.stem, "size": st.st_size, "modified": st.st_mtime})
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
        path = self._path(name)
        body = self.request.body
        if len(body) > MAX_PROGRAM_BYTES:
            raise tornado.web.HTTPError(413, "program larger than %d bytes" % MAX_PROGRAM_BYTES)
        try:
            program = json.loads(body)
        except ValueError as e:
            raise tornado.web.HTTPError(400, "body is not JSON: %s" % e)
        if not isinstance(program, dict):
            raise tornado.web.HTTPError(400, "a program is a JSON object")
        data = json.dumps(program, separators=(",", ":")).encode()
        self.programs_dir.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=self.programs_dir, prefix=".tmp-", suffix=".json")
        try:
            with os.fdopen(fd, "wb") as f:
                f.write(data)
            os.replace(tmp, path)
        except BaseException:
            os.unlink(tmp)
            raise
        self.finish(json.dumps({"name": name, "size": len(data)}))

    post = put

    def delete(self, name: str) -> None:
        path = self._path(name)
        try:
            path.unlink()
        except FileNotFoundError:
            raise tornado.web.HTTPError(404, "no program named %r" % name)
        self.set_status(204)
        self.clear_header("Content-Type")
        self.finish()


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


def program_routes(programs_dir: pathlib.Path) -> list:
    """Tornado URL specs for the program library stored in `programs_dir`."""
    kw = {"programs_dir": pathlib.Path(programs_dir)}
    return [
        tornado.web.url(r"/api/programs/?", ProgramListHandler, kw),
        tornado.web.url(r"/api/programs/([^/]+)", ProgramHandler, kw),
    ]


def default_programs_dir() -> pathlib.Path:
    """Where programs live when no --programs-dir is given (XDG data dir)."""
    base = os.environ.get("XDG_DATA_HOME") or os.path.join(os.path.expanduser("~"), ".local", "share")
    return pathlib.Path(base) / "rosgate" / "programs"
