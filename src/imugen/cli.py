"""Command line: ``imugen <stage> ...``, a thin dispatcher onto the stages' functions.

A user's mistake (bad file, bad option) prints one line ``imugen: error: FILE: problem``
and exits with status 2; no traceback, no partial output. A warning a stage raises
(``warnings.warn``, a UserWarning) prints one line ``imugen: warning: message``; other
categories (a library's RuntimeWarning) keep their category and origin on that one line.
Control characters that a file could smuggle into a message (terminal escapes, carriage
returns) are printed escaped.
"""

from __future__ import annotations

import argparse
import functools
import json
import sys
import warnings

from imugen import __version__
from imugen.core.errors import InputError

VEHICLES = ("car", "bicycle", "pedestrian", "aircraft", "airliner")
"""Vehicle classes of ``--vehicle``: the cleaning limits of ``ingest`` and the motion models of
``truth`` (listed here so that the parser imports no stage; tests/system/test_cli.py checks
both stages define exactly these)."""


def _printable(text: str) -> str:
    """``text`` with non-printable characters escaped (``\\x1b``), so a message stays one line."""
    if text.isprintable():
        return text
    return "".join(c if c.isprintable() else c.encode("unicode_escape").decode() for c in text)


class _HelpFormatter(argparse.HelpFormatter):
    """The one help formatter of every command: each option's help ends with its default,
    ``(default: X)``, printed once, by this formatter (a help text never repeats it; an option
    without a default value, or a flag, shows none)."""

    def _get_help_string(self, action):
        text = action.help or ""
        default = action.default
        if (
            not action.option_strings
            or default is None
            or default is argparse.SUPPRESS
            or isinstance(default, bool)
            or default == []
        ):
            return text
        return f"{text} (default: %(default)s)"


def _route_formats() -> str:
    """The route formats ingestion reads, from the reader registry."""
    from imugen.ingest.readers import FORMATS

    own = [f.name for f in FORMATS if f.module != "babel"]
    babel = [f.name for f in FORMATS if f.module == "babel"]
    return f"{', '.join(own)} (told apart by content); {', '.join(babel)} (by suffix, through GPSBabel)"


def _add_ingest_options(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--path", help="candidate path name, or 1-based index, when the file has several"
    )
    p.add_argument("--origin", metavar="LAT,LON,H", help="ENU origin (default: first point)")
    p.add_argument("--dt", type=float, metavar="SECONDS", help="uniform clock for an untimed path")


def _cmd_ingest(a) -> int:
    from imugen.ingest.stage import run

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
        vehicle=a.vehicle,
        max_gap_s=a.max_gap_s,
        gaps=a.gaps,
    )
    for w in ing.warnings:
        print(_printable(f"imugen: warning: {a.src}: {w}"), file=sys.stderr)
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

    params = {}
    for item in a.vehicle_param or []:
        name, sep, value = item.partition("=")
        if not sep or not name or not value:
            raise InputError("--vehicle-param", f"{item!r} is not NAME=VALUE")
        params[name] = value.split(",") if "," in value else value
    run(
        a.enu,
        a.output,
        rate_hz=a.rate_hz,
        earth=a.earth,
        vehicle=a.vehicle,
        grade=a.grade,
        vehicle_params=params or None,
    )
    return 0


def _cmd_simulate(a) -> int:
    from imugen.simulate.stage import run

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
    mounting = None
    if a.mounting is not None:
        try:
            mounting = json.loads(a.mounting)
        except json.JSONDecodeError as exc:
            raise InputError("--mounting", f"is not JSON ({exc.msg})") from None
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
        explicit_time=a.time_column,
        grades_file=a.grades_file,
        static_earth=a.earth,
        shard_size=a.shard_size,
        route=a.route,
        increments=a.increments,
        vibration=a.vibration,
        mounting=mounting,
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
    from imugen.allan.stage import run

    rep = run(a.shard, plot=a.plot, max_sequences=a.max_sequences, out=a.output)
    if a.output is None:
        print(json.dumps(rep))
    return 0


def _cmd_navigate(a) -> int:
    from imugen.navigate.stage import run

    run(a.truth, a.shard, a.output, eval_rate_hz=a.eval_rate_hz)
    return 0


def _cmd_aid(a) -> int:
    from imugen.aid.stage import AidParams, parse_scenarios, run

    try:
        lever = [float(x) for x in a.lever_arm.split(",")]
    except ValueError:
        lever = []
    if len(lever) != 3:
        raise InputError("--lever-arm", f"expected X,Y,Z in metres, got {a.lever_arm!r}")
    params = AidParams(
        receiver=a.receiver, rate_hz=a.gnss_rate_hz, draw=a.gnss_draw, lever_arm_b_m=lever,
        lever_arm_sd_m=a.lever_arm_sd, settle_s=a.settle_s, tuning_level=a.tuning_level,
        gnss_bias_states=not a.no_gnss_bias_states, scale_factors=a.scale_factors, nhc=a.nhc,
        nhc_slip_sd_mps=_floats(a.nhc_slip_sd, "--nhc-slip-sd"),
        gyro_cross_coupling=not a.no_cross_coupling,
        zupt=not a.no_zupt, gate_sigma=a.gate_sigma, align_speed_mps=a.align_speed,
        eval_rate_hz=a.eval_rate_hz, seed=a.seed,
        grade=a.grade, odometer=a.odometer, odometer_rate_hz=a.odometer_rate_hz,
        odometer_lever_b_m=_xyz(a.odometer_lever, "--odometer-lever"),
        odometer_scale_state=not a.no_odometer_scale_state, barometer=a.baro,
        barometer_rate_hz=a.baro_rate_hz, companion_draw=a.companion_draw,
        **parse_scenarios(a.scenario),
    )  # fmt: skip
    run(a.truth, a.shard, a.gnss_out, a.output, params, out_companions=a.companions_out)
    return 0


def _floats(text: str | None, option: str) -> list[float] | None:
    """``"A[,B...]"`` -> floats (None stays None; InputError naming ``option`` otherwise)."""
    if text is None:
        return None
    try:
        return [float(x) for x in text.split(",")]
    except ValueError:
        raise InputError(option, f"expected comma-separated numbers, got {text!r}") from None


def _xyz(text: str, option: str) -> list[float]:
    """``"X,Y,Z"`` metres -> three floats (InputError naming ``option`` otherwise)."""
    try:
        out = [float(x) for x in text.split(",")]
    except ValueError:
        out = []
    if len(out) != 3:
        raise InputError(option, f"expected X,Y,Z in metres, got {text!r}")
    return out


def _seconds_list(text: str) -> list[float]:
    """``"30,60,120"`` -> ``[30.0, 60.0, 120.0]`` (argparse type of ``--segments``)."""
    try:
        out = [float(x) for x in text.split(",") if x.strip()]
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"not a comma-separated list of seconds: {text!r}"
        ) from None
    if not out or any(not x > 0 for x in out):
        raise argparse.ArgumentTypeError(f"need durations > 0 s, got {text!r}")
    return out


def _cmd_evaluate(a) -> int:
    from imugen.evaluate.stage import run

    run(
        a.truth, a.nav, a.output, grade=a.grade, segments_s=a.segments, imu_paths=a.imu,
        aided_paths=a.aided,
    )  # fmt: skip
    return 0


def _cmd_tables(a) -> int:
    from imugen.evaluate.stage import run_tables

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


def _cmd_outage_figure(a) -> int:
    from imugen.figures.outage import outage_growth

    outage_growth(
        _pairs(a.aided, "--aided"),
        _pairs(a.nav, "--nav"),
        a.output,
        formats=tuple(a.formats),
        dpi=a.dpi,
    )
    return 0


def _cmd_figures(a) -> int:
    from pathlib import Path

    from imugen.figures import stage as fg

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
    from imugen.export.mat import export_mat

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


def _cmd_serve(a) -> int:
    try:
        from imugen.web.app import serve
    except ImportError:
        raise InputError("imugen serve", "needs Flask: pip install -e '.[web]'") from None
    serve(a.workdir, host=a.host, port=a.port, repo=a.repo)


def _cmd_export(a) -> int:
    from imugen.export.stage import export

    export(
        a.format,
        a.truth,
        a.shards,
        a.output,
        route=a.route,
        grade=a.grade,
        nav_rate_hz=a.nav_rate_hz,
        split_seed=a.split_seed,
        split_by=a.split_by,
        holdout_routes=[r.strip() for r in (a.holdout_routes or "").split(",") if r.strip()],
        val_fraction=a.val_fraction,
        test_fraction=a.test_fraction,
        sequences=a.sequences,
        storage=a.storage,
        overwrite=a.overwrite,
        gnss_paths=a.gnss,
        aided_paths=a.aided,
        companion_paths=a.companions,
    )
    return 0


def _cmd_grade_import(a) -> int:
    import warnings

    from imugen.sensors.grade_io import grades_document, import_grade, write_text

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        name, cfg = import_grade(a.file, name=a.name, grade_id=a.id)
    for w in caught:
        print(_printable(f"imugen: warning: {a.file}: {w.message}"), file=sys.stderr)
    text = grades_document(name, cfg)
    if a.output:
        write_text(a.output, text)
        print(f"{a.output}: grade {name!r} (id {cfg.get('id')})", file=sys.stderr)
    else:
        print(text, end="")
    return 0


def _cmd_grade_export(a) -> int:
    from imugen.sensors.grade_io import to_kalibr, write_text
    from imugen.sensors.grades import get_grade

    text = to_kalibr(get_grade(a.grade, a.grades_file), rate_hz=a.rate_hz, topic=a.topic)
    if a.output:
        write_text(a.output, text)
    else:
        print(text, end="")
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
    # every subcommand's help shows each option's default once (_HelpFormatter;
    # tests/system/test_cli.py checks that every option has help text, that no default is
    # printed twice and that defaults agree with the workflow's schema)
    sub = parser.add_subparsers(
        dest="command",
        required=True,
        parser_class=functools.partial(argparse.ArgumentParser, formatter_class=_HelpFormatter),
    )

    p = sub.add_parser("ingest", help="route file -> geodetic table + local ENU (.parquet/.csv)")
    p.add_argument("src", help=f"route file: {_route_formats()}")
    p.add_argument("-o", "--output", required=True, help="output file ending in .parquet or .csv")
    _add_ingest_options(p)
    p.add_argument("--utm", action="store_true", help="also write UTM easting/northing columns")
    p.add_argument(
        "--max-speed-kmh", type=float, default=1200.0, help="refuse faster implied speeds"
    )
    p.add_argument(
        "--max-extent-km",
        type=float,
        default=None,
        help="refuse points farther than this from the origin, measured along the WGS-84 "
        "geodesic between the origin and the point (heights ignored); a sanity limit of your "
        "own, default none: routes of any length, simulated in ECEF when long",
    )
    p.add_argument("--gap-warn-s", type=float, default=60.0, help="warn about longer time gaps")
    p.add_argument(
        "--vehicle",
        choices=list(VEHICLES),
        default="car",
        help="vehicle class whose limits decide what is an outlier",
    )
    p.add_argument(
        "--max-gap-s",
        type=float,
        metavar="SECONDS",
        help="time gaps longer than this split the path (default 60; see --gaps)",
    )
    p.add_argument(
        "--gaps",
        choices=["split", "bridge"],
        default="split",
        help="split the path at long gaps (parts are candidates; --path longest) or bridge them",
    )
    p.set_defaults(func=_cmd_ingest)

    p = sub.add_parser("truth", help="ENU route -> 6-DoF truth and ideal IMU at the IMU rate")
    p.add_argument("enu", help="ENU Parquet written by `imugen ingest`")
    p.add_argument("-o", "--output", required=True, help="truth Parquet")
    _add_truth_options(p)
    p.add_argument(
        "--grade",
        action="append",
        help="sensor grade(s), preset name or FILE.yaml:NAME, whose error budget `--earth auto` "
        "compares the dropped terms with (repeat for several: the most demanding decides; "
        "default consumer)",
    )
    p.add_argument(
        "--vehicle-param",
        action="append",
        metavar="NAME=VALUE",
        help="override a vehicle model parameter or limit (SI units, e.g. max_curvature_1pm=0.1)",
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
    p.add_argument(
        "--outputs",
        choices=["increments", "rates", "both"],
        default="increments",
        help="IMU columns written: angle/velocity increments, rate samples, or both",
    )
    p.add_argument(
        "--draw",
        choices=["ranges", "nominal"],
        default="ranges",
        help="error levels drawn in the grade's ranges per sequence, or nominal for all",
    )
    p.add_argument("--terms", help="comma-separated error terms to keep (default: all)")
    p.add_argument(
        "--vibration",
        choices=["off", "car", "aircraft", "vehicle"],
        default="off",
        help="vibration of the IMU case (vehicle: the truth's vehicle class)",
    )
    p.add_argument("--temperature", metavar="JSON", help="temperature profile (see docs)")
    p.add_argument(
        "--mounting",
        metavar="JSON",
        help='IMU misalignment and lever arm drawn per sequence, e.g. \'{"misalignment_sd_deg": '
        '[1, 1, 2], "lever_arm_m": [0.5, 0, 0.3], "lever_arm_sd_m": [0.05, 0.05, 0.05]}\' '
        "(without it the IMU is the vehicle frame at the vehicle reference point)",
    )
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
    p.add_argument(
        "--dtype",
        choices=["float32", "float64"],
        default="float32",
        help="storage type of the measurement columns",
    )
    p.add_argument(
        "--time-column",
        action="store_true",
        help="write time_s in every row (default: the truth's uniform clock is stored once, in "
        "the shard metadata, and readers of imugen.tables.shard rebuild the column)",
    )
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

    p = sub.add_parser("aid", help="shard + GNSS with scenarios -> aided (GNSS/INS) nav errors")
    p.add_argument("truth", help="truth Parquet")
    p.add_argument("shard", help="shard Parquet written by `imugen simulate`")
    p.add_argument("--gnss-out", required=True, help="GNSS epochs Parquet (+ .labels/.intervals)")
    p.add_argument("-o", "--output", required=True, help="aided navigation-error Parquet")
    p.add_argument("--receiver", default="standalone", help="phone, standalone, sbas or rtk")
    p.add_argument("--gnss-rate-hz", type=float, help="epoch rate (default: the receiver's)")
    p.add_argument(
        "--gnss-draw",
        default="ranges",
        choices=["ranges", "nominal"],
        help="receiver error levels drawn in the preset's ranges per sequence, or nominal",
    )
    p.add_argument("--lever-arm", default="0,0,0", metavar="X,Y,Z", help="antenna, body frame, m")
    p.add_argument("--lever-arm-sd", type=float, default=0.0, help="per-axis spread drawn, m")
    p.add_argument(
        "--scenario",
        action="append",
        default=[],
        metavar="SPEC",
        help="KIND:DURATION@START[,param=value] declared; outage:DURATION drawn per sequence; "
        "KIND drawn with the documented distributions (repeatable)",
    )
    p.add_argument("--settle-s", type=float, default=60.0, help="earliest start of a draw, s")
    p.add_argument(
        "--tuning-level",
        default="upper",
        choices=["nominal", "upper"],
        help="filter noise from the grade's nominal values or the top of their ranges",
    )
    p.add_argument("--no-gnss-bias-states", action="store_true", help="no receiver-bias states")
    p.add_argument("--scale-factors", action="store_true", help="estimate scale factors")
    p.add_argument(
        "--no-cross-coupling", action="store_true", help="do not estimate the gyro cross-coupling"
    )
    p.add_argument(
        "--nhc",
        action=argparse.BooleanOptionalAction,
        default=None,
        help="non-holonomic constraint (default: on for a car truth)",
    )
    p.add_argument(
        "--nhc-slip-sd",
        metavar="LAT[,VERT]",
        help="vehicle slip NHC must cover, 1-sigma m/s (default: the truth's plausibility report)",
    )
    p.add_argument("--no-zupt", action="store_true", help="no zero-velocity updates")
    p.add_argument("--gate-sigma", type=float, default=0.0, help="innovation gate (0: off)")
    p.add_argument(
        "--align-speed", type=float, default=5.0, help="GNSS speed of a moving alignment, m/s"
    )
    p.add_argument("--eval-rate-hz", type=float, default=1.0, help="evaluation epochs per second")
    p.add_argument("--seed", type=int, help="root seed (default: the shard's)")
    p.add_argument("--grade", help="grade of the filter tuning (default: the shard's)")
    p.add_argument("--odometer", help="odometer preset (abs, encoder); default none")
    p.add_argument("--odometer-rate-hz", type=float, help="odometer epochs per second")
    p.add_argument(
        "--odometer-lever", default="0,0,0", metavar="X,Y,Z", help="odometer point, body, m"
    )
    p.add_argument(
        "--no-odometer-scale-state",
        action="store_true",
        help="no odometer scale-factor state (noise inflated by its prior instead)",
    )
    p.add_argument("--baro", help="barometer preset (bmp388, ms5611); default none")
    p.add_argument("--baro-rate-hz", type=float, help="barometer epochs per second")
    p.add_argument(
        "--companion-draw",
        default="ranges",
        choices=["ranges", "nominal"],
        help="companion error levels drawn in the presets' ranges per sequence, or nominal",
    )
    p.add_argument("--companions-out", help="companion-sensor Parquet (+ .labels)")
    p.set_defaults(func=_cmd_aid)

    p = sub.add_parser("evaluate", help="navigation errors of one grade -> per-sequence RMSE")
    p.add_argument("truth", help="truth Parquet")
    p.add_argument("nav", nargs="+", help="navigation-error Parquet files of the grade")
    p.add_argument("-o", "--output", required=True, help="per-sequence metrics Parquet")
    p.add_argument("--grade", required=True, help="grade name (recorded in the output)")
    p.add_argument(
        "--segments",
        type=_seconds_list,
        default=[],
        metavar="T,T,...",
        help="relative drift after T seconds from true starts (needs --imu), e.g. 30,60,120",
    )
    p.add_argument("--imu", nargs="+", default=[], help="IMU shards of the grade (for --segments)")
    p.add_argument(
        "--aided", nargs="+", default=[], help="aided error tables of the grade (imugen aid)"
    )
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
    p.add_argument("--dpi", type=int, default=150, help="raster resolution of PNG figures")
    p.add_argument("--zoom-fraction", type=float, default=0.2, help="zoom of Figure 8")
    p.add_argument(
        "--representative",
        choices=["median", "best", "worst"],
        default="median",
        help="which sequence represents a grade in Figure 8 (by total RMSE)",
    )
    p.set_defaults(func=_cmd_figures)

    p = sub.add_parser(
        "outage-figure",
        help="aided error growth during GNSS outages per grade, free inertial beside",
    )
    p.add_argument("-o", "--output", required=True, help="figure path without extension")
    p.add_argument(
        "--aided", action="append", required=True, metavar="GRADE=PATH", help="aided tables"
    )
    p.add_argument("--nav", action="append", metavar="GRADE=PATH", help="navigation errors")
    p.add_argument("--formats", nargs="+", default=["png", "svg"], help="figure formats")
    p.add_argument("--dpi", type=int, default=150, help="raster resolution of PNG figures")
    p.set_defaults(func=_cmd_outage_figure)

    p = sub.add_parser("export-mat", help="one grade's truth, IMU, labels, errors -> MATLAB .mat")
    p.add_argument("--truth", required=True, help="truth Parquet")
    p.add_argument("--shards", nargs="+", required=True, help="the grade's shard Parquet files")
    p.add_argument("--nav", nargs="+", help="the grade's navigation-error files (optional)")
    p.add_argument("--grade", required=True, help="grade name (checked against the shards)")
    p.add_argument("--route", help="route name recorded in the file (default: truth's folder)")
    p.add_argument(
        "--mat-version",
        choices=["auto", "5", "7.3"],
        default="auto",
        help="MAT format: v5 while every variable is under 2 GiB (auto), else v7.3 (h5py)",
    )
    p.add_argument("-o", "--output", required=True, help=".mat path")
    p.set_defaults(func=_cmd_export_mat)

    p = sub.add_parser("serve", help="local web page: upload a route, pick grades, run, download")
    p.add_argument("--port", type=int, default=8765, help="TCP port")
    p.add_argument(
        "--host",
        default="127.0.0.1",
        help="address to listen on (127.0.0.1: this machine only)",
    )
    p.add_argument("--workdir", default="imugen-runs", help="folder of the runs")
    p.add_argument("--repo", help="project folder with the Snakefile (default: found)")
    p.set_defaults(func=_cmd_serve)
    p = sub.add_parser(
        "export", help="shards -> EuRoC, TUM, TLIO, RoNIN, KF-GINS or ROS 2 bag datasets"
    )
    p.add_argument("truth", help="truth Parquet of the route")
    p.add_argument("shards", nargs="+", help="IMU shard Parquet files (with their labels)")
    p.add_argument("-o", "--output", required=True, help="output folder (one subfolder per format)")
    p.add_argument(
        "--format",
        required=True,
        help="comma-separated formats: euroc, tum, tlio, ronin, kfgins, ros2",
    )
    p.add_argument("--route", help="route name in folder names (default: the truth's folder)")
    p.add_argument("--grade", help="grade name in folder names (default: from the shards)")
    p.add_argument("--nav-rate-hz", type=float, default=10.0, help="rate of TUM trajectories (Hz)")
    p.add_argument(
        "--split-seed", type=int, default=0, help="seed of the TLIO and RoNIN split lists"
    )
    p.add_argument(
        "--split-by",
        choices=["sequence", "route"],
        default="sequence",
        help="split unit of the lists: each sequence, or each route whole",
    )
    p.add_argument(
        "--holdout-routes",
        metavar="A,B",
        help="routes whose sequences form the test list, whole, in every export",
    )
    p.add_argument("--val-fraction", type=float, default=0.1, help="share of the val list")
    p.add_argument(
        "--test-fraction",
        type=float,
        default=0.1,
        help="share of the test list without --holdout-routes",
    )
    p.add_argument(
        "--sequences", type=int, nargs="+", metavar="ID", help="export only these sequence ids"
    )
    p.add_argument(
        "--storage", choices=["sqlite3", "mcap"], default="sqlite3", help="ROS 2 bag storage"
    )
    p.add_argument("--overwrite", action="store_true", help="replace an existing output folder")
    p.add_argument(
        "--gnss",
        nargs="+",
        metavar="GNSS.parquet",
        help="GNSS epoch tables of `imugen aid` for these shards (KF-GINS gnss.pos, ROS /gnss/fix)",
    )
    p.add_argument(
        "--aided",
        nargs="+",
        metavar="AIDED.parquet",
        help="aided navigation tables of `imugen aid` for these shards (TUM <seq>.aided.tum)",
    )
    p.add_argument(
        "--companions",
        nargs="+",
        metavar="COMPANIONS.parquet",
        help="companion-sensor tables of `imugen aid` for these shards "
        "(ROS /wheel/odometry, /baro/pressure)",
    )
    p.set_defaults(func=_cmd_export)

    p = sub.add_parser(
        "grade", help="import a Kalibr/VINS/i2Nav/datasheet IMU description; export Kalibr"
    )
    gsub = p.add_subparsers(
        dest="grade_command",
        required=True,
        parser_class=functools.partial(argparse.ArgumentParser, formatter_class=_HelpFormatter),
    )
    q = gsub.add_parser("import", help="IMU description -> imugen custom grade (YAML)")
    q.add_argument(
        "file",
        help="Kalibr/EuRoC imu.yaml, VINS config, i2Nav/KF-GINS config, datasheet figures "
        "(a 'datasheet:' YAML) or an imugen grades file",
    )
    q.add_argument(
        "--name", help="grade name (default: the grade's own, the datasheet part, the file name)"
    )
    q.add_argument(
        "--id", type=int, help="stable grade id >= 100 (default: the grade's own, else 1000)"
    )
    q.add_argument("-o", "--output", help="grades YAML to write (default: print)")
    q.set_defaults(func=_cmd_grade_import)
    q = gsub.add_parser("export", help="grade -> Kalibr imu.yaml (white noise + random walk)")
    q.add_argument("grade", help="preset name, or FILE.yaml:NAME")
    q.add_argument("--grades-file", help="YAML file with custom grades")
    q.add_argument("--rate-hz", type=float, default=100.0, help="update_rate (Hz)")
    q.add_argument("--topic", default="/imu0", help="rostopic")
    q.add_argument("-o", "--output", help="imu.yaml to write (default: print)")
    q.set_defaults(func=_cmd_grade_export)

    p = sub.add_parser("allan", help="Allan deviation of a static shard against its grade")
    p.add_argument("shard", help="shard Parquet written by `imugen simulate --static`")
    p.add_argument("--plot", help="also draw the Allan plot to this PNG/SVG")
    p.add_argument("--max-sequences", type=int, default=16, help="sequences to analyse")
    p.add_argument("-o", "--output", help="write the report (JSON) here instead of printing it")
    p.set_defaults(func=_cmd_allan)
    return parser


def _add_truth_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("--rate-hz", type=float, default=100.0, help="IMU rate (Hz)")
    p.add_argument(
        "--earth",
        choices=["flat", "wgs84", "geodetic", "auto"],
        default="auto",
        help="Earth model; auto picks flat when every term it drops stays below 10 %% of the "
        "grades' error effect, geodetic (ECEF, any distance) when the route reaches beyond "
        "64 km from its origin (as the workflow does)",
    )
    p.add_argument(
        "--vehicle",
        choices=list(VEHICLES),
        default="car",
        help="vehicle model of the truth motion",
    )


def _show_warning(message, category, filename, lineno, file=None, line=None) -> None:
    """``warnings.showwarning`` of the command line: one line on stderr, no source line."""
    text = f"imugen: warning: {message}"
    if category is not UserWarning:
        text = f"imugen: warning: {category.__name__}: {message} ({filename}:{lineno})"
    print(_printable(text), file=sys.stderr if file is None else file)


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        with warnings.catch_warnings():
            warnings.showwarning = _show_warning
            return args.func(args)
    except InputError as exc:
        print(_printable(f"imugen: error: {exc}"), file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("imugen: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
