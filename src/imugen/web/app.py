"""The Flask application of ``imugen serve`` (see :mod:`imugen.web`)."""

from __future__ import annotations

import math
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
from flask import Flask, abort, jsonify, redirect, render_template, request, send_file, url_for
from werkzeug.exceptions import RequestEntityTooLarge

from imugen.core.errors import InputError
from imugen.web import form as fm
from imugen.web.runs import Run, Runs, safe_name

MAX_UPLOAD = 64 << 20
"""Largest upload (route file or IMU description) [bytes]."""
INGEST_TIMEOUT_S = 120


def find_repo() -> Path:
    """The project folder holding ``Snakefile`` (the source tree of an editable install)."""
    for base in (Path(__file__).resolve().parents[3], Path.cwd()):
        if (base / "Snakefile").is_file() and (base / "workflow").is_dir():
            return base
    raise InputError("imugen serve", "cannot find the workflow (Snakefile): pass --repo")


def _grades(form, files, runs_dir: Path) -> dict:
    from imugen.sensors.grades import presets

    grades = {g: {} for g in form.getlist("grades") if g in presets()}
    up = files.get("kalibr")
    if up and up.filename:
        from imugen.sensors.grade_io import import_grade

        with tempfile.TemporaryDirectory(dir=runs_dir) as d:
            p = Path(d) / safe_name(up.filename, "imu.yaml")
            up.save(p)
            name, cfg = import_grade(
                p, name=safe_name(form.get("kalibr_name") or "").lower() or None
            )
        grades[name] = cfg
    return grades


def _preview(run: Run, route: Path, cfg_route: dict) -> dict:
    """Ingest the route (same command and messages as the CLI) for its plan view."""
    out = run.root / "preview" / "enu.parquet"
    cmd = [sys.executable, "-m", "imugen", "ingest", str(route), "-o", str(out)]
    if cfg_route.get("path") is not None:
        cmd += ["--path", str(cfg_route["path"])]
    if cfg_route.get("origin"):
        cmd += ["--origin", ",".join(map(str, cfg_route["origin"]))]
    if cfg_route.get("dt_s"):
        cmd += ["--dt", str(cfg_route["dt_s"])]
    try:
        p = subprocess.run(cmd, capture_output=True, text=True, timeout=INGEST_TIMEOUT_S)
    except subprocess.TimeoutExpired:
        raise InputError(route.name, f"not read within {INGEST_TIMEOUT_S} s") from None
    if p.returncode != 0:
        line = next(
            (ln for ln in reversed(p.stderr.splitlines()) if "error:" in ln), p.stderr.strip()
        )
        raise InputError(
            None, line.replace("imugen: error: ", "").replace(str(route.parent) + "/", "")
        )
    return plan(run)


def plan(run: Run) -> dict | None:
    """Plan view (SVG points), length, duration and warnings of the ingested route."""
    out = run.root / "preview" / "enu.parquet"
    if not out.exists():
        return None
    import pandas as pd

    from imugen.core.io import read_meta

    meta = read_meta(out)
    df = pd.read_parquet(out, columns=["e_m", "n_m"])
    e, n = df["e_m"].to_numpy(), df["n_m"].to_numpy()
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


def results(run: Run) -> dict:
    """What a finished (or partly finished) run has to show."""
    res = run.root / "results"
    out = {"tables": [], "figures": [], "allan": [], "files": [], "truth": []}
    if not res.is_dir():
        return out
    from imugen.core.io import read_meta

    for t in sorted(res.glob("*/rmse.html")):
        out["tables"].append((t.parent.name, t.read_text()))
    for f in sorted(res.glob("*/figures/*.png")):
        out["figures"].append(str(f.relative_to(run.root)))
    for f in sorted(res.glob("allan/*/allan.png")):
        out["allan"].append(str(f.relative_to(run.root)))
    for t in sorted(res.glob("*/truth.parquet")):
        m = read_meta(t)
        out["truth"].append(
            (t.parent.name, m.get("earth"), m.get("plausibility") or m.get("motion"))
        )
    for f in sorted(res.rglob("*")):
        if f.is_file() and f.suffix in (".csv", ".md", ".tex", ".mat", ".parquet", ".json"):
            out["files"].append((str(f.relative_to(run.root)), f.stat().st_size))
    return out


def create_app(workdir, repo: Path | None = None) -> Flask:
    """The application serving the runs under ``workdir``."""
    repo = Path(repo) if repo else find_repo()
    schema = fm.load_schema(repo)
    runs = Runs(Path(workdir))
    app = Flask(__name__)
    app.config["MAX_CONTENT_LENGTH"] = MAX_UPLOAD

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
        up = request.files.get("route")
        if not up or not up.filename:
            return page(
                "index.html",
                400,
                runs=runs.all(),
                values=fm.form_values(schema, request.form),
                error="choose a route file",
            )
        run = runs.new()
        route = run.root / "input" / safe_name(up.filename)
        up.save(route)
        try:
            cfg = fm.config_from_form(
                schema,
                request.form,
                str(Path("input") / route.name),
                _grades(request.form, request.files, runs.dir),
            )
            fm.validate(cfg, repo)
            _preview(run, route, cfg["routes"]["route"])
        except InputError as exc:
            shutil.rmtree(run.root, ignore_errors=True)
            return page(
                "index.html",
                400,
                runs=runs.all(),
                values=fm.form_values(schema, request.form),
                error=str(exc),
            )
        run.write_config(cfg)
        return redirect(url_for("show", rid=run.id))

    def get(rid) -> Run:
        try:
            return runs.get(rid)
        except InputError:
            abort(404)

    @app.get("/runs/<rid>")
    def show(rid):
        run = get(rid)
        cfg = run.config()
        return page(
            "run.html",
            run=run,
            cfg=cfg,
            values=fm.config_values(schema, cfg),
            plan=plan(run),
            res=results(run),
            prog=run.progress(),
        )

    @app.post("/runs/<rid>/config")
    def reconfigure(rid):
        run = get(rid)
        old = run.config()
        route = old["routes"]["route"]
        try:
            grades = _grades(request.form, request.files, runs.dir) or old.get("grades", {})
            cfg = fm.config_from_form(schema, request.form, route["file"], grades)
            fm.validate(cfg, repo)
        except InputError as exc:
            return page(
                "run.html",
                400,
                run=run,
                cfg=old,
                values=fm.form_values(schema, request.form),
                plan=plan(run),
                res=results(run),
                prog=run.progress(),
                error=str(exc),
            )
        run.write_config(cfg)
        return redirect(url_for("show", rid=rid))

    @app.post("/runs/<rid>/start")
    def start(rid):
        run = get(rid)
        try:
            run.start(repo / "Snakefile")
        except InputError as exc:
            cfg = run.config()
            return page(
                "run.html",
                409,
                run=run,
                cfg=cfg,
                values=fm.config_values(schema, cfg),
                plan=plan(run),
                res=results(run),
                prog=run.progress(),
                error=str(exc),
            )
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
        target = (run.root / sub).resolve()
        allowed = (run.root / "results").resolve(), (run.root / "report.html").resolve()
        if not (target == allowed[1] or allowed[0] in target.parents) or not target.is_file():
            abort(404)
        return send_file(target, as_attachment=request.args.get("download") == "1")

    @app.get("/runs/<rid>/results.zip")
    def archive(rid):
        run = get(rid)
        if not (run.root / "results").is_dir():
            abort(404)
        tmp = Path(tempfile.mkdtemp(dir=runs.dir))
        z = shutil.make_archive(str(tmp / f"imugen-{rid}"), "zip", run.root, "results")
        return send_file(z, as_attachment=True, download_name=f"imugen-{rid}.zip")

    @app.post("/runs/<rid>/report")
    def report(rid):
        run = get(rid)
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
            timeout=600,
        )
        if not (run.root / "report.html").exists():
            abort(409)
        return redirect(url_for("files", rid=rid, sub="report.html", download="1"))

    return app


def serve(workdir, host: str = "127.0.0.1", port: int = 8765, repo=None) -> None:
    """Run the page (Werkzeug's threaded server: a local, single-user tool)."""
    from werkzeug.serving import run_simple

    app = create_app(workdir, repo)
    if host not in ("127.0.0.1", "localhost", "::1"):
        print(f"imugen: warning: serving on {host}: reachable from other machines", file=sys.stderr)
    print(
        f"imugen serve: http://{host}:{port}/ (runs in {Path(workdir).resolve() / 'runs'})",
        file=sys.stderr,
    )
    run_simple(host, port, app, threaded=True)
