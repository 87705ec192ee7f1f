"""The files a server for real needs, filled in for this installation (``scenesuggest study deploy-files``):
nginx in front (TLS, HTTP to HTTPS, static files, cached model assets, the app servers as one upstream), a
systemd unit per app server, and the app servers' environment file. The templates are in ``deploy/``; the same
function writes what the proxy test runs, so the configuration shipped is the one tested.
"""

from __future__ import annotations

import os
import re
import secrets
import sys
from dataclasses import dataclass, field
from pathlib import Path

from scenesuggest.errors import SceneSuggestError

from ..base import config
from ..base.importmap import three_folder

TEMPLATES = config.PACKAGE / "deploy"


class DeployError(SceneSuggestError):
    pass


#: The one rule for a path written into nginx's site, systemd's unit or the environment file: absolute, and only
#: characters none of them (nor a shell sourcing the environment file) reads as syntax: no whitespace, quotes,
#: ';', '{', '#', '$', '%', '\\' or control characters.
SAFE_PATH = re.compile(r"/[A-Za-z0-9._@+,=/-]*")
#: A system user name (useradd's pattern); root is refused: the app servers never run as root.
USER_NAME = re.compile(r"[a-z_][a-z0-9_-]{0,31}")
MAX_WORKERS = 64


def safe_path(value: str, field: str) -> str:
    if not SAFE_PATH.fullmatch(value) or "/../" in value + "/":
        raise DeployError(f"expected an absolute path of letters, digits and ._@+,=/- only (no spaces, quotes or "
                          f"control characters), got {value!r}", field=field)
    return value


@dataclass
class Deployment:
    """Where things are. Ports and addresses: nginx listens on ``http_port`` and ``https_port`` (of ``address``,
    all addresses by default); the app servers on 127.0.0.1 at ``app_ports``."""

    server_name: str
    app_ports: list[int] = field(default_factory=lambda: [8001, 8002])
    http_port: int = 80
    https_port: int = 443
    address: str = ""
    cert: str | None = None
    key: str | None = None
    nginx_dir: str = "/etc/nginx"
    cache: str = "/var/cache/nginx/scenesuggest"
    acme_root: str = "/var/www/letsencrypt"
    user: str = "scenesuggest"
    env_file: str = "/etc/scenesuggest/scenesuggest.env"
    workers: int = 2
    #: nginx's access log of the site and its format (``scenesuggest``: no query string, no secret, no Referer)
    access_log: str = "/var/log/nginx/access.log"
    access_log_format: str = "scenesuggest"
    #: nginx's error log of the site, at ``crit``: its messages at ``error`` (an app server that failed to answer)
    #: name the request line, query string and all
    error_log: str = "/var/log/nginx/error.log"

    def check(self) -> None:
        """Refuse, naming it, any value that would change the meaning of a file it lands in."""
        import ipaddress

        if not config.is_host_name(self.server_name):
            raise DeployError(config.HOST_NAME_RULE, field="--server-name")
        if not USER_NAME.fullmatch(self.user) or self.user == "root":
            raise DeployError("expected a system user name (lower-case letters, digits, '_' and '-'), not root: "
                              "the app servers run unprivileged", field="--user")
        if not 1 <= self.workers <= MAX_WORKERS:
            raise DeployError(f"expected 1 to {MAX_WORKERS} workers per app server", field="--workers")
        if self.address:
            try:
                ipaddress.ip_address(self.address)
            except ValueError:
                raise DeployError("expected an IP address to listen on", field="address") from None
        if not re.fullmatch(r"[a-z_]{1,32}", self.access_log_format):
            raise DeployError("expected the name of an nginx log format", field="access_log_format")
        for value, name in ((self.cert, "--cert"), (self.key, "--key"), (self.nginx_dir, "nginx_dir"),
                            (self.access_log, "access_log"), (self.error_log, "error_log"),
                            (self.cache, "cache"), (self.acme_root, "acme_root"), (self.env_file, "env_file"),
                            (sys.executable, "the Python running this"), (str(config.data_home()),
                                                                          "SCENESUGGEST_HOME")):
            if value is not None:
                safe_path(value, name)
        for study in config.study_files():
            safe_path(str(study.resolve()), "SCENESUGGEST_STUDIES")
        safe_path(str(config.PACKAGE / "static"), "the installed package's static folder")
        safe_path(str(three_folder()), "the installed three.js folder")
        ports = [self.http_port, self.https_port, *self.app_ports]
        if not self.app_ports or any(not 0 < p < 65536 for p in ports) or len(set(ports)) != len(ports):
            raise DeployError("expected distinct ports from 1 to 65535, one or more for app servers", field="--app")

    def values(self) -> dict[str, str]:
        listen = f"{self.address}:" if self.address else ""
        cert = self.cert or f"/etc/letsencrypt/live/{self.server_name}/fullchain.pem"
        key = self.key or f"/etc/letsencrypt/live/{self.server_name}/privkey.pem"
        return {
            "UPSTREAMS": "\n".join(f"    server 127.0.0.1:{p} max_fails=3 fail_timeout=10s;" for p in self.app_ports),
            "CACHE": self.cache, "HTTP_LISTEN": f"{listen}{self.http_port}",
            "HTTPS_LISTEN": f"{listen}{self.https_port}", "SERVER_NAME": self.server_name,
            "HTTP_LISTEN6": "" if self.address else f"    listen [::]:{self.http_port};\n",
            "HTTPS_LISTEN6": "" if self.address else f"    listen [::]:{self.https_port} ssl http2;\n",
            "HTTP_LISTEN6_DEFAULT": "" if self.address else f"    listen [::]:{self.http_port} default_server;\n",
            "HTTPS_LISTEN6_DEFAULT": "" if self.address else
            f"    listen [::]:{self.https_port} ssl http2 default_server;\n",
            "ACME_ROOT": self.acme_root, "HTTPS_PORT_SUFFIX": "" if self.https_port == 443 else f":{self.https_port}",
            "CERT": cert, "KEY": key, "STATIC": str(config.PACKAGE / "static"), "THREE": str(three_folder()),
            "NGINX_DIR": self.nginx_dir, "USER": self.user, "ENV_FILE": self.env_file, "PYTHON": sys.executable,
            "WORKERS": str(self.workers), "HOME": str(config.data_home()),
            "ACCESS_LOG": f"{self.access_log} {self.access_log_format}", "ERROR_LOG": self.error_log,
            "STUDIES": ":".join(str(p.resolve()) for p in config.study_files()), "SECRET": secrets.token_hex(32),
            "STUDY_DIRS": " ".join(sorted({str(p.resolve().parent) for p in config.study_files()}))}


#: Template → where it is written in the output folder (and whether it holds secrets).
FILES = {"nginx-site.conf": ("nginx/scenesuggest.conf", False),
         "proxy-params.conf": ("nginx/scenesuggest-proxy-params.conf", False),
         "scenesuggest@.service": ("systemd/scenesuggest@.service", False),
         "scenesuggest.env.in": ("scenesuggest.env", True)}


def fill(template: str, values: dict[str, str]) -> str:
    """``@@NAME@@`` replaced by its value (nginx's own ``$variables`` stay); every placeholder must be known."""
    unknown = sorted(set(re.findall(r"@@([A-Z0-9_]+)@@", template)) - set(values))
    if unknown:
        raise DeployError(f"template placeholders without a value: {', '.join(unknown)}")
    return re.sub(r"@@([A-Z0-9_]+)@@", lambda m: values[m.group(1)], template)


def write_deploy_files(out: str | Path, deployment: Deployment) -> list[Path]:
    """Write the filled files into ``out`` (absent or empty); returns them."""
    deployment.check()
    out = Path(out)
    if out.exists() and (not out.is_dir() or any(out.iterdir())):
        raise DeployError("already exists and is not an empty folder: nothing was written", file=str(out))
    values = deployment.values()
    written = []
    for template, (name, secret) in FILES.items():
        path = out / name
        path.parent.mkdir(parents=True, exist_ok=True)
        fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600 if secret else 0o644)
        with os.fdopen(fd, "w", encoding="utf-8") as f:
            f.write(fill((TEMPLATES / template).read_text(encoding="utf-8"), values))
        written.append(path)
    return written
