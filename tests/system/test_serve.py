"""imugen serve: the form follows the schema, bad input is one line, runs are isolated; and a real
headless Chromium drives the page end to end on the shipped example."""

from __future__ import annotations

import io
import os
import re
import shutil
import threading
import time
import urllib.request
from pathlib import Path

import pytest
import yaml

flask = pytest.importorskip("flask")

from imugen.web import form as fm  # noqa: E402
from imugen.web.app import create_app  # noqa: E402
from imugen.web.runs import Run, safe_name  # noqa: E402

REPO = Path(__file__).resolve().parents[2]
ROUTE = REPO / "resources" / "example_route.kml"
TINY = {
    "route.vehicle": "car",
    "truth.rate_hz": "10",
    "simulate.sequences": "2",
    "simulate.sequences_per_shard": "2",
    "allan.static_s": "60",
    "allan.rate_hz": "10",
    "allan.sequences": "1",
    "figures.formats": "png",
    "grades": "consumer",
}


@pytest.fixture
def client(tmp_path):
    app = create_app(tmp_path, REPO)
    app.config["TESTING"] = True
    return app.test_client(), tmp_path


def _token(client) -> str:
    """The form token the page embeds (every POST must carry it)."""
    html = client.get("/").get_data(as_text=True)
    return re.search(r'name="csrf_token" value="([^"]+)"', html).group(1)


def _post(client, data, name="example.kml", content=None):
    body = {"csrf_token": _token(client), **data}
    body["route"] = (io.BytesIO(content if content is not None else ROUTE.read_bytes()), name)
    return client.post("/runs", data=body, content_type="multipart/form-data")


def test_form_offers_every_schema_key(client):
    c, _ = client
    html = c.get("/").get_data(as_text=True)
    schema = fm.load_schema(REPO)
    offered = fm.section_fields(schema)
    assert {"truth", "simulate", "gnss", "scenarios", "aided"} <= set(offered)
    for fields in offered.values():
        for f in fields:
            assert f'name="{f.name}"' in html, f.name
    assert 'name="grades" value="tactical"' in html


def test_a_null_choice_is_offered_as_none_and_submits_as_no_value(client):
    """An enum with null (``companions.odometer``) shows "none" with an empty value, so the
    form's default submits as no key, never as the string 'None'."""
    c, _ = client
    html = c.get("/").get_data(as_text=True)
    assert 'value="None"' not in html
    assert '<option value="" selected>none</option>' in html


def test_valid_upload_makes_an_isolated_run_with_a_schema_valid_config(client):
    c, tmp = client
    r = _post(c, TINY, name="../../evil name.kml")
    assert r.status_code == 302
    rid = r.headers["Location"].rsplit("/", 1)[1]
    run = tmp / "runs" / rid
    assert (run / "input" / "evil_name.kml").exists()  # sanitized, inside the run
    cfg = yaml.safe_load((run / "config" / "config.yaml").read_text())
    assert cfg["routes"]["route"]["file"] == "input/evil_name.kml"
    assert cfg["grades"] == {"consumer": {}} and cfg["simulate"]["sequences"] == 2
    fm.validate(cfg, REPO)
    page = c.get(f"/runs/{rid}").get_data(as_text=True)
    assert 'id="plan"' in page and "<polyline points=" in page
    assert fm.config_values(fm.load_schema(REPO), cfg)["simulate.sequences"] == 2


@pytest.mark.parametrize(
    "content, data, message",
    [
        (
            b"<gpx><trk><trkseg><trkpt lat='1' lon='-1230'/><trkpt lat='1' lon='2'/></trkseg></trk></gpx>",
            {},
            "longitude",
        ),
        (None, {"truth.rate_hz": "-5"}, "rate_hz"),
        (None, {"grades": "nonexistent"}, "grade"),
    ],
)
def test_bad_input_is_one_line_and_leaves_no_run(client, content, data, message):
    c, tmp = client
    body = {**TINY, **data}
    if "grades" in data:
        body["grades"] = data["grades"]
    r = _post(c, body, name="bad.gpx" if content else "example.kml", content=content)
    assert r.status_code == 400
    html = r.get_data(as_text=True)
    err = html.split('id="error">', 1)[1].split("</p>", 1)[0]
    assert message in err and "\n" not in err and "Traceback" not in html
    assert not any((tmp / "runs").iterdir())


def test_files_stay_inside_the_run(client):
    c, tmp = client
    rid = _post(c, TINY).headers["Location"].rsplit("/", 1)[1]
    (tmp / "secret.txt").write_text("x")
    for sub in ("../../secret.txt", "config/config.yaml", "results/../../secret.txt"):
        assert c.get(f"/runs/{rid}/files/{sub}").status_code == 404
    assert c.get("/runs/..%2f/files/x", follow_redirects=True).status_code == 404
    assert safe_name("..") == "route" and safe_name("a/../../b c.gpx") == "b_c.gpx"


def test_upload_size_is_bounded(client, monkeypatch):
    c, tmp = client
    c.application.config["MAX_CONTENT_LENGTH"] = 1000
    r = _post(c, TINY)
    assert r.status_code == 413 and not any((tmp / "runs").iterdir())


# --- a real browser ---------------------------------------------------------------------------
def _chromium():
    webdriver = pytest.importorskip("selenium.webdriver")
    binary = shutil.which("chromium") or shutil.which("chromium-browser")
    driver = shutil.which("chromedriver")
    if not binary or not driver:
        pytest.skip(
            "Chromium and its driver are not installed (apt-get install chromium chromium-driver)"
        )
    from selenium.webdriver.chrome.options import Options
    from selenium.webdriver.chrome.service import Service

    opts = Options()
    opts.binary_location = binary
    for a in (
        "--headless=new",
        "--no-sandbox",
        "--disable-dev-shm-usage",
        "--window-size=1200,1600",
    ):
        opts.add_argument(a)
    return webdriver.Chrome(service=Service(driver), options=opts)


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


EVIL = """<!doctype html><html><body>
<form id="a" method="post" action="{target}" enctype="text/plain"><input name="x" value="1"></form>
<form id="b" method="post" action="{target}" target="sink"><input name="csrf_token" value="guess"></form>
<iframe name="sink"></iframe>
<script>document.getElementById("b").submit(); setTimeout(() => document.getElementById("a").submit(), 500);</script>
</body></html>"""


def _evil_site(target: str) -> tuple[str, object]:
    """Another site (another port: another origin) whose page posts forms to ``target``."""
    import http.server

    page = EVIL.format(target=target).encode()

    class Handler(http.server.BaseHTTPRequestHandler):
        def do_GET(self):
            self.send_response(200)
            self.send_header("Content-Type", "text/html")
            self.end_headers()
            self.wfile.write(page)

        def log_message(self, *a):
            pass

    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), Handler)
    threading.Thread(target=server.serve_forever, daemon=True).start()
    return f"http://127.0.0.1:{server.server_port}/", server


def test_browser_end_to_end_on_the_shipped_example(tmp_path):
    from selenium.common.exceptions import NoSuchElementException, StaleElementReferenceException
    from selenium.webdriver.common.action_chains import ActionChains
    from selenium.webdriver.common.by import By
    from selenium.webdriver.support import expected_conditions as ec
    from selenium.webdriver.support.ui import WebDriverWait
    from werkzeug.serving import make_server

    app = create_app(tmp_path, REPO, access_token="browser-test-token")
    server = make_server("127.0.0.1", 0, app, threaded=True)
    threading.Thread(target=server.serve_forever, daemon=True).start()
    base = f"http://127.0.0.1:{server.server_port}"
    shots = os.environ.get("IMUGEN_SCREENSHOTS")
    browser = _chromium()
    evil_server = None
    try:
        browser.get(base + "/")  # without the printed address's token: refused
        assert "open the address" in browser.find_element(By.TAG_NAME, "body").text
        browser.get(base + "/?token=browser-test-token")
        browser.find_element(By.ID, "route").send_keys(str(ROUTE))
        for g in browser.find_elements(By.NAME, "grades"):
            if g.is_selected() != (g.get_attribute("value") == "consumer"):
                g.click()
        for name, value in TINY.items():
            if name in ("grades", "figures.formats"):
                continue
            el = browser.find_element(By.ID, name)
            if el.tag_name == "select":
                continue
            el.clear()
            el.send_keys(value)
        for box in browser.find_elements(By.NAME, "figures.formats"):
            if box.is_selected() != (box.get_attribute("value") == "png"):
                box.click()
        mat = browser.find_element(By.ID, "exports.mat")
        if mat.is_selected():
            mat.click()
        if shots:
            browser.save_screenshot(str(Path(shots) / "web_new_run.png"))
        browser.find_element(By.ID, "create").click()
        wait = WebDriverWait(browser, 120)
        facts = wait.until(ec.presence_of_element_located((By.ID, "route-facts"))).text
        assert "points" in facts and " m," in facts, facts
        run_root = tmp_path / "runs" / browser.current_url.rstrip("/").rsplit("/", 1)[1]
        # a double click on Start starts one Snakemake
        ActionChains(browser).double_click(browser.find_element(By.ID, "start")).perform()
        wait.until(ec.presence_of_element_located((By.ID, "status")))
        time.sleep(3)
        assert len(_snakemakes(run_root)) == 1, _snakemakes(run_root)
        # another site's page posting to the running run's Cancel changes nothing
        evil, evil_server = _evil_site(base + f"/runs/{run_root.name}/cancel")
        browser.get(evil)
        time.sleep(2)
        assert Run(run_root).state()["status"] == "running"
        browser.get(base + f"/runs/{run_root.name}")
        deadline, status = time.time() + 600, ""
        while time.time() < deadline:
            try:
                status = browser.find_element(By.ID, "status").text
            except (NoSuchElementException, StaleElementReferenceException):
                status = ""  # reloading
            if status in ("finished", "failed", "cancelled"):
                break
            time.sleep(2)
        assert status == "finished", browser.find_element(By.ID, "log").get_attribute(
            "textContent"
        )[-3000:]
        table = browser.find_element(By.ID, "rmse").text
        assert "consumer" in table
        # the RMSE table fits the page; the truth's facts are a table with words and units
        right, main_right, page_w, view_w = browser.execute_script(
            "const t = document.querySelector('#rmse table').getBoundingClientRect();"
            "const m = document.querySelector('main').getBoundingClientRect();"
            "return [t.right, m.right, document.documentElement.scrollWidth, window.innerWidth];"
        )
        assert right <= main_right + 1 and page_w <= view_w, (right, main_right, page_w, view_w)
        truth = browser.find_element(By.ID, "truth-facts")
        assert truth.tag_name == "table"
        assert "top speed" in truth.text and " m/s" in truth.text and "Earth model" in truth.text
        assert "_mps" not in truth.text and "max_" not in truth.text
        if shots:
            browser.save_screenshot(str(Path(shots) / "web_run.png"))
        cookie = "; ".join(f"{c['name']}={c['value']}" for c in browser.get_cookies())

        def fetch(url):
            return urllib.request.urlopen(urllib.request.Request(url, headers={"Cookie": cookie}))

        link = next(
            a.get_attribute("href")
            for a in browser.find_elements(By.CSS_SELECTOR, "#files a")
            if a.text.endswith("rmse.csv")
        )
        csv = fetch(link).read().decode()
        assert csv.startswith("grade,east_m,north_m,up_m,total_m") and "consumer" in csv
        z = fetch(browser.find_element(By.ID, "download-zip").get_attribute("href"))
        assert z.read(2) == b"PK"
        assert [p.name for p in (tmp_path / "runs").iterdir() if p.is_dir()] == [run_root.name]
    finally:
        browser.quit()
        server.shutdown()
        if evil_server is not None:
            evil_server.shutdown()
