"""``imugen serve`` obeys only its own page (issue 22).

Host allow-list (DNS rebinding), access token, cross-site requests (Origin, content type, form
token), headers, serialized and capped starts, streamed archives without links, clear 4xx
refusals that leave no run folder behind, form values the workflow would refuse.
"""

from __future__ import annotations

import io
import os
import re
import threading
import time
import urllib.error
import urllib.parse
import urllib.request
import zipfile
from pathlib import Path

import pytest
import yaml

flask = pytest.importorskip("flask")

from imugen.web import app as web  # noqa: E402
from imugen.web.app import create_app  # noqa: E402
from imugen.web.runs import Run, Runs  # noqa: E402
from imugen.web.security import is_loopback, split_host  # noqa: E402

from helpers import REPO, ROUTE  # noqa: E402

TINY = {
    "route.vehicle": "car",
    "truth.rate_hz": "10",
    "grades": "consumer",
    "figures.formats": "png",
}
EUROC = (
    "%YAML:1.0\nsensor_type: imu\nrate_hz: 200\ngyroscope_noise_density: 1.6968e-04\n"
    "gyroscope_random_walk: 1.9393e-05\naccelerometer_noise_density: 2.0000e-3\n"
    "accelerometer_random_walk: 3.0000e-3\n"
)
SLOW_SNAKEFILE = """
rule all:
    shell: "echo imugen-test-started; sleep 30"
"""


@pytest.fixture
def client(tmp_path):
    app = create_app(tmp_path, REPO)
    app.config["TESTING"] = True
    return app.test_client(), tmp_path


def token(c) -> str:
    html = c.get("/").get_data(as_text=True)
    return re.search(r'name="csrf_token" value="([^"]+)"', html).group(1)


def post_run(c, data=None, name="example.kml", content=None, files=None, **kw):
    body = {"csrf_token": token(c), **TINY, **(data or {})}
    body["route"] = (io.BytesIO(ROUTE.read_bytes() if content is None else content), name)
    for field, (fname, fcontent) in (files or {}).items():
        body[field] = (io.BytesIO(fcontent), fname)
    return c.post("/runs", data=body, content_type="multipart/form-data", **kw)


def run_ids(tmp) -> list[str]:
    return sorted(p.name for p in (tmp / "runs").iterdir() if p.is_dir())


def error_line(resp) -> str:
    html = resp.get_data(as_text=True)
    assert "Traceback" not in html
    return html.split('id="error">', 1)[1].split("</p>", 1)[0]


# --- who may drive the page -------------------------------------------------------------------
@pytest.mark.parametrize(
    "host, ok",
    [
        ("localhost", True),
        ("localhost:8765", True),
        ("127.0.0.1:8765", True),
        ("127.0.0.2", True),
        ("127.1", True),
        ("0x7f.1", True),
        ("2130706433", True),
        ("[::1]:8765", True),
        ("::1", True),
        ("[::ffff:127.0.0.1]", True),
        ("evil.example", False),
        ("127.0.0.1.evil.example", False),
        ("localhost.evil.example", False),
        ("127.0.0.1 evil", False),
        ("10.0.0.1", False),
        ("0.0.0.0", False),
        ("", False),
    ],
)
def test_loopback_spellings(host, ok):
    assert is_loopback(host) is ok


def test_host_allow_list(client):
    c, tmp = client
    post_run(c)  # one run exists: its id must not leak
    (rid,) = run_ids(tmp)
    r = c.get("/", headers={"Host": "evil.example"})
    assert r.status_code == 400 and rid not in r.get_data(as_text=True)
    assert (
        c.get(f"/runs/{rid}/progress.json", headers={"Host": "evil.example:80"}).status_code == 400
    )
    for host in ("127.0.0.2:5000", "[::1]:5000", "localhost", "127.1"):
        assert c.get("/", headers={"Host": host}).status_code == 200, host
    app = create_app(tmp, REPO, hosts=["lab.example"])
    assert app.test_client().get("/", headers={"Host": "lab.example:8765"}).status_code == 200
    assert split_host("[::1]:8765") == "::1" and split_host("Lab.Example.:80") == "lab.example"


def test_access_token_admits_only_the_printed_address(tmp_path):
    c = create_app(tmp_path, REPO, access_token="s3cret").test_client()
    assert c.get("/").status_code == 403
    assert c.get("/?token=wrong").status_code == 403
    r = c.get("/?token=s3cret")
    assert r.status_code == 302 and r.headers["Location"].endswith("/")
    cookie = r.headers["Set-Cookie"]
    assert "HttpOnly" in cookie and "SameSite=Strict" in cookie and "s3cret" in cookie
    assert c.get("/").status_code == 200  # the cookie now
    other = create_app(tmp_path, REPO, access_token="s3cret").test_client()
    assert other.post("/runs", data={}, content_type="multipart/form-data").status_code == 403


@pytest.mark.parametrize(
    "headers, content_type, with_token, status",
    [
        ({"Origin": "http://evil.example"}, "multipart/form-data", True, 403),
        ({"Origin": "null"}, "multipart/form-data", True, 403),
        ({"Referer": "http://evil.example/x.html"}, "multipart/form-data", True, 403),
        ({"Origin": "http://localhost:9999"}, "multipart/form-data", True, 403),
        ({}, "text/plain", True, 415),
        ({}, "application/json", True, 415),
        ({}, "multipart/form-data", False, 403),
    ],
)
def test_cross_site_requests_change_nothing(client, headers, content_type, with_token, status):
    c, tmp = client
    post_run(c)
    (rid,) = run_ids(tmp)
    tok = token(c)
    for path in ("/runs", f"/runs/{rid}/start", f"/runs/{rid}/cancel", f"/runs/{rid}/config"):
        data = {**TINY, **({"csrf_token": tok} if with_token else {})}
        if content_type == "multipart/form-data":
            data["route"] = (io.BytesIO(ROUTE.read_bytes()), "x.kml")
            r = c.post(path, data=data, content_type=content_type, headers=headers)
        else:
            body = "&".join(f"{k}={v}" for k, v in data.items() if isinstance(v, str))
            r = c.post(path, data=body, content_type=content_type, headers=headers)
        assert r.status_code == status, (path, r.status_code)
    assert run_ids(tmp) == [rid]
    assert Run(tmp / "runs" / rid).state()["status"] == "new"  # never started


def test_same_origin_form_posts_are_accepted(client):
    c, _ = client
    r = post_run(c, headers={"Origin": "http://localhost", "Referer": "http://localhost/"})
    assert r.status_code == 302


def test_headers_forbid_framing_and_foreign_scripts(client):
    c, tmp = client
    rid = post_run(c).headers["Location"].rsplit("/", 1)[1]
    for path in ("/", f"/runs/{rid}"):
        r = c.get(path)
        assert r.headers["X-Frame-Options"] == "DENY"
        csp = r.headers["Content-Security-Policy"]
        assert "frame-ancestors 'none'" in csp and "script-src 'self'" in csp
        assert "unsafe-inline" not in csp and "default-src 'none'" in csp
        html = r.get_data(as_text=True)
        # the policy allows no inline script or style: the page has none
        assert not re.search(r"<script(?![^>]*\bsrc=)", html) and " style=" not in html
    (tmp / "runs" / rid / "results").mkdir()
    (tmp / "runs" / rid / "results" / "x.svg").write_text("<svg><script>alert(1)</script></svg>")
    r = c.get(f"/runs/{rid}/files/results/x.svg")
    assert r.status_code == 200 and "sandbox" in r.headers["Content-Security-Policy"]


# --- starting runs ------------------------------------------------------------------------------
def _fake_repo(tmp_path) -> Path:
    """The project's schema with a Snakefile whose one job prints a marker and sleeps."""
    repo = tmp_path / "repo"
    (repo / "workflow" / "schemas").mkdir(parents=True)
    schema = REPO / "workflow" / "schemas" / "config.schema.yaml"
    (repo / "workflow" / "schemas" / "config.schema.yaml").write_text(schema.read_text())
    (repo / "Snakefile").write_text(SLOW_SNAKEFILE)
    return repo


def _snakemakes(root: Path) -> list[int]:
    """Pids of the Snakemake processes working in run folder ``root`` (not --unlock)."""
    out = []
    for d in Path("/proc").iterdir():
        try:
            argv = (d / "cmdline").read_bytes().split(b"\0")
        except OSError:
            continue
        if b"snakemake" in argv and str(root).encode() in argv and b"--unlock" not in argv:
            if not argv[0].endswith(b"sh"):
                out.append(int(d.name))
    return out


@pytest.fixture
def live(tmp_path):
    """A real server (threads) on the fake repository; yields (base URL, app, work folder)."""
    from werkzeug.serving import make_server

    app = create_app(tmp_path / "work", _fake_repo(tmp_path), max_running=1)
    server = make_server("127.0.0.1", 0, app, threaded=True)
    threading.Thread(target=server.serve_forever, daemon=True).start()
    base = f"http://127.0.0.1:{server.server_port}"
    yield base, app, tmp_path / "work"
    for run in Runs(tmp_path / "work").all():
        run.cancel()
    server.shutdown()


def _form_post(base, path, tok, data=None):
    body = urllib.parse.urlencode({"csrf_token": tok, **(data or {})}).encode()
    req = urllib.request.Request(base + path, data=body, method="POST")
    req.add_header("Content-Type", "application/x-www-form-urlencoded")
    try:
        with urllib.request.urlopen(req) as r:
            return r.status, r.read().decode()
    except urllib.error.HTTPError as e:
        return e.code, e.read().decode()


class _NoRedirect(urllib.request.HTTPRedirectHandler):
    def redirect_request(self, *a, **k):
        return None


def _new_run(app, work) -> Run:
    c = app.test_client()
    r = post_run(c)
    assert r.status_code == 302, r.get_data(as_text=True)[-500:]
    return Runs(work).get(r.headers["Location"].rsplit("/", 1)[1])


def _wait_log(run: Run, text: str, timeout: float = 120) -> None:
    end = time.time() + timeout
    while time.time() < end:
        if run.log_path.exists() and text in run.log_path.read_text():
            return
        time.sleep(0.2)
    raise AssertionError(run.log_path.read_text() if run.log_path.exists() else "no run.log")


def test_double_start_runs_one_snakemake_and_keeps_the_log(live):
    base, app, work = live
    tok = app.config["GUARD"].form_token
    run = _new_run(app, work)
    opener = urllib.request.build_opener(_NoRedirect)
    statuses = []

    def start():
        req = urllib.request.Request(
            f"{base}/runs/{run.id}/start",
            data=urllib.parse.urlencode({"csrf_token": tok}).encode(),
            headers={"Content-Type": "application/x-www-form-urlencoded"},
        )
        try:
            statuses.append(opener.open(req).status)
        except urllib.error.HTTPError as e:
            statuses.append(e.code)

    clicks = [threading.Thread(target=start) for _ in range(2)]
    for t in clicks:
        t.start()
        time.sleep(0.3)  # a double click
    for t in clicks:
        t.join()
    assert sorted(statuses) == [302, 409], statuses
    _wait_log(run, "imugen-test-started")
    assert len(_snakemakes(run.root)) == 1
    size = run.log_path.stat().st_size
    status, html = _form_post(base, f"/runs/{run.id}/start", tok)
    assert status == 409 and "is already running" in html
    assert run.log_path.stat().st_size >= size and "imugen-test-started" in run.log_path.read_text()
    assert len(_snakemakes(run.root)) == 1


def test_runs_at_once_are_capped(live):
    base, app, work = live
    tok = app.config["GUARD"].form_token
    first, second = _new_run(app, work), _new_run(app, work)
    assert _form_post(base, f"/runs/{first.id}/start", tok)[0] == 200  # redirected to its page
    status, html = _form_post(base, f"/runs/{second.id}/start", tok)
    assert status == 429 and "1 run already running (at most 1 at once" in html
    assert second.state()["status"] == "new" and not second.log_path.exists()
    first.cancel()
    assert first.state()["status"] == "cancelled" and not _snakemakes(first.root)


def test_route_checks_at_once_are_capped(client, monkeypatch):
    _, tmp = client
    entered, release = threading.Event(), threading.Event()
    real = web._preview

    def slow(*a):
        entered.set()
        release.wait(60)
        return real(*a)

    monkeypatch.setattr(web, "MAX_CHECKS", 1)
    monkeypatch.setattr(web, "_preview", slow)
    app = create_app(tmp / "w", REPO)
    c1, c2 = app.test_client(), app.test_client()
    results = []
    t = threading.Thread(target=lambda: results.append(post_run(c1).status_code))
    t.start()
    assert entered.wait(60)
    r = post_run(c2)
    assert r.status_code == 429 and "route checks are running" in error_line(r)
    release.set()
    t.join()
    assert results == [302] and len(run_ids(tmp / "w")) == 1


# --- archives and files ---------------------------------------------------------------------------
def test_results_zip_is_streamed_and_skips_links(client, tmp_path):
    c, tmp = client
    rid = post_run(c).headers["Location"].rsplit("/", 1)[1]
    res = tmp / "runs" / rid / "results"
    (res / "r" / "figures").mkdir(parents=True)
    (res / "r" / "rmse.csv").write_text("grade,total_m\nconsumer,1\n")
    (res / "r" / "figures" / "a.png").write_bytes(os.urandom(3000))
    secret = tmp_path / "secret.txt"
    secret.write_text("not yours")
    (res / "r" / "leak.txt").symlink_to(secret)
    (res / "r" / "tree").symlink_to(tmp_path)
    os.mkfifo(res / "r" / "pipe")
    before = sorted(p.name for p in (tmp / "runs").iterdir())
    for _ in range(2):
        r = c.get(f"/runs/{rid}/results.zip")
        assert r.status_code == 200 and r.is_streamed
        z = zipfile.ZipFile(io.BytesIO(r.get_data()))
        assert sorted(z.namelist()) == ["results/r/figures/a.png", "results/r/rmse.csv"]
        assert z.read("results/r/rmse.csv").startswith(b"grade,")
        assert z.testzip() is None
    assert sorted(p.name for p in (tmp / "runs").iterdir()) == before  # no copy left behind


@pytest.mark.parametrize("sub", ["results/%00", "results/" + "a" * 6000, "results/x%00y.png"])
def test_odd_file_paths_are_404(client, sub):
    c, tmp = client
    rid = post_run(c).headers["Location"].rsplit("/", 1)[1]
    (tmp / "runs" / rid / "results").mkdir()
    assert c.get(f"/runs/{rid}/files/{sub}").status_code == 404


# --- refusals leave nothing behind ------------------------------------------------------------
def test_deeply_nested_imu_upload_is_a_400_and_leaves_no_run(client):
    c, tmp = client
    deep = ("a: " + "[" * 5000 + "]" * 5000).encode()
    r = post_run(c, files={"kalibr": ("imu.yaml", deep)})
    assert r.status_code == 400
    assert error_line(r) == "imu.yaml: is nested too deeply to be an IMU description"
    assert run_ids(tmp) == []


def test_imported_imu_without_a_name_is_named_after_its_file(client):
    c, tmp = client
    r = post_run(c, files={"kalibr": ("My Sensor.yaml", EUROC.encode())})
    assert r.status_code == 302
    (rid,) = run_ids(tmp)
    cfg = yaml.safe_load((tmp / "runs" / rid / "config" / "config.yaml").read_text())
    assert set(cfg["grades"]) == {"consumer", "my_sensor"}, cfg["grades"]
    r = post_run(c, {"kalibr_name": "Bench IMU #2"}, files={"kalibr": ("imu.yaml", EUROC.encode())})
    cfg = yaml.safe_load(
        (
            tmp / "runs" / r.headers["Location"].rsplit("/", 1)[1] / "config" / "config.yaml"
        ).read_text()
    )
    assert "bench_imu_2" in cfg["grades"]
    r = post_run(c, {"kalibr_name": "consumer"}, files={"kalibr": ("imu.yaml", EUROC.encode())})
    assert r.status_code == 400 and "name of a shipped preset" in error_line(r)


def test_errors_name_the_upload_not_the_servers_paths(client):
    c, tmp = client
    r = post_run(c, files={"kalibr": ("imu.yaml", b"gyro: [1, 2\n")})
    line = error_line(r)
    assert r.status_code == 400 and line.startswith("imu.yaml: ")
    assert "/tmp" not in line and str(tmp) not in line and "imugen-imu-" not in line
    r = post_run(c, content=b"lat,lon\n1,2\n1,-1230\n", name="bad.csv")
    line = error_line(r)
    assert r.status_code == 400 and str(tmp) not in line and "/runs/" not in line
    assert run_ids(tmp) == []


@pytest.mark.parametrize(
    "field, value, message",
    [
        ("truth.rate_hz", "nan", "is not a finite number"),
        ("truth.rate_hz", "inf", "is not a finite number"),
        ("truth.rate_hz", "1e-300", "less than the minimum of 1"),
        ("allan.rate_hz", "0.5", "less than the minimum of 1"),
        ("route.dt_s", "-1", "less than or equal to the minimum of 0"),
        ("route.origin", "nan,151.2,10", "finite numbers"),
        ("route.origin", "-133.9,151.2,10", "less than the minimum of -90"),
    ],
)
def test_form_refuses_what_the_workflow_refuses(client, field, value, message):
    c, tmp = client
    r = post_run(c, {field: value})
    assert r.status_code == 400 and message in error_line(r), error_line(r)
    assert run_ids(tmp) == []


# --- E N U files need the origin, which the form offers ------------------------------------------
def test_enu_route_with_the_forms_origin(client):
    c, tmp = client
    assert 'name="route.origin"' in c.get("/").get_data(as_text=True)
    enu = "".join(f"{k * 4.0} {k * 3.0} 0\n" for k in range(50)).encode()
    r = post_run(c, {"route.dt_s": "1"}, content=enu, name="square.txt")
    assert r.status_code == 400 and "need an origin" in error_line(r)
    r = post_run(
        c, {"route.dt_s": "1", "route.origin": "-33.9, 151.2, 10"}, content=enu, name="s.txt"
    )
    assert r.status_code == 302, error_line(r)
    rid = r.headers["Location"].rsplit("/", 1)[1]
    cfg = yaml.safe_load((tmp / "runs" / rid / "config" / "config.yaml").read_text())
    assert cfg["routes"]["route"]["origin"] == [-33.9, 151.2, 10.0]
    assert "origin -33.900000, 151.200000" in c.get(f"/runs/{rid}").get_data(as_text=True)


# --- the start-up line ------------------------------------------------------------------------------
@pytest.mark.parametrize(
    "host, remote", [("127.0.0.1", False), ("127.0.0.2", False), ("::1", False), ("10.1.2.3", True)]
)
def test_serve_warns_only_for_remote_addresses(tmp_path, monkeypatch, capsys, host, remote):
    import werkzeug.serving

    calls = []
    monkeypatch.setattr(werkzeug.serving, "run_simple", lambda *a, **k: calls.append((a, k)))
    monkeypatch.setattr(os, "umask", lambda m: 0o022)
    web.serve(tmp_path, host=host, port=8999, repo=REPO)
    err = capsys.readouterr().err
    assert ("reachable from other machines" in err) is remote
    url = re.search(r"http://\S+", err).group(0)
    assert re.search(r"/\?token=[\w-]{20,}$", url)
    app = calls[0][0][2]
    c = app.test_client()
    assert (
        c.get("/", headers={"Host": f"{host}:8999" if ":" not in host else f"[{host}]"}).status_code
        == 403
    )
