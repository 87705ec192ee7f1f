"""Configuration from the environment and the instance folder (never read at import time).

| variable | meaning | default |
|---|---|---|
| ``SCENESUGGEST_STUDIES`` | study files, separated by ``:`` | the built-in demo study (``study_server/demo``) |
| ``SCENESUGGEST_HOME`` | the server's data folder: instance folder, and the priors and model libraries that \
study files name by corpus only | ``var/`` of the checkout; installed: ``var/scenesuggest`` in the Python prefix |
| ``DATABASE_URL`` | SQLAlchemy URL (``postgresql+psycopg://…`` to scale) | SQLite file in the instance folder |
| ``SCENESUGGEST_INSTANCE`` | instance folder (database, secret key, admin password) | ``instance/`` of the home |
| ``SCENESUGGEST_SECRET_KEY`` | signs cookies | generated once into the instance folder |
| ``SCENESUGGEST_ADMIN_PASSWORD_HASH`` | werkzeug hash of the admin password | ``instance/admin.json`` |
| ``SCENESUGGEST_FRAME_ANCESTORS`` | CSP frame-ancestors, for platforms that embed the study | ``'self'`` |
| ``SCENESUGGEST_PROXY_HOPS`` | how many reverse proxies stand before the app: their ``X-Forwarded-For``, \
``-Proto`` and ``-Port`` are believed for that many hops, no more (the client's address for rate limits, \
``https`` for URLs; an entry that is not an IP address counts for nothing); ``X-Forwarded-Host`` never \
(the proxy's ``Host`` is used). ``study serve`` refuses hops on an address beyond loopback (anyone reaching the \
port could claim any address) | ``0``: none believed |
| ``SCENESUGGEST_SERVER_NAME`` | the study's public host name: requests naming another host get 400, and links \
the app writes (the admin's participant link) name this one (``localhost`` and ``127.0.0.1`` also answer, \
for checks on the host itself) | any host |
| ``SCENESUGGEST_WARM`` | ``1``: each app process loads every study's priors, library and engines before its \
first request (``study serve`` sets it unless set; commands that do not serve never warm); ``0``: on first use \
| ``1`` in production, else ``0`` |
| ``SCENESUGGEST_ENV`` | ``development`` or ``production`` (a secret key from the environment is then required, \
cookies are ``Secure``) | ``development`` |
"""

from __future__ import annotations

import json
import os
import re
import secrets
import sys
from pathlib import Path

from scenesuggest.errors import SceneSuggestError

PACKAGE = Path(__file__).resolve().parents[1]  # the study_server package
MIGRATIONS = PACKAGE / "migrations"
DEFAULT_STUDY = PACKAGE / "demo" / "study.toml"
ADMIN_FILE = "admin.json"
PASSWORD_FILE = "admin-password.txt"


def checkout() -> Path | None:
    """The source checkout the package runs from (an editable install), or None when it is installed."""
    root = PACKAGE.parent
    return root if (root / "pyproject.toml").is_file() else None


def part_of_the_package(path: Path) -> bool:
    """Whether ``path`` belongs to the installed package (a study that ships with it, such as the built-in demo):
    such files are read-only, as a reinstall would overwrite them. In a checkout they are the project's source."""
    return checkout() is None and Path(path).resolve().is_relative_to(PACKAGE)


def data_home() -> Path:
    """Where the server keeps its data: ``SCENESUGGEST_HOME``, else ``var/`` of the checkout it runs from, else
    ``var/scenesuggest`` under the Python prefix (the virtual environment it is installed in), as Flask places
    the instance folders of installed packages."""
    if os.environ.get("SCENESUGGEST_HOME"):
        return Path(os.environ["SCENESUGGEST_HOME"]).resolve()
    root = checkout()
    return root / "var" if root is not None else Path(sys.prefix) / "var" / "scenesuggest"


def study_files() -> list[Path]:
    """The study files the server runs: ``SCENESUGGEST_STUDIES`` (separated by ``:``), else the built-in demo."""
    studies = os.environ.get("SCENESUGGEST_STUDIES")
    return [Path(p) for p in studies.split(":") if p] if studies else [DEFAULT_STUDY]


def instance_path() -> Path:
    return Path(os.environ.get("SCENESUGGEST_INSTANCE") or data_home() / "instance").resolve()


def absolute_sqlite(url: str, base: Path) -> str:
    """``url`` with a relative SQLite path made absolute against ``base`` (other URLs as they are)."""
    from sqlalchemy.engine import make_url

    if not url.startswith("sqlite"):
        return url
    parsed = make_url(url)
    name = parsed.database
    if not name or name == ":memory:" or name.startswith("file:") or Path(name).is_absolute():
        return url
    return parsed.set(database=str((base / name).resolve())).render_as_string(hide_password=False)


class ConfigError(SceneSuggestError):
    """A setting that stops the server from starting; the message names the variable."""


ENVIRONMENTS = ("development", "production")
MIN_SECRET = 32
MAX_PROXY_HOPS = 5


#: A host name: dot-separated labels of 1 to 63 letters, digits and '-' (not first or last), at most 253 characters
#: in all; no empty label (a leading '.' is a wildcard to Flask's trusted hosts and nginx), no lone '-'.
HOST_LABEL = re.compile(r"(?!-)[A-Za-z0-9-]{1,63}(?<!-)")
HOST_NAME_RULE = ("expected the public host name: labels of letters, digits and '-' (not first or last) joined by "
                  "single dots, e.g. study.example.org")


def is_host_name(value: str) -> bool:
    """Whether ``value`` is a host name by :data:`HOST_LABEL` (an IPv4 address is one)."""
    return 0 < len(value) <= 253 and all(HOST_LABEL.fullmatch(label) for label in value.split("."))


def from_environment(instance: Path) -> dict:
    """The app's settings as a Flask config dict. In production the secret key must come from the environment
    (a generated one would differ between hosts and vanish with the instance folder) and cookies are Secure."""
    instance.mkdir(mode=0o700, parents=True, exist_ok=True)
    env = os.environ.get("SCENESUGGEST_ENV", "development")
    if env not in ENVIRONMENTS:
        raise ConfigError(f"must be one of {', '.join(ENVIRONMENTS)}", field="SCENESUGGEST_ENV")
    production = env == "production"
    if production and len(os.environ.get("SCENESUGGEST_SECRET_KEY", "")) < MIN_SECRET:
        raise ConfigError(f"production needs a secret key of at least {MIN_SECRET} characters in the environment "
                          "(e.g. python -c 'import secrets; print(secrets.token_hex(32))')",
                          field="SCENESUGGEST_SECRET_KEY")
    hops = os.environ.get("SCENESUGGEST_PROXY_HOPS", "0")
    if not hops.isdigit() or int(hops) > MAX_PROXY_HOPS:
        raise ConfigError(f"expected the number of reverse proxies before the app, 0 to {MAX_PROXY_HOPS}",
                          field="SCENESUGGEST_PROXY_HOPS")
    server_name = os.environ.get("SCENESUGGEST_SERVER_NAME", "")
    if server_name and not is_host_name(server_name):
        raise ConfigError(HOST_NAME_RULE, field="SCENESUGGEST_SERVER_NAME")
    warm = os.environ.get("SCENESUGGEST_WARM", "1" if production else "0")
    if warm not in ("0", "1"):
        raise ConfigError("expected 1 (load every study's resources before the first request) or 0",
                          field="SCENESUGGEST_WARM")
    return {
        "ENV_NAME": env,
        "WARM_STUDIES": warm == "1",
        "PROXY_HOPS": int(hops),
        "TRUSTED_HOSTS": [server_name, "localhost", "127.0.0.1"] if server_name else None,
        "DEBUG": False,
        "SESSION_COOKIE_SECURE": production,
        "STUDY_FILES": study_files(),
        "SQLALCHEMY_DATABASE_URI": os.environ.get("DATABASE_URL") or f"sqlite:///{instance / 'studies.sqlite3'}",
        "SECRET_KEY": os.environ.get("SCENESUGGEST_SECRET_KEY") or _secret_key(instance),
        "ADMIN_PASSWORD_HASH": os.environ.get("SCENESUGGEST_ADMIN_PASSWORD_HASH") or _admin_hash(instance),
        "FRAME_ANCESTORS": os.environ.get("SCENESUGGEST_FRAME_ANCESTORS", "'self'"),
        "MAX_CONTENT_LENGTH": 1024 * 1024,
        "SESSION_COOKIE_HTTPONLY": True,
        "SESSION_COOKIE_SAMESITE": "Lax",
    }


def _secret_key(instance: Path) -> str:
    path = instance / "secret_key"
    if not path.exists():
        try:
            fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
            with os.fdopen(fd, "w") as f:
                f.write(secrets.token_hex(32))
        except FileExistsError:  # another worker wrote it first
            pass
    return path.read_text().strip()


def _admin_hash(instance: Path) -> str | None:
    path = instance / ADMIN_FILE
    if path.exists():
        return json.loads(path.read_text()).get("password_hash")
    return None


def ensure_admin_password(instance: Path) -> Path | None:
    """Create an admin password on first run (hash in admin.json, the password itself in a 0600 file whose
    path is printed by ``make serve``); returns the password file when one was created or still exists."""
    from werkzeug.security import generate_password_hash

    instance.mkdir(mode=0o700, parents=True, exist_ok=True)
    if os.environ.get("SCENESUGGEST_ADMIN_PASSWORD_HASH"):
        return None
    for secret in (instance / ADMIN_FILE, instance / PASSWORD_FILE):  # made by an older version: keep them private
        if secret.exists() and secret.stat().st_uid == os.getuid():
            secret.chmod(0o600)
    if not (instance / ADMIN_FILE).exists():
        password = secrets.token_urlsafe(12)
        fd = os.open(instance / PASSWORD_FILE, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
        with os.fdopen(fd, "w") as f:
            f.write(password + "\n")
        fd = os.open(instance / ADMIN_FILE, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
        with os.fdopen(fd, "w") as f:
            f.write(json.dumps({"password_hash": generate_password_hash(password)}))
    return instance / PASSWORD_FILE if (instance / PASSWORD_FILE).exists() else None
