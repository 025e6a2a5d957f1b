"""Plausibility figures of the truth of every shipped and shared real track (README table).

Run with this checkout's code (after) or another's (before, e.g. main)::

    python benchmarks/truth_plausibility.py [--src=/work/main/src] [--rate-hz=20] [--md=OUT]
        [--nhc-md=OUT] [--skip=SUBSTRING ...]

``--src`` puts another ``imugen`` first on the path for ingestion and truth; the figures are
always computed by this checkout's :mod:`imugen.truth.report` with its vehicle limits, so
before and after are measured alike. Tracks: the shipped example route and paper trajectory,
and every file in ``../shared/data/trajectories`` (the Colorado GPX holds a drive and then a
walk: both); a file no reader of that code reads is listed as such. The last columns are the
body-frame velocity on the ground (the non-holonomic constraint): RMS and max of its lateral and
vertical components and the moving time slipping beyond 0.1 deg. ``gate findings``: the limits
the truth's pre-write gate (:mod:`imugen.truth.gate`) finds exceeded; ``build s`` and ``build
CPU-s``: wall and CPU time of the truth, printed with the machine's load. ``--nhc-md`` also
writes the ground tracks' body-frame velocity columns as their own table (the Validation page's
non-holonomic table); ``--skip`` leaves out the tracks whose label holds a substring (the Pacific
route: 11 million samples at 20 Hz, several GB).
"""

from __future__ import annotations

import argparse
import importlib.util
import os
import sys
import time
import warnings
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
SHARED = Path(
    os.environ.get("IMUGEN_SHARED_TRAJECTORIES", REPO.parent / "shared" / "data" / "trajectories")
)


def _load(name, path):
    spec = importlib.util.spec_from_file_location(name, path)
    mod = importlib.util.module_from_spec(spec)
    sys.modules[name] = mod
    spec.loader.exec_module(mod)
    return mod


def tracks():
    """(label, file, ingest options, vehicle) of every track."""
    out = [
        ("example_route.kml (shipped)", REPO / "resources" / "example_route.kml", {}, "car"),
        (
            "paper reference ENU (shipped)",
            REPO / "resources" / "paper" / "seed_reference_trajectory_enu.txt",
            {"origin": "31.63,-7.99,480.6", "dt": 1.0},
            "car",
        ),
    ]
    if SHARED.is_dir():
        for f in sorted(SHARED.iterdir()):
            if f.suffix in (".md",) or f.name.startswith("seed_"):
                continue
            n = f.name.lower()
            if "colorado" in n:
                out += [(f"{f.name} #1", f, {"path": 1}, "car")]
                out += [(f"{f.name} #2", f, {"path": 2}, "pedestrian")]
                continue
            veh = "car"
            for key, v in (("cycl", "bicycle"), ("bike", "bicycle"), ("hike", "pedestrian")):
                if key in n:
                    veh = v
            if "glider" in n or n.endswith(".igc"):
                veh = "aircraft"
            kw = {"path": 3} if "kml_samples" in n else {}  # its first timed-less 3-D path
            out.append((f.name if not kw else f"{f.name} #3", f, kw, veh))
    return out


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--src", help="imugen source tree to measure (default: this checkout)")
    ap.add_argument("--rate-hz", type=float, default=20.0)
    ap.add_argument("--md", help="write the Markdown table here")
    ap.add_argument("--nhc-md", help="write the ground tracks' body-velocity table here")
    ap.add_argument("--skip", action="append", default=[], help="leave out labels holding this")
    a = ap.parse_args()
    sys.path.insert(0, str(a.src or REPO / "src"))
    warnings.simplefilter("ignore")
    from imugen import truth
    from imugen.core.errors import InputError
    from imugen.ingest.stage import ingest

    here = REPO / "src" / "imugen" / "truth"
    report = _load("_report", here / "report.py")
    limits = _load("_vehicles", here / "vehicles.py").VEHICLES
    rows, nhc = [], []
    for label, f, kw, veh in tracks():
        if any(k.lower() in label.lower() for k in a.skip):
            continue
        used = veh if veh in truth.VEHICLES else "car"  # before: no bicycle class
        try:
            ing = ingest(f, **kw)
        except InputError as exc:
            rows.append(f"| {label} | {veh} | not read: {str(exc.message)[:60]} |")
            continue
        t0, c0 = time.perf_counter(), time.process_time()
        df, meta = truth.build_truth(
            ing.table, ing.meta, rate_hz=a.rate_hz, earth="wgs84", vehicle=used, verbose=False
        )
        dt, cpu = time.perf_counter() - t0, time.process_time() - c0
        timed = bool(ing.meta["timed"]) and "time_s" in ing.table
        air = None
        if used == "aircraft":  # same classification for before and after
            import numpy as np

            v = df[["v_e_mps", "v_n_mps", "v_u_mps"]].to_numpy()
            up = df["u_m"].to_numpy()
            lim = limits[used]  # fast, or high above the route's lowest point
            air = (np.linalg.norm(v, axis=1) >= 0.9 * lim.airborne_speed_mps) | (
                up - up.min() >= 0.75 * lim.airborne_height_m
            )
        r = report.plausibility(
            df,
            limits[veh],
            input_enu=ing.table[["e_m", "n_m", "u_m"]].to_numpy(),
            input_time=ing.table["time_s"].to_numpy() if timed else None,
            fit=meta["fit"],
            airborne=air,
        )
        inv = "-" if r["invented_fraction"] is None else f"{100 * r['invented_fraction']:.2f}"
        rows.append(
            f"| {label} | {used} | {r['max_abs_pitch_deg']:.1f} | {r['max_abs_roll_deg']:.1f} "
            f"| {r['max_yaw_rate_dps']:.0f} | {r['max_yaw_rate_excess_dps']:.1f} "
            f"| {r['max_accel_mps2']:.2f} | {r['max_jerk_mps3']:.1f} "
            f"| {r['max_rate_increment_radps']:.2g} | {r['max_attitude_step_excess_rad']:.2g} "
            f"| {r['length_ratio']:.3f} | {inv} | {r['time_stopped_s']:.0f}/{r['time_moving_s']:.0f}"
            f"/{r['time_airborne_s']:.0f} | {len(r['warnings'])} | {len(meta['gate'])} "
            f"| {dt:.1f} | {cpu:.1f} "
            f"| {r['rms_body_lateral_speed_mps']:.2g} | {r['max_body_lateral_speed_mps']:.2g} "
            f"| {r['rms_body_vertical_speed_mps']:.2g} | {r['max_body_vertical_speed_mps']:.2g} "
            f"| {100 * r['slip_fraction']:.1f} |"
        )
        print(rows[-1], file=sys.stderr)
        if used != "aircraft":
            nhc.append(
                f"| {label} | {used} | {r['rms_body_lateral_speed_mps']:.2g} "
                f"| {r['max_body_lateral_speed_mps']:.2g} | {r['rms_body_vertical_speed_mps']:.2g} "
                f"| {r['max_body_vertical_speed_mps']:.2g} | {r['max_abs_pitch_deg']:.1f} "
                f"| {100 * r['slip_fraction']:.1f} |"
            )
    head = (
        "| track | vehicle | max abs pitch deg | max abs roll deg | max yaw rate deg/s "
        "| yaw rate beyond v k_max deg/s | max accel m/s^2 | max jerk m/s^3 "
        "| dtheta vs gyro rad/s | attitude step excess rad | length truth/input "
        "| invented % | stopped/moving/airborne s | warnings | gate findings | build s "
        "| build CPU-s | body lateral RMS m/s | max | body vertical RMS m/s | max "
        "| slip > 0.1 deg % |\n"
        "|" + "---|" * 22
    )
    load = ", ".join(f"{x:.1f}" for x in os.getloadavg())
    text = (
        f"{time.strftime('%Y-%m-%d', time.gmtime())}, {a.rate_hz:g} Hz, wgs84; machine load "
        f"(1/5/15 min) {load} at the end; build s is wall time, CPU-s this process's\n\n"
        + head
        + "\n"
        + "\n".join(rows)
        + "\n"
    )
    print(text)
    if a.md:
        Path(a.md).write_text(text)
    if a.nhc_md:
        Path(a.nhc_md).write_text(
            f"{time.strftime('%Y-%m-%d', time.gmtime())}, {a.rate_hz:g} Hz, wgs84, m/s\n\n"
            "| track | vehicle | lateral RMS | lateral max | vertical RMS | vertical max "
            "| max abs pitch deg | slip > 0.1 deg, % of moving time |\n"
            "|" + "---|" * 8 + "\n" + "\n".join(nhc) + "\n"
        )


if __name__ == "__main__":
    main()
