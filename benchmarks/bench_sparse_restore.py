"""A restore's peak disk use for a sparse backup: a backup of a few hundred kB on disk whose database claims
``--gigabytes`` (a real SQLite header, then holes; the manifest's size and SHA-256 recomputed, as anyone who can
write the file can). ``study restore`` runs in a subprocess of the checkout measured while this process samples the
bytes on disk under the target's folder (its scratch copies) every 10 ms; prints the peak, the refusal and the time.
``--baseline DIR`` (a git worktree of an earlier revision) measures that revision in the same run.

Usage: .venv/bin/python benchmarks/bench_sparse_restore.py [--gigabytes 1] [--baseline DIR]
"""

from __future__ import annotations

import argparse
import contextlib
import hashlib
import json
import os
import subprocess
import sys
import tarfile
import tempfile
import time
from pathlib import Path

import checkout
import tests_path  # noqa: F401 (tests/ on the path, for the shared test infrastructure)

ROOT = Path(__file__).resolve().parents[1]


def sparse_backup(folder: Path, claimed: int) -> Path:
    """A backup of a real (empty, migrated) database's first page and ``claimed`` bytes in all, holes after it."""
    from demostudy import make_app

    from study_server.experimenter.backup import backup

    app = make_app(folder / "source")  # migrated: the scratch database whose first page is taken
    made = backup(app.config["SQLALCHEMY_DATABASE_URI"], folder / "real.backup")
    with tarfile.open(folder / "real.backup") as tar:
        head = bytearray(tar.extractfile("database.sqlite3").read(4096))
    head[28:32] = (claimed // 4096).to_bytes(4, "big")
    digest, zeros = hashlib.sha256(bytes(head)), bytes(1 << 20)
    left = claimed - len(head)
    while left:
        digest.update(zeros[:min(left, len(zeros))])
        left -= min(left, len(zeros))
    manifest = json.dumps({"format": "scenesuggest-backup/1", "kind": "sqlite", "payload": "database.sqlite3",
                           **{k: made[k] for k in ("revision", "participants", "events", "app_version")},
                           "bytes": claimed, "sha256": digest.hexdigest()}).encode()
    out = folder / "sparse.backup"
    with out.open("wb") as f:
        for name, size, body in (("MANIFEST.json", len(manifest), manifest), ("database.sqlite3", claimed, head)):
            info = tarfile.TarInfo(name)
            info.size = size
            f.write(info.tobuf(tarfile.PAX_FORMAT))
            f.write(bytes(body) + bytes(-len(body) % 512))
            if name != "MANIFEST.json":
                f.seek(size - len(body) + (-size % 512), 1)
        f.write(bytes(1024))
    return out


def on_disk(folder: Path) -> int:
    total = 0
    for root, _, files in os.walk(folder):
        for name in files:
            with contextlib.suppress(FileNotFoundError):  # a scratch file removed meanwhile
                total += os.lstat(os.path.join(root, name)).st_blocks * 512
    return total


def measure(root: Path, source: Path, folder: Path) -> dict:
    target = folder / f"target-{root.name}"
    target.mkdir()
    start = time.perf_counter()
    proc = subprocess.Popen([sys.executable, "-m", "scenesuggest.cli", "study", "restore", str(source), "--db",
                             f"sqlite:///{target / 'restored.sqlite3'}"], env=checkout.env_for(root),
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=folder)  # -m: cwd first
    peak = 0
    while proc.poll() is None:
        peak = max(peak, on_disk(target))
        time.sleep(0.01)
    _, err = proc.communicate()
    return {"exit": proc.returncode, "peak_disk_mb": round(peak / 2**20, 1), "seconds": round(time.perf_counter() -
            start, 2), "said": (err.strip().splitlines() or [""])[-1][:200]}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--gigabytes", type=float, default=1.0)
    parser.add_argument("--baseline", help="another checkout to measure in the same run")
    args = parser.parse_args()
    checkout.require(ROOT)
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        source = sparse_backup(tmp, int(args.gigabytes * 2**30) // 4096 * 4096)
        out = {"benchmark": "sparse_restore", "backup_on_disk_kb": round(source.stat().st_blocks * 512 / 1024),
               "claimed_mb": round(args.gigabytes * 1024), "this": measure(ROOT, source, tmp)}
        if args.baseline:
            out["baseline"] = {"checkout": args.baseline, **measure(Path(args.baseline), source, tmp)}
    print(json.dumps(out, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
