"""Running behind a reverse proxy: ``/healthz`` and the proxy hops the app believes (in process; the nginx test
puts a real proxy in front)."""

import json
import os
import subprocess

import pytest
from demostudy import make_app
from flowhelp import csrf
from integrityhelp import PASSWORD
from support import lacking
from werkzeug.security import generate_password_hash


def test_healthz_says_ok_and_names_what_is_wrong_without_secrets(tmp_path, demo_resources):
    from flask_migrate import downgrade
    from sqlalchemy import text

    from study_server import MIGRATIONS
    from study_server.base.extensions import db

    app = make_app(tmp_path)
    c = app.test_client()
    r = c.get("/healthz")
    assert r.status_code == 200 and r.headers["Cache-Control"] == "no-store"
    assert r.json == {"ok": True, "database": "ok", "schema": "ok", "studies": {"demo": "ok"},
                      "engines": {"demo": {"paper": {"version": "1", "status": "not loaded yet"}}}}
    with app.app_context():
        downgrade(directory=str(MIGRATIONS), revision="-1")
    r = c.get("/healthz")
    assert r.status_code == 503 and r.json["schema"] == "behind: run 'scenesuggest study migrate'"
    with app.app_context():
        db.session.execute(text("DROP TABLE alembic_version"))
        db.session.commit()
    assert c.get("/healthz").json["schema"] == "not migrated"
    text_ = json.dumps(c.get("/healthz").json)
    assert str(tmp_path) not in text_ and "sqlite" not in text_.lower()


def test_healthz_names_a_study_whose_priors_cannot_be_loaded(tmp_path, demo_resources):
    import shutil

    from demostudy import DEMO_STUDY

    from study_server.base.config import data_home

    folder = tmp_path / "study"
    shutil.copytree(DEMO_STUDY.parent, folder)
    (folder / "bad.npz").write_bytes(b"not a priors file")
    study_file = folder / "study.toml"
    study_file.write_text(study_file.read_text().replace(
        '[resources]\ncorpus = "ai2thor"\n',
        f'[resources]\ncorpus = "ai2thor"\npriors = "bad.npz"\nlibrary = "{data_home() / "library" / "ai2thor"}"\n'))
    app = make_app(tmp_path, studies=[study_file], CHECK_RESOURCES=False)
    r = app.test_client().get("/healthz")
    assert r.status_code == 503 and r.json["studies"]["demo"].startswith("unavailable (")
    assert r.json["database"] == "ok" and "bad.npz" not in r.get_data(as_text=True)


@pytest.mark.parametrize("hops", [0, 1])
def test_the_app_believes_exactly_the_configured_proxy_hops(tmp_path, demo_resources, hops):
    """One proxy appends the address it saw to X-Forwarded-For; a client's own entries before it count for
    nothing. Without a proxy configured, the header counts for nothing at all."""
    from flask import request, url_for

    app = make_app(tmp_path, PROXY_HOPS=hops, ADMIN_PASSWORD_HASH=generate_password_hash(PASSWORD))
    app.add_url_rule("/whoami", "whoami", lambda: f"{url_for('health.healthz', _external=True)[:-7]} "
                                                  f"{request.remote_addr}")

    def guess(spoofed, proxy_saw="203.0.113.9", password="guess"):
        c = app.test_client()
        c.environ_base["REMOTE_ADDR"] = "127.0.0.1"  # the proxy
        headers = {"X-Forwarded-For": f"{spoofed}, {proxy_saw}", "X-Forwarded-Proto": "https"}
        page = c.get("/admin/login", headers=headers)
        return c.post("/admin/login", headers=headers,
                      data={"csrf_token": csrf(page), "password": password}).status_code

    assert [guess(f"198.51.100.{i}") for i in range(7)] == [401] * 5 + [429] * 2  # spoofing buys no guesses
    # another client behind the same proxy is another client only when the proxy is believed
    assert guess("x", proxy_saw="192.0.2.7", password=PASSWORD) == (302 if hops else 429)
    c = app.test_client()
    c.environ_base["REMOTE_ADDR"] = "127.0.0.1"
    seen = c.get("/whoami", headers={"X-Forwarded-For": "198.51.100.1, 192.0.2.1", "X-Forwarded-Proto": "https",
                                     "Host": "study.example", "X-Forwarded-Host": "evil.example"}
                 ).get_data(as_text=True)  # the proxy sets Host; a forwarded host is never believed
    assert seen == ("https://study.example/ 192.0.2.1" if hops else "http://study.example/ 127.0.0.1")


def test_only_an_ip_address_keys_a_quota_and_only_the_server_name_is_answered(tmp_path, demo_resources):
    """An X-Forwarded-For entry that is not an address counts for nothing (the connecting address is used); with
    SCENESUGGEST_SERVER_NAME set, a request naming another host is refused and links name the server."""
    from flask import url_for

    from study_server.base.security import client_ip

    app = make_app(tmp_path, PROXY_HOPS=1, TRUSTED_HOSTS=["study.example", "localhost", "127.0.0.1"])
    app.add_url_rule("/whoami", "whoami", lambda: f"{url_for('health.healthz', _external=True)} {client_ip()}")
    c = app.test_client()
    c.environ_base["REMOTE_ADDR"] = "127.0.0.1"
    for claimed in ("anything at all", "999.1.1.1", "' OR 1=1 --", "x" * 500):
        seen = c.get("/whoami", headers={"X-Forwarded-For": claimed, "Host": "study.example"})
        assert seen.get_data(as_text=True) == "http://study.example/healthz 127.0.0.1", claimed
    seen = c.get("/whoami", headers={"X-Forwarded-For": "2001:db8::7", "Host": "study.example"})
    assert seen.get_data(as_text=True).endswith(" 2001:db8::7")
    for host in ("evil.example", "study.example.evil.example", "study.example@evil.example"):
        assert c.get("/healthz", headers={"Host": host}).status_code == 400, host
    assert c.get("/healthz", headers={"Host": "127.0.0.1:8001"}).status_code == 200  # a check on the host itself


def test_serve_refuses_believed_proxies_on_an_address_beyond_loopback(tmp_path, monkeypatch):
    monkeypatch.setenv("SCENESUGGEST_PROXY_HOPS", "1")
    monkeypatch.setenv("SCENESUGGEST_INSTANCE", str(tmp_path / "instance"))
    from click.testing import CliRunner

    from scenesuggest.cli import main

    monkeypatch.setattr(os, "execv", lambda *args: pytest.fail(f"served: {args}"))  # never replace this process
    for host in ("0.0.0.0", "::", "192.0.2.10", "study.example.org"):
        done = CliRunner().invoke(main, ["study", "serve", "--no-prepare", "--host", host, "--port", "1"])
        assert done.exit_code == 2 and "SCENESUGGEST_PROXY_HOPS=1" in done.output and "--host" in done.output, (
            host, done.output)
    monkeypatch.setenv("SCENESUGGEST_SERVER_NAME", "bad name")
    from study_server.base.config import ConfigError, from_environment

    with pytest.raises(ConfigError) as info:
        from_environment(tmp_path / "instance")
    assert info.value.field == "SCENESUGGEST_SERVER_NAME"


def test_proxy_hops_must_be_a_small_number(monkeypatch, tmp_path):
    from study_server.base.config import ConfigError, from_environment

    for bad in ("one", "-1", "9"):
        monkeypatch.setenv("SCENESUGGEST_PROXY_HOPS", bad)
        with pytest.raises(ConfigError) as info:
            from_environment(tmp_path / "instance")
        assert info.value.field == "SCENESUGGEST_PROXY_HOPS"
    monkeypatch.setenv("SCENESUGGEST_PROXY_HOPS", "2")
    assert from_environment(tmp_path / "instance")["PROXY_HOPS"] == 2


def test_warm_defaults_on_in_production_only_and_must_be_0_or_1(monkeypatch, tmp_path):
    from study_server.base.config import ConfigError, from_environment

    monkeypatch.delenv("SCENESUGGEST_WARM", raising=False)
    assert from_environment(tmp_path / "instance")["WARM_STUDIES"] is False
    monkeypatch.setenv("SCENESUGGEST_ENV", "production")
    monkeypatch.setenv("SCENESUGGEST_SECRET_KEY", "k" * 64)
    assert from_environment(tmp_path / "instance")["WARM_STUDIES"] is True
    for bad in ("yes", "2", ""):
        monkeypatch.setenv("SCENESUGGEST_WARM", bad)
        with pytest.raises(ConfigError) as info:
            from_environment(tmp_path / "instance")
        assert info.value.field == "SCENESUGGEST_WARM"


def test_a_warmed_app_answers_the_first_suggestion_without_loading_anything(tmp_path, demo_resources, monkeypatch):
    """Warmed: the priors, the library and every suggesting condition's engine are loaded when the app is built,
    so the first click reads nothing from disk (a cold app loads both on it); what was loaded is frozen out of
    the collector's reach."""
    import gc

    from flowhelp import auth, to_trials

    from scenesuggest.learning.priors import Priors
    from study_server.studies import served

    loads = []
    for owner, name in ((Priors, "load"), (served, "load_index")):
        real = getattr(owner, name)
        monkeypatch.setattr(owner, name, lambda *a, real=real, name=name, **k: (loads.append(name), real(*a, **k))[1])
    try:
        for warm in (False, True):
            gc.unfreeze()
            app = make_app(tmp_path / str(warm), WARM_STUDIES=warm)
            assert (gc.get_freeze_count() > 0) == warm
            rt = app.extensions["studies"]["demo"]
            assert sorted(rt._engines) == (["basic", "full"] if warm else [])
            at_start = sorted(loads)
            client = app.test_client()
            headers = auth(to_trials(client))
            trial = client.get("/api/session", headers=headers).json["trial"]
            objects = client.get(f"/api/scenes/{trial['scene']}?which=target", headers=headers).json["objects"]
            o = next(o for o in objects if o.get("parent"))
            r = client.post("/api/suggest", headers=headers, json={
                "trial": trial["index"], "scene": {"objects": objects}, "parent": o["parent"],
                "point": o["contact_point"], "normal": o["contact_normal"]})
            assert trial["condition"] != "none" and r.status_code == 200 and r.json["suggestions"]
            assert (at_start, sorted(loads)) == ((["load", "load_index"], ["load", "load_index"]) if warm else
                                                 ([], ["load", "load_index"])), warm
            loads.clear()
    finally:
        gc.unfreeze()


def test_a_warmed_app_with_priors_it_cannot_load_stops_at_start_naming_the_file(tmp_path, demo_resources):
    """Priors whose header passes the start-up check but whose arrays are gone: a warmed server says so at
    start-up (file and key); a cold one starts and /healthz reports it."""
    import numpy as np
    from demostudy import DEMO_STUDY, copy_demo_study

    from study_server.studies.study_file import StudyFileError, load_study

    demo = load_study(DEMO_STUDY)
    with np.load(demo.priors) as good:
        np.savez(tmp_path / "header-only.npz", meta=good["meta"])
    study = copy_demo_study(tmp_path)
    study.write_text(study.read_text().replace(
        'corpus = "ai2thor"\n', f'corpus = "ai2thor"\npriors = "{tmp_path / "header-only.npz"}"\n'
                                 f'library = "{demo.library}"\n', 1))
    with pytest.raises(StudyFileError) as info:
        make_app(tmp_path / "warm", studies=[study], WARM_STUDIES=True)
    assert info.value.field == "resources.priors" and info.value.file == str(study), info.value
    cold = make_app(tmp_path / "cold", studies=[study])
    r = cold.test_client().get("/healthz")
    assert r.status_code == 503 and r.json["studies"]["demo"].startswith("unavailable"), r.json


def test_healthz_says_when_the_database_cannot_be_reached(tmp_path, demo_resources):
    import socket

    from demostudy import DEMO_STUDY

    from study_server import create_app

    with socket.socket() as s:  # a port nobody listens on
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    app = create_app({"INSTANCE_PATH": str(tmp_path / "instance"), "STUDY_FILES": [DEMO_STUDY],
                      "SECRET_KEY": "test", "SQLALCHEMY_DATABASE_URI": f"postgresql+psycopg://u:secret@127.0.0.1:{port}/x"})
    r = app.test_client().get("/healthz")
    assert r.status_code == 503 and r.json["database"] == "unreachable" and r.json["schema"] == "unknown"
    assert "secret" not in r.get_data(as_text=True) and str(port) not in r.get_data(as_text=True)


def test_deploy_files_are_filled_in_private_where_secret_and_never_overwritten(tmp_path, monkeypatch):
    import stat

    from study_server.experimenter.deployment import DeployError, Deployment, write_deploy_files

    monkeypatch.setenv("SCENESUGGEST_STUDIES", str(tmp_path / "my-study" / "study.toml"))
    monkeypatch.setenv("SCENESUGGEST_HOME", str(tmp_path / "home"))
    written = write_deploy_files(tmp_path / "out", Deployment("study.example.org", [8001, 8002, 8003]))
    texts = {p.relative_to(tmp_path / "out").as_posix(): p.read_text() for p in written}
    assert set(texts) == {"nginx/scenesuggest.conf", "nginx/scenesuggest-proxy-params.conf",
                          "systemd/scenesuggest@.service", "scenesuggest.env"}
    assert not any("@@" in t for t in texts.values())
    site = texts["nginx/scenesuggest.conf"]
    assert site.count("server 127.0.0.1:80") == 3 and "return 301 https://study.example.org$request_uri;" in site
    assert site.count("default_server") == 4 and site.count("return 444;") == 2
    assert "listen [::]:443 ssl http2;" in site and "http_503" not in texts["nginx/scenesuggest-proxy-params.conf"]
    assert "/etc/letsencrypt/live/study.example.org/fullchain.pem" in site
    unit = texts["systemd/scenesuggest@.service"]
    assert "Restart=on-failure" in unit and f"ReadWritePaths=-{tmp_path / 'home'} {tmp_path / 'my-study'}" in unit
    env = texts["scenesuggest.env"]
    assert f"SCENESUGGEST_STUDIES='{tmp_path / 'my-study' / 'study.toml'}'" in env and "PROXY_HOPS=1" in env
    secret = next(line.split("=", 1)[1] for line in env.splitlines() if line.startswith("SCENESUGGEST_SECRET_KEY="))
    assert len(secret) == 64
    assert stat.S_IMODE((tmp_path / "out" / "scenesuggest.env").stat().st_mode) == 0o600
    again = write_deploy_files(tmp_path / "again", Deployment("study.example.org"))
    assert next(p for p in again if p.name == "scenesuggest.env").read_text() != env  # a fresh key each time
    with pytest.raises(DeployError, match="not an empty folder"):
        write_deploy_files(tmp_path / "out", Deployment("study.example.org"))
    for bad, field in ((Deployment("study example"), "--server-name"), (Deployment("x.org", [80]), "--app"),
                       (Deployment("x.org", []), "--app")):
        with pytest.raises(DeployError) as info:
            write_deploy_files(tmp_path / "never", bad)
        assert info.value.field == field
    assert not (tmp_path / "never").exists()


HOSTILE = [  # (Deployment's keyword, value, the option named): each would have changed a file's meaning
    ("cert", "/etc/ssl/a.pem;\n    location /x { return 200; }\n#", "--cert"),
    ("key", "/etc/ssl/k.pem\nssl_verify_client off", "--key"),
    ("cert", "relative/cert.pem", "--cert"),
    ("user", "scenesuggest\nExecStartPre=+/bin/sh -c id", "--user"),
    ("user", "root", "--user"),
    ("user", "Bad User", "--user"),
    ("workers", 0, "--workers"),
    ("workers", -3, "--workers"),
    ("address", "127.0.0.1; evil", "address"),
]


@pytest.mark.parametrize("name", ["-", "a..b", ".example.org", "example.org.", "-a.org", "a-.org", "a" * 64 + ".org",
                                  "a_b.org", "a b", "ä.org", "x." * 127 + "x"])
def test_a_server_name_that_is_no_host_name_is_refused_by_deploy_files_and_the_app(tmp_path, monkeypatch, name):
    """A leading '.' is a wildcard to Flask's trusted hosts and to nginx; '-' and empty labels name no host."""
    from study_server.base.config import ConfigError, from_environment
    from study_server.experimenter.deployment import DeployError, Deployment, write_deploy_files

    with pytest.raises(DeployError) as info:
        write_deploy_files(tmp_path / "out", Deployment(name))
    assert info.value.field == "--server-name" and not (tmp_path / "out").exists()
    monkeypatch.setenv("SCENESUGGEST_SERVER_NAME", name)
    with pytest.raises(ConfigError) as info:
        from_environment(tmp_path / "instance")
    assert info.value.field == "SCENESUGGEST_SERVER_NAME"
    monkeypatch.setenv("SCENESUGGEST_SERVER_NAME", "study-1.example.org")
    assert from_environment(tmp_path / "instance")["TRUSTED_HOSTS"][0] == "study-1.example.org"


@pytest.mark.parametrize(("key", "value", "option"), HOSTILE)
def test_deploy_files_refuse_a_value_that_would_change_a_files_meaning(tmp_path, key, value, option):
    from study_server.experimenter.deployment import DeployError, Deployment, write_deploy_files

    with pytest.raises(DeployError) as info:
        write_deploy_files(tmp_path / "out", Deployment("study.example.org", **{key: value}))
    assert info.value.field == option
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("studies", ["/srv/my study/study.toml", "/srv/a/study.toml\nSCENESUGGEST_ENV=development",
                                     "/srv/$(id)/study.toml", "/srv/it's/study.toml"])
def test_deploy_files_refuse_study_paths_a_unit_or_a_shell_would_split(tmp_path, monkeypatch, studies):
    from study_server.experimenter.deployment import DeployError, Deployment, write_deploy_files

    monkeypatch.setenv("SCENESUGGEST_STUDIES", studies)
    with pytest.raises(DeployError) as info:
        write_deploy_files(tmp_path / "out", Deployment("study.example.org"))
    assert info.value.field == "SCENESUGGEST_STUDIES" and not (tmp_path / "out").exists()


def test_the_written_files_pass_nginx_and_systemds_own_checks(tmp_path, monkeypatch):
    """nginx -t on the site (as the proxy test runs it) and systemd-analyze verify on the unit, where present;
    the environment file sourced by a shell sets exactly its variables."""
    import shutil

    from serverproc import NginxProxy, nginx_missing

    monkeypatch.setenv("SCENESUGGEST_STUDIES", str(tmp_path / "my-study,v2" / "study.toml"))
    checked = 0
    if not nginx_missing():
        proxy = NginxProxy(tmp_path / "nginx", [8001])
        nginx = shutil.which("nginx", path=os.environ.get("PATH", "") + ":/usr/sbin")
        done = subprocess.run([nginx, "-t", "-c", str(proxy.prefix / "nginx.conf"), "-p", str(proxy.prefix)],
                              capture_output=True, text=True)
        assert done.returncode == 0 and "syntax is ok" in done.stderr, done.stderr
        checked += 1
        unit = (proxy.prefix / "deploy" / "systemd" / "scenesuggest@.service").read_text()
        env_file = proxy.prefix / "deploy" / "scenesuggest.env"
    else:
        from study_server.experimenter.deployment import Deployment, write_deploy_files

        write_deploy_files(tmp_path / "out", Deployment("study.example.org"))
        unit = (tmp_path / "out" / "systemd" / "scenesuggest@.service").read_text()
        env_file = tmp_path / "out" / "scenesuggest.env"
    if shutil.which("systemd-analyze"):
        instance = tmp_path / "units" / "scenesuggest@8001.service"
        instance.parent.mkdir()
        instance.write_text(unit.replace("User=scenesuggest", "User=daemon").replace("Group=scenesuggest",
                                                                                    "Group=daemon"))
        done = subprocess.run(["systemd-analyze", "verify", "--man=no", str(instance)], capture_output=True,
                              text=True)
        assert done.returncode == 0 and "scenesuggest@8001.service" not in done.stderr, done.stderr
        checked += 1
    sourced = subprocess.run(["sh", "-c", f"set -a; . '{env_file}'; env"], capture_output=True, text=True,
                             env={"PATH": "/usr/bin:/bin"})
    assert sourced.returncode == 0, sourced.stderr
    names = {line.split("=", 1)[0] for line in sourced.stdout.splitlines() if line.startswith("SCENESUGGEST_")}
    assert names == {"SCENESUGGEST_ENV", "SCENESUGGEST_SECRET_KEY", "SCENESUGGEST_STUDIES", "SCENESUGGEST_HOME",
                     "SCENESUGGEST_CACHE", "SCENESUGGEST_PROXY_HOPS", "SCENESUGGEST_ADMIN_PASSWORD_HASH",
                     "SCENESUGGEST_SERVER_NAME"}
    assert f"SCENESUGGEST_STUDIES={tmp_path / 'my-study,v2' / 'study.toml'}" in sourced.stdout.splitlines()
    assert checked >= (2 if os.environ.get("CI") == "true" else 0)


def test_postgresql_without_its_driver_says_how_to_install_it(tmp_path, monkeypatch):
    import importlib.util

    from demostudy import DEMO_STUDY

    from study_server import create_app
    from study_server.base.config import ConfigError

    real = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec", lambda name, *a: None if name == "psycopg" else real(name, *a))
    with pytest.raises(ConfigError) as info:
        create_app({"INSTANCE_PATH": str(tmp_path), "STUDY_FILES": [DEMO_STUDY], "SECRET_KEY": "x",
                    "SQLALCHEMY_DATABASE_URI": "postgresql+psycopg://u@127.0.0.1/x"})
    assert info.value.field == "DATABASE_URL" and "scenesuggest-studio[postgres]" in info.value.message


def test_served_gunicorn_logs_no_secret_reads_no_local_config_and_has_no_control_socket(tmp_path, demo_resources):
    """gunicorn as `study serve` runs it, from a folder holding a gunicorn.conf.py (gunicorn would run it) and with
    a home of its own (where gunicorn's default control socket would go): an entry link's SESSION_ID and pilot
    signature, a one-time admin link's secret and a Referer never reach the access log."""
    import signal
    import time
    import urllib.error
    import urllib.request

    from serverproc import free_port

    from study_server.cli import gunicorn_command

    make_app(tmp_path, f"sqlite:///{tmp_path / 'study.sqlite3'}")  # migrated
    folder = tmp_path / "cwd"
    folder.mkdir()
    (folder / "gunicorn.conf.py").write_text(f"open({str(tmp_path / 'ran')!r}, 'w').close()\n")
    port = free_port()
    env = {**os.environ, "SCENESUGGEST_INSTANCE": str(tmp_path / "instance"), "HOME": str(tmp_path / "home"),
           "DATABASE_URL": f"sqlite:///{tmp_path / 'study.sqlite3'}", "SCENESUGGEST_STUDIES": str(demo_resources),
           "SCENESUGGEST_SECRET_KEY": "loopback-only-" + "x" * 32, "PYTHONPATH": os.getcwd()}
    server = subprocess.Popen(gunicorn_command(1, f"127.0.0.1:{port}"), cwd=folder, env=env, stdout=subprocess.PIPE,
                              stderr=subprocess.STDOUT, start_new_session=True)
    secret = "5ec2e75ec2e75ec2e75ec2e7"
    try:
        for path in (f"/study/demo/start?pid=p1&SESSION_ID={secret}&pilot={secret}", f"/admin/link/{secret}",
                     f"//admin/link/{secret}", "/healthz"):
            request = urllib.request.Request(f"http://127.0.0.1:{port}{path}",
                                             headers={"Referer": f"http://x/?SESSION_ID={secret}"})
            for _ in range(300):
                try:
                    urllib.request.urlopen(request, timeout=10).close()
                    break
                except urllib.error.HTTPError:
                    break
                except OSError:
                    time.sleep(0.1)
    finally:
        os.killpg(server.pid, signal.SIGTERM)
        log = server.communicate(timeout=30)[0].decode(errors="replace")
    assert '"GET /healthz HTTP/1.1" 200' in log, log
    assert '"GET /study/demo/start HTTP/1.1"' in log and '"GET /admin/link/[secret] HTTP/1.1"' in log
    assert secret not in log
    assert not (tmp_path / "ran").exists()  # the folder's gunicorn.conf.py never ran
    assert not (tmp_path / "home" / ".gunicorn").exists()  # no control socket


def test_served_gunicorn_believes_no_forwarded_header_itself(tmp_path):
    """gunicorn takes X-Forwarded-Proto from loopback by default; with the app's settings only the app's own
    proxy rule (SCENESUGGEST_PROXY_HOPS) decides, so a local client cannot make a request https."""
    import signal
    import time
    import urllib.request

    from serverproc import free_port

    from study_server.cli import gunicorn_command

    (tmp_path / "scheme_app.py").write_text(
        "def app(environ, start_response):\n"
        "    start_response('200 OK', [('Content-Type', 'text/plain')])\n"
        "    return [environ['wsgi.url_scheme'].encode()]\n")
    port = free_port()
    command = gunicorn_command(1, f"127.0.0.1:{port}")[:-1] + ["scheme_app:app"]
    server = subprocess.Popen(command, cwd=tmp_path, env={**os.environ, "PYTHONPATH": f"{tmp_path}:{os.getcwd()}"},
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
    try:
        request = urllib.request.Request(f"http://127.0.0.1:{port}/", headers={"X-Forwarded-Proto": "https",
                                                                               "X-Forwarded-Ssl": "on"})
        for _ in range(300):
            try:
                with urllib.request.urlopen(request, timeout=10) as r:
                    scheme = r.read().decode()
                break
            except OSError:
                time.sleep(0.1)
    finally:
        os.killpg(server.pid, signal.SIGTERM)
        server.wait(timeout=30)
    assert scheme == "http"


def test_nginx_logs_no_secret_of_an_entry_link_or_a_one_time_admin_link(tmp_path):
    """The site as `study deploy-files` writes it, in front of nothing (each answer a 502, each still logged): an
    entry link's SESSION_ID and test signature, a one-time link's secret and a Referer never reach the access log,
    on HTTPS or on the redirect from HTTP."""
    import ssl
    import urllib.error
    import urllib.request

    from serverproc import NginxProxy, free_port, nginx_missing

    missing = nginx_missing()
    if missing:
        lacking(missing)  # under CI=true a failure: CI installs nginx
    secret = "5ec2e75ec2e75ec2e75ec2e7"
    with NginxProxy(tmp_path / "nginx", [free_port()], log_format="scenesuggest") as proxy:
        trusted = ssl.create_default_context(cafile=str(proxy.cert))
        for base in (proxy.https, proxy.http):
            for path in (f"/study/demo/start?PROLIFIC_PID=a&SESSION_ID={secret}&pilot={secret}",
                         f"/admin/link/{secret}"):
                request = urllib.request.Request(base + path, headers={"Referer": f"{base}/?SESSION_ID={secret}"})
                with pytest.raises(urllib.error.HTTPError):  # 502: no app behind (from HTTP after the 301)
                    urllib.request.urlopen(request, timeout=10, context=trusted)
    log = (tmp_path / "nginx" / "access.log").read_text()
    assert log.count("\n") == 6 and log.count('"GET /study/demo/start HTTP/1.1" 502') == 2
    assert '"GET /admin/link/[secret] HTTP/1.1" 301' in log and secret not in log
    errors = (tmp_path / "nginx" / "error.log").read_text()  # nginx's own: the 502s' causes quote the request line
    assert secret not in errors and "upstream" not in errors


def test_the_access_log_shows_only_its_allowance_whatever_format_is_asked_for(caplog):
    """An operator's --access-logformat naming headers, environment variables, the query or the Referer gets '-'
    there; an error naming a request names its path alone."""
    import datetime
    import logging
    from types import SimpleNamespace

    from gunicorn.config import Config

    from study_server.base.gunicorn_settings import AccessLog

    secret = "5ec2e75ec2e75ec2e75ec2e7"
    cfg = Config()
    cfg.set("accesslog", "-")
    cfg.set("access_log_format", '%(r)s %(U)s %(q)s %(f)s %(u)s %({cookie}i)s %({referer}i)s %({path_info}e)s '
                                 '%({query_string}e)s %({set-cookie}o)s %({location}o)s %(s)s')
    log = AccessLog(cfg)
    environ = {"REQUEST_METHOD": "GET", "RAW_URI": f"//admin/link/{secret}?SESSION_ID={secret}",
               "PATH_INFO": f"//admin/link/{secret}", "QUERY_STRING": f"SESSION_ID={secret}",
               "SERVER_PROTOCOL": "HTTP/1.1", "HTTP_REFERER": f"https://x/?SESSION_ID={secret}",
               "HTTP_AUTHORIZATION": "Basic dXNlcjpwYXNz", "REMOTE_ADDR": "127.0.0.1"}
    resp = SimpleNamespace(status="302 FOUND", sent=0, headers=[("Set-Cookie", f"s={secret}"),
                                                                 ("Location", f"/x?{secret}")])
    req = SimpleNamespace(headers=[("COOKIE", f"s={secret}"), ("REFERER", f"/?{secret}")])
    written = []
    log.access_log = SimpleNamespace(info=lambda fmt, atoms: written.append(fmt % atoms))
    log.access(resp, req, environ, datetime.timedelta(milliseconds=3))
    assert written == ["GET /admin/link/[secret] HTTP/1.1 /admin/link/[secret] - - - - - - - - - 302"], written
    with caplog.at_level(logging.ERROR):
        log.error_log.propagate = True
        log.exception("Error handling request %s", f"/study/demo/start?SESSION_ID={secret}")
    assert secret not in caplog.text and "/study/demo/start" in caplog.text
