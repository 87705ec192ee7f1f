"""Writing a file, or a whole folder, so that a reader sees either the old or the new content, never half of either.

What is written gets the permissions a plain ``open`` or ``mkdir`` would give (the system applies the process's
umask), or keeps those of the file it replaces — never a private mode of its own, so a server running as another
user of the same group can read what ``priors train`` or ``assets build`` wrote. A path that is a symbolic link is
written through: the file it points to is replaced.
"""

from __future__ import annotations

import os
import secrets
from pathlib import Path


def _beside(path: Path) -> Path:
    return path.parent / f".{path.name}-{secrets.token_hex(6)}"


def write_atomically(path: str | Path, data: bytes) -> Path:
    """Write ``data`` to a temporary file beside ``path``, flush it to disk and rename it over ``path``; on any
    failure the temporary file is removed and ``path`` is left as it was."""
    path = Path(path)
    if path.is_symlink():
        path = path.resolve()
    mode = path.stat().st_mode & 0o7777 if path.exists() else None
    tmp = _beside(path)
    fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666)
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
        if mode is not None:
            os.chmod(tmp, mode)
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    return path


def temporary_folder_beside(target: Path) -> Path:
    """An empty folder beside ``target`` to build it in, then rename over it (made as ``mkdir`` would make it)."""
    target.parent.mkdir(parents=True, exist_ok=True)
    tmp = _beside(target)
    tmp.mkdir(0o777)
    return tmp
