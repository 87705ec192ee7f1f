"""The backup file: one uncompressed tar archive holding ``MANIFEST.json`` and then the database.

The manifest says what made the backup (format, app version, schema revision, database kind, participants,
events, when) and the payload's size and SHA-256; reading a backup checks all of it before a byte of the payload
is used. The payload is a SQLite database file (``database.sqlite3``) or a ``pg_dump`` custom-format archive
(``database.pgdump``). A digest in the file proves the file is whole, not who wrote it: a backup is code for the
database that restores it, so it is kept where only the operator can write (the README says so); the restore
checks the schema it brings separately (``backup_schema``).
"""

from __future__ import annotations

import hashlib
import io
import json
import os
import tarfile
import time
from pathlib import Path

from scenesuggest.errors import SceneSuggestError

FORMAT = "scenesuggest-backup/1"
MANIFEST = "MANIFEST.json"
PAYLOAD = {"sqlite": "database.sqlite3", "postgresql": "database.pgdump"}
MAX_MANIFEST = 64 * 1024  # bytes; a manifest is a few hundred
CHUNK = 1 << 20


class BackupError(SceneSuggestError):
    pass


def sha256_of(path: Path) -> str:
    digest = hashlib.sha256()
    with path.open("rb") as f:
        while block := f.read(CHUNK):
            digest.update(block)
    return digest.hexdigest()


def write_archive(payload: Path, manifest: dict, out: Path) -> dict:
    """Write ``manifest`` (completed with the payload's name, size and digest) and ``payload`` into the tar file
    ``out`` (which exists, empty and private); returns the completed manifest."""
    manifest = {"format": FORMAT, **manifest, "payload": PAYLOAD[manifest["kind"]],
                "bytes": payload.stat().st_size, "sha256": sha256_of(payload)}
    body = json.dumps(manifest, indent=2, sort_keys=True).encode()
    with tarfile.open(out, "w", format=tarfile.PAX_FORMAT) as tar:
        info = tarfile.TarInfo(MANIFEST)
        info.size, info.mtime, info.mode = len(body), int(time.time()), 0o600
        tar.addfile(info, io.BytesIO(body))
        info = tarfile.TarInfo(manifest["payload"])
        info.size, info.mtime, info.mode = manifest["bytes"], int(time.time()), 0o600
        with payload.open("rb") as f:
            tar.addfile(info, f)
    return manifest


def _manifest(tar: tarfile.TarFile, where: str) -> dict:
    member = tar.next()
    if member is None or member.name != MANIFEST or not member.isreg() or member.size > MAX_MANIFEST:
        raise BackupError(f"not a backup written by 'study backup' (it starts with {MANIFEST})", file=where)
    try:
        manifest = json.loads(tar.extractfile(member).read())
    except (ValueError, UnicodeDecodeError):
        raise BackupError(f"{MANIFEST} is not JSON: the backup is damaged", file=where) from None
    if not isinstance(manifest, dict) or manifest.get("format") != FORMAT:
        raise BackupError(f"{MANIFEST} is not of the format {FORMAT!r}", file=where)
    wanted = {"kind": str, "revision": str, "participants": int, "events": int, "bytes": int, "sha256": str,
              "payload": str, "app_version": str}
    for key, kind in wanted.items():
        if not isinstance(manifest.get(key), kind) or isinstance(manifest.get(key), bool):
            raise BackupError(f"{MANIFEST}: field '{key}' is missing or not a {kind.__name__}", file=where)
    if manifest["kind"] not in PAYLOAD or manifest["payload"] != PAYLOAD[manifest["kind"]]:
        raise BackupError(f"{MANIFEST}: a {manifest['kind']!r} backup of {manifest['payload']!r} is not one of "
                          "ours", file=where)
    return manifest


def read_manifest(source: Path) -> dict:
    """The manifest of the backup ``source``, checked for form (not yet against its payload)."""
    where = str(source)
    _whole_file(source)
    try:
        with tarfile.open(source, "r:") as tar:
            return _manifest(tar, where)
    except (tarfile.TarError, EOFError, ValueError):
        raise BackupError("not a backup written by 'study backup' (not a whole tar archive)", file=where) from None


def _whole_file(source: Path) -> None:
    try:
        source.stat()
    except OSError as e:
        raise BackupError(f"cannot read: {e.strerror}", file=str(source)) from None
    if not source.is_file():
        raise BackupError("not a file", file=str(source))


def _holes(path: Path, start: int, length: int) -> bool:
    """Whether bytes ``start`` to ``start + length`` of the file ``path`` hold a hole (a sparse file's unwritten
    range, which reads as zeros and takes no disk; a compressing filesystem's data is not one). A filesystem
    that cannot tell holes reports none."""
    if length <= 0:
        return False
    with path.open("rb") as f:
        try:
            data = os.lseek(f.fileno(), start, os.SEEK_DATA)
        except OSError:  # no data from start on: a hole to the end (ENXIO)
            return True
        return data > start or os.lseek(f.fileno(), start, os.SEEK_HOLE) < start + length


def _payload(source: Path, check_head=None):
    """(manifest, the payload's blocks) of the backup ``source``, its members checked for form; the blocks are
    read as they are taken."""
    where = str(source)
    tar = tarfile.open(source, "r:")  # noqa: SIM115 - closed here on a refusal, else when the blocks are read
    try:
        manifest = _manifest(tar, where)
        member = tar.next()
        if member is None or member.name != manifest["payload"]:
            raise BackupError(f"the backup holds no {manifest['payload']} (is it cut short?)", file=where)
        if not member.isreg() or member.issparse() or member.size != manifest["bytes"]:
            raise BackupError(f"{member.name} is not the regular file of {manifest['bytes']} bytes the manifest "
                              "names", file=where)
        if member.size > source.stat().st_size:
            raise BackupError(f"{member.name} claims more bytes than the file holds", file=where)
        if _holes(source, member.offset_data, member.size):  # gigabytes that take no disk until written out
            raise BackupError(f"{member.name} claims {member.size} bytes, but the file has holes where they "
                              f"should be (it takes {source.stat().st_blocks * 512} bytes on disk): nothing is "
                              "expanded beyond the backup's real size; 'study backup' writes no holes", file=where)
    except BaseException:
        tar.close()
        raise

    def blocks():
        try:
            stream, left, first = tar.extractfile(member), member.size, True
            while left:
                block = stream.read(min(CHUNK, left))
                if not block:
                    raise BackupError(f"the backup is cut short ({left} bytes of {member.name} missing)",
                                      file=where)
                if first and check_head is not None:
                    check_head(block[:4096], member.size)
                first = False
                left -= len(block)
                yield block
            if tar.next() is not None:
                raise BackupError(f"the backup holds more than {MANIFEST} and {member.name}", file=where)
        finally:
            tar.close()
    return manifest, blocks()


def extract_payload(source: Path, into: Path, check_head=None) -> dict:
    """Copy the backup's database out of ``source`` into the existing private file ``into``, after a first,
    read-only pass has checked its size and SHA-256 against the manifest (so a damaged, changed or forged file
    writes nothing); ``check_head(first_bytes, size)`` may refuse the payload from its first 4 kB. Returns the
    manifest."""
    where = str(source)
    _whole_file(source)
    try:
        manifest, blocks = _payload(source, check_head)
        digest = hashlib.sha256()
        for block in blocks:
            digest.update(block)
        if digest.hexdigest() != manifest["sha256"]:
            raise BackupError(f"{manifest['payload']} does not match its SHA-256 in {MANIFEST}: the backup was "
                              "changed or damaged after it was written; nothing was restored", file=where)
        manifest, blocks = _payload(source)
        with into.open("r+b") as out:
            for block in blocks:
                out.write(block)
            out.truncate()
            out.flush()
            os.fsync(out.fileno())
    except (tarfile.TarError, EOFError, ValueError, OSError) as e:
        if isinstance(e, OSError) and not isinstance(e, tarfile.TarError) and e.errno is not None:
            raise BackupError(f"cannot read: {e.strerror}", file=where) from None
        raise BackupError("not a backup written by 'study backup' (not a whole tar archive)", file=where) from None
    return manifest
