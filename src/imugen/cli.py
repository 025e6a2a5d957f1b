"""Command line: ``imugen <stage> ...``, a thin dispatcher onto the stages' functions.

A user's mistake (bad file, bad option) prints one line ``imugen: error: FILE: problem``
and exits with status 2; no traceback, no partial output.
"""

from __future__ import annotations

import argparse
import json
import sys

from imugen import __version__
from imugen.errors import InputError


def _add_ingest_options(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--path", help="candidate path name, or 1-based index, when the file has several"
    )
    p.add_argument("--origin", metavar="LAT,LON,H", help="ENU origin (default: first point)")
    p.add_argument("--dt", type=float, metavar="SECONDS", help="uniform clock for an untimed path")


def _cmd_ingest(a) -> int:
    from imugen.ingest import run

    ing = run(
        a.src,
        a.output,
        path=a.path,
        origin=a.origin,
        dt=a.dt,
        utm=a.utm,
        max_speed_kmh=a.max_speed_kmh,
        max_extent_km=a.max_extent_km,
        gap_warn_s=a.gap_warn_s,
    )
    for w in ing.warnings:
        print(f"imugen: warning: {a.src}: {w}", file=sys.stderr)
    m = ing.meta
    print(
        f"{a.output}: path {m['path']!r}, {m['points_out']} points, "
        f"{m['length_3d_m']:.1f} m, {'timed ' + format(m['duration_s'], '.1f') + ' s' if m['timed'] else 'untimed'}, "
        f"origin {m['origin']['lat_deg']:.7f},{m['origin']['lon_deg']:.7f},{m['origin']['alt_m']:.2f}",
        file=sys.stderr,
    )
    return 0


def _cmd_truth(a) -> int:
    from imugen.truth import run

    run(a.enu, a.output, rate_hz=a.rate_hz, earth=a.earth, vehicle=a.vehicle, grade=a.grade)
    return 0


def _cmd_simulate(a) -> int:
    from imugen.simulate import run

    if a.truth is None and a.static is None:
        raise InputError("imugen simulate", "give a TRUTH.parquet or --static SECONDS")
    if a.truth is not None and a.static is not None:
        raise InputError("imugen simulate", "give either a TRUTH.parquet or --static, not both")
    terms = None if a.terms is None else [t.strip() for t in a.terms.split(",") if t.strip()]
    temperature = None
    if a.temperature is not None:
        try:
            temperature = json.loads(a.temperature)
        except json.JSONDecodeError as exc:
            raise InputError("--temperature", f"is not JSON ({exc.msg})") from None
    meta = run(
        truth=a.truth,
        out=a.output,
        grade=a.grade,
        sequences=a.sequences,
        seed=a.seed,
        shard=a.shard,
        static_s=a.static,
        rate_hz=a.rate_hz,
        outputs=a.outputs,
        draw=a.draw,
        terms=terms,
        temperature=temperature,
        series=a.series,
        dtype=a.dtype,
        grades_file=a.grades_file,
        static_earth=a.earth,
        shard_size=a.shard_size,
        route=a.route,
        increments=a.increments,
        navigate=a.navigate,
        eval_rate_hz=a.eval_rate_hz,
    )
    written = " + ".join(p for p in (a.output, a.navigate) if p is not None)
    print(
        f"{written}: grade {meta['grade']['name']!r}, {a.sequences} sequences, shard {a.shard}, "
        f"seed {a.seed}",
        file=sys.stderr,
    )
    return 0


def _cmd_allan(a) -> int:
    from imugen.allan import run

    print(json.dumps(run(a.shard, plot=a.plot, max_sequences=a.max_sequences)))
    return 0


def _cmd_navigate(a) -> int:
    from imugen.navigate import run

    run(a.truth, a.shard, a.output, eval_rate_hz=a.eval_rate_hz)
    return 0


def _cmd_evaluate(a) -> int:
    from imugen.evaluate import run

    run(a.truth, a.nav, a.output, grade=a.grade)
    return 0


def _cmd_tables(a) -> int:
    from imugen.evaluate import run_tables

    paths = run_tables(a.metrics, a.output)
    print(paths["md"].read_text(), file=sys.stderr)
    return 0


def _pairs(items, option):
    """``GRADE=PATH`` options -> {grade: [paths]} in the given order."""
    out: dict[str, list[str]] = {}
    for item in items or []:
        grade, sep, path = item.partition("=")
        if not sep or not grade or not path:
            raise InputError(option, f"{item!r} is not GRADE=PATH")
        out.setdefault(grade, []).append(path)
    return out


def _cmd_figures(a) -> int:
    from pathlib import Path

    from imugen import figures as fg

    nav = _pairs(a.nav, "--nav")
    metrics = {g: p[0] for g, p in _pairs(a.metrics, "--metrics").items()}
    imu = {g: p[0] for g, p in _pairs(a.imu, "--imu").items()}
    out = Path(a.outdir)
    kw = {"formats": tuple(a.formats), "dpi": a.dpi}
    fg.figure8(
        a.truth,
        nav,
        metrics,
        out / "figure8",
        zoom_fraction=a.zoom_fraction,
        representative=a.representative,
        **kw,
    )
    fg.trajectories_3d(
        a.truth, nav, metrics, out / "trajectories_3d", representative=a.representative, **kw
    )
    fg.error_vs_time(nav, out / "error_vs_time", **kw)
    for grade, shard in imu.items():
        fg.imu_signals(a.truth, shard, out / f"imu_{grade}", **kw)
    return 0


def _cmd_export_mat(a) -> int:
    from imugen.export import export_mat

    export_mat(
        a.truth,
        a.shards,
        a.output,
        grade=a.grade,
        nav_paths=a.nav,
        version=a.mat_version,
        route=a.route,
    )
    return 0


def _cmd_closure(a) -> int:
    from imugen.closure import closure

    result = closure(
        a.src,
        rate_hz=a.rate_hz,
        earth=a.earth,
        vehicle=a.vehicle,
        path=a.path,
        origin=a.origin,
        dt=a.dt,
        grade=a.grade,
    )
    print(json.dumps(result))
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="imugen", description=__doc__.splitlines()[0])
    parser.add_argument("--version", action="version", version=f"imugen {__version__}")
    sub = parser.add_subparsers(dest="command", required=True)

    p = sub.add_parser("ingest", help="route file -> geodetic table + local ENU (.parquet/.csv)")
    p.add_argument("src", help="KML, KMZ, GPX, CSV or E N U text file")
    p.add_argument("-o", "--output", required=True, help="output file ending in .parquet or .csv")
    _add_ingest_options(p)
    p.add_argument("--utm", action="store_true", help="also write UTM easting/northing columns")
    p.add_argument(
        "--max-speed-kmh", type=float, default=1200.0, help="refuse faster implied speeds"
    )
    p.add_argument(
        "--max-extent-km", type=float, default=100.0, help="largest distance from origin"
    )
    p.add_argument("--gap-warn-s", type=float, default=60.0, help="warn about longer time gaps")
    p.set_defaults(func=_cmd_ingest)

    p = sub.add_parser("truth", help="ENU route -> 6-DoF truth and ideal IMU at the IMU rate")
    p.add_argument("enu", help="ENU Parquet written by `imugen ingest`")
    p.add_argument("-o", "--output", required=True, help="truth Parquet")
    _add_truth_options(p)
    p.add_argument(
        "--grade",
        action="append",
        help="sensor grade(s) whose error budget `--earth auto` compares the dropped terms "
        "with (repeat for several: the most demanding decides; default consumer)",
    )
    p.set_defaults(func=_cmd_truth)

    p = sub.add_parser("closure", help="ingest -> truth -> mechanize the ideal IMU; print errors")
    p.add_argument("src", help="any route file ingestion reads")
    _add_truth_options(p)
    _add_ingest_options(p)
    p.add_argument("--grade", help="grade for the `--earth auto` budget")
    p.set_defaults(func=_cmd_closure)

    p = sub.add_parser("simulate", help="truth (or a still IMU) -> one shard of erroneous IMU")
    p.add_argument("truth", nargs="?", help="truth Parquet written by `imugen truth`")
    p.add_argument(
        "-o", "--output", help="shard Parquet (labels go beside it); optional with --navigate"
    )
    p.add_argument(
        "--navigate",
        metavar="NAV.parquet",
        help="also navigate the shard in the same pass and write its error table here (as "
        "`imugen navigate` would, without re-reading the shard); without -o no shard is written",
    )
    p.add_argument(
        "--eval-rate-hz", type=float, default=1.0, help="with --navigate: error epochs per second"
    )
    p.add_argument("--grade", required=True, help="preset name, or FILE.yaml:NAME")
    p.add_argument("--sequences", type=int, required=True, help="sequences in this shard (M)")
    p.add_argument("--seed", type=int, required=True, help="base seed of the experiment")
    p.add_argument("--shard", type=int, required=True, help="shard index K (0-based)")
    p.add_argument(
        "--shard-size",
        type=int,
        metavar="M",
        help="sequences per shard of the experiment: global ids are K*M+j (default: "
        "--sequences; give it for a shorter last shard)",
    )
    p.add_argument("--static", type=float, metavar="SECONDS", help="simulate a still, level IMU")
    p.add_argument("--rate-hz", type=float, default=100.0, help="IMU rate for --static")
    p.add_argument("--earth", choices=["flat", "wgs84"], default="flat", help="for --static")
    p.add_argument("--outputs", choices=["increments", "rates", "both"], default="increments")
    p.add_argument("--draw", choices=["ranges", "nominal"], default="ranges")
    p.add_argument("--terms", help="comma-separated error terms to keep (default: all)")
    p.add_argument("--temperature", metavar="JSON", help="temperature profile (see docs)")
    p.add_argument(
        "--series",
        action="store_true",
        help="also write the true bias, scale-factor and effective-error series",
    )
    p.add_argument(
        "--increments",
        choices=["compensated", "raw"],
        default="compensated",
        help="increment semantics: compensated (rotation vector; body frame frozen at the "
        "interval start, sculling included) or raw (plain integrals of rate and specific force)",
    )
    p.add_argument("--dtype", choices=["float32", "float64"], default="float32")
    p.add_argument("--grades-file", help="YAML file with custom grades")
    p.add_argument(
        "--route",
        help="route name: its id enters every spawn key and the sequence ids (default: the "
        "route recorded in the truth metadata, else the truth file's folder name; 'static' "
        "with --static)",
    )
    p.set_defaults(func=_cmd_simulate)

    p = sub.add_parser("navigate", help="shard of IMU sequences -> strapdown -> errors vs truth")
    p.add_argument("truth", help="truth Parquet")
    p.add_argument("shard", help="shard Parquet written by `imugen simulate`")
    p.add_argument("-o", "--output", required=True, help="navigation-error Parquet")
    p.add_argument("--eval-rate-hz", type=float, default=1.0, help="evaluation epochs per second")
    p.set_defaults(func=_cmd_navigate)

    p = sub.add_parser("evaluate", help="navigation errors of one grade -> per-sequence RMSE")
    p.add_argument("truth", help="truth Parquet")
    p.add_argument("nav", nargs="+", help="navigation-error Parquet files of the grade")
    p.add_argument("-o", "--output", required=True, help="per-sequence metrics Parquet")
    p.add_argument("--grade", required=True, help="grade name (recorded in the output)")
    p.set_defaults(func=_cmd_evaluate)

    p = sub.add_parser("tables", help="per-grade metrics -> RMSE table (CSV, MD, TeX, HTML)")
    p.add_argument("metrics", nargs="+", help="metrics Parquet files, one per grade")
    p.add_argument("-o", "--output", required=True, help="CSV path; .md/.tex/.html beside it")
    p.set_defaults(func=_cmd_tables)

    p = sub.add_parser("figures", help="route figures: Figure 8, 3-D, errors vs time, IMU")
    p.add_argument("truth", help="truth Parquet")
    p.add_argument("-o", "--outdir", required=True, help="folder for the figures")
    p.add_argument("--nav", action="append", metavar="GRADE=PATH", help="navigation errors")
    p.add_argument("--metrics", action="append", metavar="GRADE=PATH", help="per-sequence RMSE")
    p.add_argument("--imu", action="append", metavar="GRADE=PATH", help="a shard per grade")
    p.add_argument("--formats", nargs="+", default=["png", "svg"], help="figure formats")
    p.add_argument("--dpi", type=int, default=150)
    p.add_argument("--zoom-fraction", type=float, default=0.2, help="zoom of Figure 8")
    p.add_argument("--representative", choices=["median", "best", "worst"], default="median")
    p.set_defaults(func=_cmd_figures)

    p = sub.add_parser("export-mat", help="one grade's truth, IMU, labels, errors -> MATLAB .mat")
    p.add_argument("--truth", required=True, help="truth Parquet")
    p.add_argument("--shards", nargs="+", required=True, help="the grade's shard Parquet files")
    p.add_argument("--nav", nargs="+", help="the grade's navigation-error files (optional)")
    p.add_argument("--grade", required=True, help="grade name (checked against the shards)")
    p.add_argument("--route", help="route name recorded in the file (default: truth's folder)")
    p.add_argument("--mat-version", choices=["auto", "5", "7.3"], default="auto")
    p.add_argument("-o", "--output", required=True, help=".mat path")
    p.set_defaults(func=_cmd_export_mat)

    p = sub.add_parser("allan", help="Allan deviation of a static shard against its grade")
    p.add_argument("shard", help="shard Parquet written by `imugen simulate --static`")
    p.add_argument("--plot", help="also draw the Allan plot to this PNG/SVG")
    p.add_argument("--max-sequences", type=int, default=16, help="sequences to analyse")
    p.set_defaults(func=_cmd_allan)
    return parser


def _add_truth_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("--rate-hz", type=float, default=100.0, help="IMU rate (default 100)")
    p.add_argument("--earth", choices=["flat", "wgs84", "auto"], default="flat")
    p.add_argument("--vehicle", choices=["car", "aircraft", "pedestrian"], default="car")


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return args.func(args)
    except InputError as exc:
        print(f"imugen: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("imugen: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
