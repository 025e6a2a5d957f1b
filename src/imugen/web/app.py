"""The Flask application of ``imugen serve`` (see :mod:`imugen.web`; its guards:
:mod:`imugen.web.security`)."""

from __future__ import annotations

import math
import os
import re
import secrets
import shutil
import subprocess
import sys
import tempfile
import threading
import warnings
from pathlib import Path

import numpy as np
from flask import (
    Flask,
    Response,
    abort,
    jsonify,
    redirect,
    render_template,
    request,
    send_file,
    stream_with_context,
    url_for,
)
from werkzeug.exceptions import RequestEntityTooLarge

from imugen.core.errors import InputError
from imugen.web import form as fm
from imugen.web.runs import Refused, Run, Runs, safe_name
from imugen.web.security import HEADERS, Guard, is_loopback, same_origin

MAX_UPLOAD = 64 << 20
"""Largest upload (route file or IMU description) [bytes]."""
INGEST_TIMEOUT_S = 120
REPORT_TIMEOUT_S = 600
MAX_PATH_CHARS = 1024
"""Longest file path below a run that the page serves."""
CORES_PER_RUN = min(2, os.cpu_count() or 1)
"""Snakemake ``--cores`` of one run."""
MAX_RUNNING = max(1, (os.cpu_count() or 1) // CORES_PER_RUN)
"""Runs at once (default: as many as the machine's cores hold at CORES_PER_RUN each)."""
MAX_CHECKS = 2
"""Route checks (ingestion for the plan view), reports and archives at once."""
TRUTH_FACTS = (
    ("length_truth_m", "path length", "{:,.0f} m"),
    ("length_input_m", "length of the route file's path", "{:,.0f} m"),
    ("time_moving_s", "time moving", "{:,.0f} s"),
    ("time_stopped_s", "time stopped", "{:,.0f} s"),
    ("time_airborne_s", "time airborne", "{:,.0f} s"),
    ("max_speed_mps", "top speed", "{:.1f} m/s"),
    ("max_accel_mps2", "largest acceleration", "{:.2f} m/s²"),
    ("max_jerk_mps3", "largest jerk", "{:.2f} m/s³"),
    ("max_yaw_rate_dps", "largest turn rate", "{:.1f} °/s"),
    ("max_abs_pitch_deg", "largest |pitch| on the ground", "{:.1f}°"),
    ("max_abs_roll_deg", "largest |roll| on the ground", "{:.1f}°"),
    ("max_sideslip_deg", "largest sideslip", "{:.2f}°"),
    ("fit_rms_m", "distance to the route's points (RMS)", "{:.2f} m"),
    ("fit_max_m", "distance to the route's points (max)", "{:.2f} m"),
    ("invented_m", "motion between fixes the file does not show", "{:,.0f} m"),
)
"""Facts of the truth's plausibility report shown on the page: key, label, format."""


def find_repo() -> Path:
    """The project folder holding ``Snakefile`` (the source tree of an editable install)."""
    for base in (Path(__file__).resolve().parents[3], Path.cwd()):
        if (base / "Snakefile").is_file() and (base / "workflow").is_dir():
            return base
    raise InputError("imugen serve", "cannot find the workflow (Snakefile): pass --repo")


def grade_name(text: str) -> str:
    """A grade name from free text: lower-case letters, digits and ``_`` (else ``imported``)."""
    s = re.sub(r"[^a-z0-9_]+", "_", str(text).lower()).strip("_")[:40]
    return s or "imported"


def _grades(form, files) -> dict:
    """Preset grades ticked in the form, and the imported IMU description, if any."""
    from imugen.sensors.grade_io import import_grade
    from imugen.sensors.grades import presets

    grades = {g: {} for g in form.getlist("grades") if g in presets()}
    up = files.get("kalibr")
    if up and up.filename:
        shown = safe_name(up.filename, "imu.yaml")
        typed = (form.get("kalibr_name") or "").strip()
        with tempfile.TemporaryDirectory(prefix="imugen-imu-") as d:
            p = Path(d) / shown
            up.save(p)
            try:
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore")
                    name, cfg = import_grade(p, name=grade_name(typed) if typed else None)
            except InputError as exc:  # named by the upload, never by the server's paths
                raise InputError(shown, exc.message.replace(d + os.sep, "")) from None
            except RecursionError:
                raise InputError(shown, "is nested too deeply") from None
        grades[grade_name(name)] = cfg
    return grades


def _preview(run: Run, route: Path, cfg_route: dict) -> dict:
    """Ingest the route (same command and messages as the CLI) for its plan view."""
    out = run.root / "preview" / "enu.parquet"
    cmd = [sys.executable, "-m", "imugen", "ingest", f"--output={out}"]
    if cfg_route.get("path") is not None:
        cmd.append(f"--path={cfg_route['path']}")
    if cfg_route.get("origin"):
        cmd.append("--origin=" + ",".join(map(repr, map(float, cfg_route["origin"]))))
    if cfg_route.get("dt_s"):
        cmd.append(f"--dt={float(cfg_route['dt_s'])!r}")
    cmd.append(f"--vehicle={cfg_route.get('vehicle', 'car')}")
    cmd += ["--", str(route)]
    try:
        p = subprocess.run(cmd, capture_output=True, text=True, timeout=INGEST_TIMEOUT_S)
    except subprocess.TimeoutExpired:
        raise InputError(route.name, f"not read within {INGEST_TIMEOUT_S} s") from None
    if p.returncode != 0:
        line = next(
            (ln for ln in reversed(p.stderr.splitlines()) if "error:" in ln), p.stderr.strip()
        )
        for prefix in ("imugen: error: ", str(route.parent) + os.sep, str(run.root) + os.sep):
            line = line.replace(prefix, "")
        raise InputError(None, line[:500])
    return plan(run)


def plan(run: Run) -> dict | None:
    """Plan view (SVG points), length, duration and warnings of the ingested route."""
    out = run.root / "preview" / "enu.parquet"
    if not out.exists():
        return None
    from imugen.tables import enu as tenu

    df, meta = tenu.read(out, columns=[tenu.E, tenu.N])
    e, n = df[tenu.E].to_numpy(), df[tenu.N].to_numpy()
    step = max(1, len(e) // 2000)
    e, n = e[::step], n[::step]
    span = max(float(np.ptp(e)), float(np.ptp(n)), 1.0)
    W = 560.0
    x = 20 + (e - e.min()) / span * W
    y = 20 + (n.max() - n) / span * W
    return {
        "points": " ".join(f"{a:.1f},{b:.1f}" for a, b in zip(x, y, strict=True)),
        "width": 600,
        "height": int(40 + float(np.ptp(n)) / span * W),
        "scale_m": _nice(span / 4),
        "scale_px": _nice(span / 4) / span * W,
        "meta": meta,
    }


def _nice(x: float) -> float:
    p = 10 ** math.floor(math.log10(x))
    return max(m * p for m in (1, 2, 5) if m * p <= x) if x > 0 else 1.0


def truth_facts(meta: dict) -> list[tuple[str, str]]:
    """(label, value with unit) rows of a truth's plausibility report."""
    rep = meta.get("plausibility") or meta.get("motion") or {}
    rows = []
    for key, label, fmt in TRUTH_FACTS:
        v = rep.get(key)
        if isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v):
            if key == "time_airborne_s" and not v:
                continue
            rows.append((label, fmt.format(v)))
    return rows


def results(run: Run) -> dict:
    """What a finished (or partly finished) run has to show."""
    res = run.root / "results"
    out = {"tables": [], "figures": [], "allan": [], "files": [], "truth": []}
    if not res.is_dir():
        return out
    import glob

    from imugen.tables import layout
    from imugen.tables import truth as ttruth

    root = glob.escape(str(res))

    def find(pattern: str) -> list[Path]:
        return sorted(map(Path, glob.glob(pattern)))

    for t in find(layout.rmse("*", "html", root=root)):
        out["tables"].append((t.parent.name, t.read_text()))
    for f in find(layout.figure("*", "png", route="*", root=root)):
        out["figures"].append(str(f.relative_to(run.root)))
    for f in find(layout.allan("*", "png", root=root)):
        out["allan"].append(str(f.relative_to(run.root)))
    for t in layout.find_truths(res):
        m = ttruth.read_meta(t)
        rep = m.get("plausibility") or m.get("motion") or {}
        out["truth"].append(
            {
                "route": t.parent.name,
                "earth": m.get("earth"),
                "rate_hz": m.get("rate_hz"),
                "facts": truth_facts(m),
                "warnings": [w for w in rep.get("warnings") or [] if isinstance(w, str)],
            }
        )
    for f in sorted(res.rglob("*")):
        if f.is_file() and f.suffix in (".csv", ".md", ".tex", ".mat", ".parquet", ".json"):
            out["files"].append((str(f.relative_to(run.root)), f.stat().st_size))
    return out


def create_app(
    workdir,
    repo: Path | None = None,
    *,
    hosts=(),
    access_token: str | None = None,
    max_running: int = MAX_RUNNING,
) -> Flask:
    """The application serving the runs under ``workdir``.

    ``hosts``: names or addresses besides the loopback ones that may appear in ``Host`` (the
    ``--host`` address); ``access_token``: token that admits a browser (None: none, for tests
    of the other guards; :func:`serve` always sets one); ``max_running``: runs at once.
    """
    repo = Path(repo) if repo else find_repo()
    schema = fm.load_schema(repo)
    runs = Runs(Path(workdir))
    guard = Guard(hosts, access_token)
    checks = threading.BoundedSemaphore(MAX_CHECKS)
    app = Flask(__name__)
    app.config["MAX_CONTENT_LENGTH"] = MAX_UPLOAD
    app.config["GUARD"] = guard

    def page(template, status=200, **kw):
        from imugen.sensors.grades import presets

        kw.setdefault("error", None)
        return (
            render_template(
                template,
                route_fields=fm.route_fields(schema),
                sections=fm.section_fields(schema),
                presets=presets(),
                **kw,
            ),
            status,
        )

    def refuse(status: int, message: str):
        return Response(f"imugen serve: {message}\n", status, mimetype="text/plain")

    @app.before_request
    def check_request():
        if not guard.host_allowed(request.host):
            return refuse(400, "this page answers only to loopback names and its --host")
        if guard.access_token is not None:
            cookie = Guard.cookie_name(request.host)
            if not guard.token_ok(request.cookies.get(cookie)):
                if request.method == "GET" and guard.token_ok(request.args.get("token")):
                    resp = redirect(request.path)
                    resp.set_cookie(
                        cookie, guard.access_token, httponly=True, samesite="Strict", path="/"
                    )
                    return resp
                return refuse(403, "open the address `imugen serve` printed (with its token)")
        if request.method not in ("GET", "HEAD", "OPTIONS"):
            if request.mimetype not in ("application/x-www-form-urlencoded", "multipart/form-data"):
                return refuse(415, "only this page's forms may change anything")
            if not same_origin(request):
                return refuse(403, "a request from another site was refused")
            if not guard.form_ok(request.form.get("csrf_token")):
                return refuse(403, "the form is out of date (the server restarted?): reload it")
        return None

    @app.after_request
    def headers(resp):
        for k, v in HEADERS.items():
            resp.headers.setdefault(k, v)
        if request.endpoint == "files":
            resp.headers["Content-Security-Policy"] = HEADERS["Content-Security-Policy"] + (
                "; sandbox"
            )
        if request.endpoint != "static":
            resp.headers.setdefault("Cache-Control", "no-store")
        return resp

    @app.context_processor
    def tokens():
        return {"csrf_token": guard.form_token}

    @app.errorhandler(RequestEntityTooLarge)
    def too_large(_):
        return page(
            "index.html",
            413,
            runs=runs.all(),
            values={},
            error=f"upload larger than {MAX_UPLOAD >> 20} MiB",
        )

    @app.get("/")
    def index():
        return page("index.html", runs=runs.all(), values={})

    @app.post("/runs")
    def create():
        def refused(status, message):
            values = fm.form_values(schema, request.form)
            return page("index.html", status, runs=runs.all(), values=values, error=message)

        up = request.files.get("route")
        if not up or not up.filename:
            return refused(400, "choose a route file")
        name = safe_name(up.filename)
        try:  # everything that can be checked before a run folder exists
            cfg = fm.config_from_form(
                schema,
                request.form,
                str(Path("input") / name),
                _grades(request.form, request.files),
            )
            fm.validate(cfg, repo)
        except InputError as exc:
            return refused(400, str(exc))
        if not checks.acquire(blocking=False):
            return refused(429, f"{MAX_CHECKS} route checks are running: try again in a moment")
        try:
            run = runs.new()
            try:
                route = run.root / "input" / name
                up.save(route)
                _preview(run, route, cfg["routes"]["route"])
                run.write_config(cfg)
            except BaseException:
                shutil.rmtree(run.root, ignore_errors=True)
                raise
        except InputError as exc:
            return refused(400, str(exc))
        finally:
            checks.release()
        return redirect(url_for("show", rid=run.id))

    def get(rid) -> Run:
        try:
            return runs.get(rid)
        except InputError:
            abort(404)

    def run_page(run: Run, status: int = 200, values=None, error=None):
        cfg = run.config()
        return page(
            "run.html",
            status,
            run=run,
            cfg=cfg,
            values=fm.config_values(schema, cfg) if values is None else values,
            plan=plan(run),
            res=results(run),
            prog=run.progress(),
            error=error,
        )

    @app.get("/runs/<rid>")
    def show(rid):
        return run_page(get(rid))

    @app.post("/runs/<rid>/config")
    def reconfigure(rid):
        run = get(rid)
        values = fm.form_values(schema, request.form)
        if run.running:
            return run_page(run, 409, values, "the run is running: cancel it to change options")
        route = run.config()["routes"]["route"]
        try:
            grades = _grades(request.form, request.files) or run.config().get("grades", {})
            cfg = fm.config_from_form(schema, request.form, route["file"], grades)
            fm.validate(cfg, repo)
        except InputError as exc:
            return run_page(run, 400, values, str(exc))
        run.write_config(cfg)
        return redirect(url_for("show", rid=rid))

    @app.post("/runs/<rid>/start")
    def start(rid):
        run = get(rid)
        if not run.config_path.exists():
            abort(404)
        try:
            runs.start(run, repo / "Snakefile", CORES_PER_RUN, max_running)
        except Refused as exc:
            return run_page(run, exc.status, error=str(exc))
        return redirect(url_for("show", rid=rid))

    @app.post("/runs/<rid>/cancel")
    def cancel(rid):
        get(rid).cancel()
        return redirect(url_for("show", rid=rid))

    @app.get("/runs/<rid>/progress.json")
    def progress(rid):
        return jsonify(get(rid).progress())

    @app.get("/runs/<rid>/files/<path:sub>")
    def files(rid, sub):
        run = get(rid)
        if "\x00" in sub or len(sub) > MAX_PATH_CHARS:
            abort(404)
        try:
            target = (run.root / sub).resolve()
            allowed = (run.root / "results").resolve(), (run.root / "report.html").resolve()
            inside = target == allowed[1] or allowed[0] in target.parents
            if not inside or not target.is_file():
                abort(404)
        except (OSError, ValueError):
            abort(404)
        return send_file(target, as_attachment=request.args.get("download") == "1")

    @app.get("/runs/<rid>/results.zip")
    def archive(rid):
        run = get(rid)
        if not (run.root / "results").is_dir():
            abort(404)
        if not checks.acquire(blocking=False):
            return refuse(429, f"{MAX_CHECKS} archives or checks are running: try again soon")

        def body():
            try:
                yield from run.iter_results_zip()
            finally:
                checks.release()

        return Response(
            stream_with_context(body()),
            mimetype="application/zip",
            headers={"Content-Disposition": f'attachment; filename="imugen-{rid}.zip"'},
        )

    @app.post("/runs/<rid>/report")
    def report(rid):
        run = get(rid)
        if run.running:
            return run_page(run, 409, error="the run is running: the report follows its end")
        if not checks.acquire(blocking=False):
            return run_page(run, 429, error=f"{MAX_CHECKS} checks are running: try again soon")
        try:
            subprocess.run(
                [
                    sys.executable,
                    "-m",
                    "snakemake",
                    "-s",
                    str(repo / "Snakefile"),
                    "-d",
                    str(run.root),
                    "--report",
                    "report.html",
                ],
                capture_output=True,
                timeout=REPORT_TIMEOUT_S,
            )
        except subprocess.TimeoutExpired:
            return run_page(run, 409, error=f"the report took longer than {REPORT_TIMEOUT_S} s")
        finally:
            checks.release()
        if not (run.root / "report.html").exists():
            return run_page(run, 409, error="Snakemake wrote no report (see the log)")
        return redirect(url_for("files", rid=rid, sub="report.html", download="1"))

    return app


def serve(workdir, host: str = "127.0.0.1", port: int = 8765, repo=None) -> None:
    """Run the page (Werkzeug's threaded server: a local, single-user tool).

    The page answers to loopback names and ``host``; it admits the browser that opens the
    printed address (its random token becomes a cookie); files are written for the user only.
    """
    from werkzeug.serving import run_simple

    os.umask(0o077)
    token = secrets.token_urlsafe(24)
    app = create_app(workdir, repo, hosts=[host], access_token=token)
    if not is_loopback(host):
        print(f"imugen: warning: serving on {host}: reachable from other machines", file=sys.stderr)
    shown = f"[{host}]" if ":" in host else host
    print(
        f"imugen serve: http://{shown}:{port}/?token={token} "
        f"(runs in {Path(workdir).resolve() / 'runs'})",
        file=sys.stderr,
    )
    run_simple(host, port, app, threaded=True)
