"""The program library's storage: block programs as JSON files under one directory, a space per
signed-in name (``users/NAME/``; the shared space at the top). What a name and a file may be, where a
space is, a stored program read for the gateway's own use (runs by library name), a file written
whole, and a space's bytes. The HTTP API, and whose space a request may open, are ``web.programs``.
"""

from __future__ import annotations

import errno
import hashlib
import json
import os
import pathlib
import re
import tempfile

from ..settings import data_dir

MAX_PROGRAM_BYTES = 2 * 1024 * 1024
MAX_SPACE_BYTES = 32 * 1024 * 1024
NAME = re.compile(r"[A-Za-z0-9_-][A-Za-z0-9 _-]{0,63}")
OWNER = re.compile(r"[A-Za-z0-9_-][A-Za-z0-9_.@-]{0,63}")
USERS = "users"


def space_name(owner: str) -> str:
    """The directory of a signed-in name's space: the name itself when it is a safe file name,
    else u- and a digest of it."""
    return owner if OWNER.fullmatch(owner) else "u-" + hashlib.sha256(owner.encode()).hexdigest()[:16]


def space_dir(programs_dir: pathlib.Path, owner: str | None) -> pathlib.Path:
    """The folder of a space (owner None: the shared space)."""
    return programs_dir if owner is None else programs_dir / USERS / space_name(owner)


def stored_program(programs_dir: pathlib.Path, name: str, owner: str | None) -> dict:
    """A stored program of a space, for the gateway's own use (runs by library name).
    ValueError for a bad name or a file that is not a program; FileNotFoundError if absent."""
    if not NAME.fullmatch(name):
        raise ValueError("bad program name %r" % name[:80])
    try:
        program = json.loads(read_no_follow(space_dir(pathlib.Path(programs_dir), owner) / (name + ".json")))
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


def read_no_follow(path: pathlib.Path) -> bytes:
    """A stored program's bytes; a symlink in the library is not a program (it could point anywhere)."""
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NOFOLLOW)
    except OSError as e:
        if e.errno == errno.ELOOP:
            raise FileNotFoundError(path) from None
        raise
    with os.fdopen(fd, "rb") as f:
        return f.read(MAX_PROGRAM_BYTES + 1)


def default_programs_dir() -> pathlib.Path:
    """Where programs live when no --programs-dir is given (XDG data dir)."""
    return data_dir("programs")
