"""gunicorn's settings for the study server, and its access log without secrets.

``study serve`` and the systemd unit run gunicorn with ``-c python:study_server.base.gunicorn_settings``, so gunicorn
never reads a ``gunicorn.conf.py`` from the working directory (it would run it), and with these settings:

- no control socket (by default one path per user, which every instance would take over and delete on exit);
- no X-Forwarded-* believed by gunicorn itself (by default it takes X-Forwarded-Proto from loopback): the app
  believes exactly SCENESUGGEST_PROXY_HOPS proxies, none by default;
- a folder of lock files shared by the workers (``on_starting``), so that at most half of them wait on http
  engines at once (``scenesuggest.engines.http.WaitSlots``);
- :class:`AccessLog`: an entry link's query carries Prolific's ``SESSION_ID`` (what resumes a session in another
  browser) and a pilot's signature, a one-time admin link carries its secret in its path, and a Referer repeats
  either; each request is logged as method, path and protocol with no query string, the one-time link's secret
  cut out (:func:`logged_path`), and no Referer, cookie or authorisation, whatever ``--access-logformat`` asks for.
"""

from __future__ import annotations

import os
import re
import shutil
import tempfile

from gunicorn.glogging import Logger

#: Paths that hold a secret after this prefix: the one-time admin sign-in link (``/admin/link/<secret>``).
SECRET_PATHS = ("/admin/link/",)

# --- gunicorn's settings (read with -c python:study_server.base.gunicorn_settings) -----------------------------------
logger_class = "study_server.base.gunicorn_settings.AccessLog"
control_socket_disable = True
forwarded_allow_ips = ""
secure_scheme_headers: dict = {}
access_log_format = '%(h)s - %(t)s "%(r)s" %(s)s %(b)s "%(a)s"'


def on_starting(server) -> None:
    """Before the workers start: a folder of their own for the locks that bound how many of them wait on http
    engines at once (``scenesuggest.engines.http.WaitSlots``), and their number, in the workers' environment."""
    os.environ[WAITS] = tempfile.mkdtemp(prefix="scenesuggest-engine-waits-")
    os.environ[WORKERS] = str(server.cfg.workers)


def on_exit(server) -> None:
    shutil.rmtree(os.environ.get(WAITS, ""), ignore_errors=True)


#: The environment variables on_starting sets for the workers (read by study_server.studies.served).
WAITS = "SCENESUGGEST_ENGINE_WAITS"
WORKERS = "SCENESUGGEST_WORKERS"


def logged_path(path: str) -> str:
    """``path`` as a log shows it: no query string, repeated slashes as one, a one-time link's secret replaced by
    ``[secret]``."""
    path = re.sub("/{2,}", "/", path.split("?", 1)[0]) or "/"
    for prefix in SECRET_PATHS:
        if path.startswith(prefix):
            return prefix + "[secret]"
    return path


class AccessLog(Logger):
    """gunicorn's logger keeping no secret (see the module docstring): the access log's atoms are an allowance —
    the client's address, the time, the method, path (:func:`logged_path`) and protocol, the status, the size, the
    user agent and the durations; any other (a header, an environment variable, the query, the user of a Basic
    authorisation) reads ``-`` — and a request named in an error message is named by its path alone."""

    def atoms(self, resp, req, environ, request_time):
        given = super().atoms(resp, req, environ, request_time)
        path = logged_path(environ.get("PATH_INFO") or "/")
        atoms = {k: given[k] for k in LOGGED if k in given}  # gunicorn reads any other atom as "-"
        atoms.update({"r": f"{environ.get('REQUEST_METHOD')} {path} {environ.get('SERVER_PROTOCOL')}", "U": path})
        return atoms

    def error(self, msg, *args, **kwargs):
        super().error(msg, *map(_unsecret, args), **kwargs)

    def exception(self, msg, *args, **kwargs):
        super().exception(msg, *map(_unsecret, args), **kwargs)


#: The access-log atoms logged as gunicorn gives them (see AccessLog).
LOGGED = ("h", "t", "s", "m", "H", "b", "B", "a", "T", "D", "M", "L", "p")


def _unsecret(value):
    """An error message's argument: a request URI (gunicorn names the request it failed on) as :func:`logged_path`."""
    return logged_path(value) if isinstance(value, str) and value.startswith("/") else value
