"""Writing a file, or a whole folder, so that a reader sees either the old or the new content, never half of either.

What is written gets the permissions a plain ``open`` or ``mkdir`` would give (the process's umask applied), or
keeps those of the file it replaces — never the private mode of the temporary file it was written as, so a server
running as another user of the same group can read what ``priors train`` or ``assets build`` wrote.
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path


def umask() -> int:
    """The process's file-creation mask (read without changing it, where the system tells; else the usual 0o022)."""
    try:
        for line in Path("/proc/self/status").read_text().splitlines():
            if line.startswith("Umask:"):
                return int(line.split()[1], 8)
    except (OSError, ValueError):
        pass
    return 0o022


def write_atomically(path: str | Path, data: bytes) -> Path:
    """Write ``data`` to a temporary file beside ``path``, flush it to disk and rename it over ``path``; on any
    failure the temporary file is removed and ``path`` is left as it was."""
    path = Path(path)
    mode = path.stat().st_mode & 0o7777 if path.exists() else 0o666 & ~umask()
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}-")
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
        os.chmod(tmp, mode)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return path


def temporary_folder_beside(target: Path) -> Path:
    """An empty folder beside ``target`` to build it in, then rename over it; with the mode ``mkdir`` would give."""
    target.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(dir=target.parent, prefix=f".{target.name}-"))
    tmp.chmod(0o777 & ~umask())
    return tmp
