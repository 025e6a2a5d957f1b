"""Structure-aware fuzzing of every reader through ``imugen ingest`` (issues 16 and 22).

Hypothesis builds KML, KMZ, GPX, CSV, E N U, NMEA, IGC, GeoJSON, ROS NavSatFix, hemisphere
lettered and NUL-padded CSV files, pose trajectories (TUM, EuRoC ground truth, CSV with named
pose columns; issue 28), and the GPSBabel formats (FIT, TCX, OziExplorer PLT) from
their grammar with hostile leaves (non-finite and overflowing numbers, times at the ends of the
calendar, stray separators, short records, deep nesting, odd encodings, malformed ``# imugen:``
comments). Oracle for every case: the command either succeeds with a table of finite numbers,
or exits with status 2, one stderr line ``imugen: error: ...`` and nothing written; any other
exception fails the test.

The suite runs a fixed regression seed (:data:`REGRESSION_SEED`, 200 cases per reader) so CI
runs the same cases each time; ``python scripts/fuzz_readers.py --seed=N --cases=N`` runs a
fresh seed on demand (``IMUGEN_FUZZ_SEED`` and ``IMUGEN_FUZZ_EXAMPLES`` here).
"""

from __future__ import annotations

import contextlib
import io
import json
import os
import tempfile
import zipfile
from pathlib import Path
from xml.sax.saxutils import escape, quoteattr

import numpy as np
import pandas as pd
from hypothesis import HealthCheck, example, given, seed, settings
from hypothesis import strategies as st

from imugen import cli

REGRESSION_SEED = 22
"""The seed the suite runs (a fixed set of cases; scripts/fuzz_readers.py draws others)."""
FUZZ_SEED = int(os.environ.get("IMUGEN_FUZZ_SEED", REGRESSION_SEED))
_SETTINGS = settings(
    max_examples=int(os.environ.get("IMUGEN_FUZZ_EXAMPLES", "200")),
    deadline=None,
    database=None,
    print_blob=True,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
)


def FUZZ(test):
    """The fuzz settings and seed of every test below."""
    return seed(FUZZ_SEED)(_SETTINGS(test))


# --- leaves ------------------------------------------------------------------------------------
WEIRD_NUMBERS = ["", "nan", "-inf", "Infinity", "1e400", "-0", "+.5", "7.", "1,5", "0x10",
                 "1_0", "\u0661", " 1 ", "1e", ".", "--1", "9" * 120, "1e-400", "4e1"]  # fmt: skip
numbers = st.one_of(
    st.floats(-200, 200).map(repr),
    st.floats(allow_nan=True, allow_infinity=True).map(repr),
    st.integers(-1000, 1000).map(str),
    st.sampled_from(WEIRD_NUMBERS),
)
lat_lon = st.tuples(st.floats(-1.0, 1.0), st.floats(-1.0, 1.0)).map(
    lambda p: (repr(40 + p[0] * 0.01), repr(-105 + p[1] * 0.01))
)
WEIRD_TIMES = ["", "yesterday", "9999-12-31T23:00:00-05:00", "0001-01-01T00:30:00+01:00",
               "2024-02-30T00:00:00Z", "2024-01-01T00:00:00+25:00", "2024-01-01", "1" * 200,
               "2024-01-01T00:00:00.123456789Z", "nan", "1e300"]  # fmt: skip
good_times = st.integers(0, 59).map(lambda s: f"2024-01-01T00:00:{s:02d}Z")
times = st.one_of(
    st.datetimes().map(lambda d: d.isoformat() + "Z"),
    st.integers(0, 10).map(lambda s: f"2024-01-01T00:00:{s:02d}Z"),
    st.sampled_from(WEIRD_TIMES),
)
names = st.one_of(st.sampled_from(["", " ", "A", "x" * 2000]), st.text(max_size=12))


def mostly(good, bad):
    """``good`` about 4 times in 5, else ``bad``: most cases get deep into a reader."""
    return st.integers(0, 4).flatmap(lambda k: bad if k == 0 else good)


whitespace = st.sampled_from([" ", "\n", "\t", "  \n ", ""])


def xml_text(s: str) -> str:
    """Escape for XML, keeping only characters XML 1.0 allows (others are a different test)."""
    ok = "".join(c for c in s if c in "\t\n\r" or (" " <= c <= "\ud7ff") or c > "\ue000")
    return escape(ok)


# --- documents ----------------------------------------------------------------------------------
@st.composite
def coordinates(draw) -> str:
    tuples = []
    hostile = draw(st.integers(0, 4)) == 0
    for i in range(draw(mostly(st.integers(2, 4), st.integers(0, 6)))):
        if not hostile or draw(st.booleans()):
            lat, lon = draw(lat_lon)
            parts = [lon, lat] + ([repr(1600.0 + i)] if draw(st.booleans()) else [])
        else:
            parts = draw(st.lists(numbers, min_size=1, max_size=4))
        sep = draw(st.sampled_from([",", ", ", " ,", ",,"])) if hostile else ","
        tuples.append(sep.join(parts))
    gap = draw(whitespace) if hostile else " "
    return gap.join(tuples) if tuples else gap


@st.composite
def geometry(draw, depth: int = 0) -> str:
    kinds = ["LineString", "LineString", "Track", "Track", "Point", "Polygon", "Junk"]
    if depth < 3:
        kinds.append("MultiGeometry")
    kind = draw(st.sampled_from(kinds))
    mode = draw(st.sampled_from(["", "absolute", "clampToGround", "relativeToGround", "odd"]))
    alt = f"<altitudeMode>{mode}</altitudeMode>" if mode else ""
    if kind == "LineString":
        return f"<LineString>{alt}<coordinates>{xml_text(draw(coordinates()))}</coordinates></LineString>"
    if kind == "Track":
        n = draw(mostly(st.integers(2, 4), st.integers(0, 5)))
        nw = draw(st.sampled_from([0, n, n, n, n + 1]))
        whens = "".join(
            f"<when>{xml_text(draw(mostly(good_times, times)))}</when>" for _ in range(nw)
        )
        coords = "".join(
            f"<gx:coord>{xml_text(draw(coordinates()).replace(',', ' '))}</gx:coord>" for _ in range(n)
        )  # fmt: skip
        return f"<gx:Track>{alt}{whens}{coords}</gx:Track>"
    if kind == "MultiGeometry":
        kids = draw(st.lists(geometry(depth + 1), max_size=3))
        return f"<MultiGeometry>{alt}{''.join(kids)}</MultiGeometry>"
    if kind == "Point":
        return f"<Point><coordinates>{xml_text(draw(coordinates()))}</coordinates></Point>"
    if kind == "Polygon":
        return "<Polygon><outerBoundaryIs><LinearRing><coordinates>0,0 1,1</coordinates></LinearRing></outerBoundaryIs></Polygon>"  # fmt: skip
    return f"<{draw(st.sampled_from(['Model', 'Folder', 'when', 'coord']))}/>"


@st.composite
def kml_doc(draw) -> bytes:
    marks = []
    for _ in range(draw(mostly(st.just(1), st.integers(0, 3)))):
        name = f"<name>{xml_text(draw(names))}</name>" if draw(st.booleans()) else ""
        geoms = "".join(
            draw(
                mostly(
                    st.lists(geometry(), min_size=1, max_size=1), st.lists(geometry(), max_size=3)
                )
            )
        )
        marks.append(f"<Placemark>{name}{geoms}</Placemark>")
    body = "".join(marks)
    if draw(st.booleans()):
        body = f"<Document><Folder>{body}</Folder></Document>"
    root = draw(mostly(st.just("kml"), st.sampled_from(["gpx", "html"])))
    text = (
        f'<{root} xmlns="http://www.opengis.net/kml/2.2" '
        f'xmlns:gx="http://www.google.com/kml/ext/2.2">{body}</{root}>'
    )
    decl = draw(mostly(st.sampled_from(["", '<?xml version="1.0" encoding="UTF-8"?>']), st.sampled_from(["", '<?xml version="1.0"?>', '<?xml version="1.0" encoding="UTF-8"?>',
                                 '<?xml version="1.0" encoding="UTF-16"?>', '<?xml version="1.0" encoding="UTF-32"?>',
                                 '<?xml version="1.0" encoding="ISO-8859-1"?>', '<!DOCTYPE kml [<!ENTITY a "b">]>'])))  # fmt: skip
    encoding = draw(mostly(st.just("utf-8"), st.sampled_from(["utf-8-sig", "utf-16"])))
    data = (decl + text).encode(encoding)
    if draw(st.integers(0, 9)) == 0:  # a byte-level mutation
        i = draw(st.integers(len(data) // 4, len(data)))
        data = data[:i] + draw(st.binary(max_size=4)) + data[i + 1 :]
    return data


@st.composite
def gpx_doc(draw) -> bytes:
    def point(tag: str) -> str:
        lat, lon = draw(mostly(lat_lon, st.tuples(numbers, numbers)) if hostile else lat_lon)
        attrs = ""
        if not hostile or draw(st.integers(0, 9)):
            attrs += f" lat={quoteattr(lat)}"
        if not hostile or draw(st.integers(0, 9)):
            attrs += f" lon={quoteattr(lon)}"
        ele = draw(mostly(st.just("1600"), numbers))
        ele = f"<ele>{xml_text(ele)}</ele>" if draw(st.booleans()) else ""
        when = f"<time>{xml_text(draw(mostly(good_times, times)))}</time>" if timed else ""
        return f"<{tag}{attrs}>{ele}{when}</{tag}>"

    parts = []
    timed = draw(st.booleans())
    hostile = draw(st.booleans())
    for _ in range(draw(mostly(st.just(1), st.integers(0, 2)))):
        name = f"<name>{xml_text(draw(names))}</name>" if draw(st.booleans()) else ""
        segs = "".join(
            "<trkseg>" + "".join(point("trkpt") for _ in range(draw(mostly(st.integers(2, 4), st.integers(0, 5))))) + "</trkseg>"
            for _ in range(draw(mostly(st.just(1), st.integers(0, 2))))
        )  # fmt: skip
        parts.append(f"<trk>{name}{segs}</trk>")
    if draw(st.integers(0, 3)) == 0:
        parts.append(
            "<rte>" + "".join(point("rtept") for _ in range(draw(st.integers(0, 4)))) + "</rte>"
        )
    if draw(st.booleans()):
        parts.append('<wpt lat="1" lon="2"/>')
    return ('<gpx version="1.1">' + "".join(parts) + "</gpx>").encode()


json_values = st.recursive(
    st.none() | st.booleans() | st.floats() | st.integers() | st.text(max_size=8),
    lambda kids: (
        st.lists(kids, max_size=3) | st.dictionaries(st.text(max_size=5), kids, max_size=3)
    ),
    max_leaves=8,
)
valid_meta = st.fixed_dictionaries(
    {},
    optional={
        "path": names,
        "notes": st.lists(st.text(max_size=5), max_size=2),
        "altitude_trusted": st.booleans(),
        "start_time_utc": good_times,
        "source": st.just("x.kml"),
    },
)
META_KEYS = ["path", "notes", "altitude_trusted", "altitude_mode", "start_time_utc", "origin", "source"]  # fmt: skip


@st.composite
def csv_doc(draw) -> bytes:
    columns = st.sampled_from(["lat", "Latitude", "lon", "lng", "alt", "height (m)", "time",
                               "t", "e_m", "n_m", "u_m", "name", "x", '"lat"', "lat [deg]"])  # fmt: skip
    usual = st.sampled_from([["lat", "lon"], ["lat", "lon", "alt"], ["time", "lat", "lon", "alt"],
                             ["Latitude", "Longitude (deg)", "t"], ["e_m", "n_m", "u_m"]])  # fmt: skip
    headers = draw(mostly(usual, st.lists(columns, min_size=1, max_size=5)))
    delim = draw(st.sampled_from([",", ";", "\t", " "]))
    lines = []
    hostile = draw(st.booleans())
    if draw(st.integers(0, 3)) == 0:
        meta = draw(
            mostly(valid_meta, st.dictionaries(st.sampled_from(META_KEYS), json_values, max_size=4))
        )
        if draw(st.booleans()):
            meta["origin"] = {"lat_deg": 40.0, "lon_deg": -105.0, "alt_m": draw(st.floats())}
        lines.append("# imugen: " + (json.dumps(meta) if draw(st.integers(0, 5)) else "{bad"))
    lines.append(delim.join(headers))
    for _ in range(draw(mostly(st.integers(2, 5), st.integers(0, 6)))):
        cells = []
        for h in headers:
            h = h.lower().strip('"')
            if not hostile and h.startswith(("lat", "lon", "lng")):
                cell = draw(lat_lon)[0 if h.startswith("lat") else 1]
            elif h.startswith("lat"):
                cell = draw(mostly(lat_lon.map(lambda p: p[0]), numbers))
            elif h.startswith(("lon", "lng")):
                cell = draw(mostly(lat_lon.map(lambda p: p[1]), numbers))
            elif h.startswith("t"):
                cell = draw(mostly(st.just(repr(float(len(lines)))) | good_times, times | numbers))
            else:
                cell = draw(mostly(st.floats(-50, 50).map(repr), numbers))
            if delim == ";" and draw(st.booleans()):
                cell = cell.replace(".", ",")
            if draw(st.integers(0, 4)) == 0:
                cell = '"' + cell.replace('"', '""') + '"'
            cells.append(cell)
        if draw(st.integers(0, 9)) == 0:
            cells.append("extra")
        lines.append(delim.join(cells))
    encoding = draw(mostly(st.just("utf-8"), st.sampled_from(["utf-8-sig", "utf-16", "latin-1"])))
    return "\n".join(lines).encode(encoding, errors="replace")


@st.composite
def enu_doc(draw) -> bytes:
    ncol = draw(mostly(st.sampled_from([3, 4]), st.sampled_from([2, 5])))
    sep = draw(st.sampled_from([" ", "\t", ",", "  "]))
    rows = []
    for i in range(draw(mostly(st.integers(2, 5), st.integers(0, 6)))):
        if draw(st.integers(0, 5)):
            vals = [repr(float(i))] * (ncol == 4) + [repr(i * 3.0), repr(i * 4.0), "0"]
        else:
            vals = draw(st.lists(numbers, min_size=ncol, max_size=ncol))
        rows.append(sep.join(vals))
    return "\n".join(rows).encode()


@st.composite
def kmz_doc(draw) -> bytes:
    buf = io.BytesIO()
    member = draw(mostly(st.just("doc.kml"), st.sampled_from(["a.kml", "../doc.kml", "/abs.kml", "dir/doc.kml",
                                   "C:\\doc.kml", "doc.txt"])))  # fmt: skip
    with zipfile.ZipFile(
        buf, "w", draw(st.sampled_from([zipfile.ZIP_STORED, zipfile.ZIP_DEFLATED]))
    ) as zf:
        zf.writestr(member, draw(kml_doc()))
    data = buf.getvalue()
    if draw(st.integers(0, 4)) == 0:  # truncate or corrupt the archive
        i = draw(st.integers(len(data) // 2, len(data)))
        data = data[:i] + draw(st.binary(max_size=8))
    return data


choose = mostly(
    st.just(["--path=1"]), st.sampled_from([[], ["--path=2"], ["--path=A"], ["--path=longest"]])
)


# --- the oracle ---------------------------------------------------------------------------------
def check_ingest(data: bytes, name: str, *options: str) -> None:
    with tempfile.TemporaryDirectory() as d:
        src = Path(d) / name
        src.write_bytes(data)
        out_dir = Path(d) / "out"
        out_dir.mkdir()
        out = out_dir / "route.csv"
        err = io.StringIO()
        with contextlib.redirect_stderr(err):
            rc = cli.main(["ingest", str(src), "-o", str(out), *options])
        lines = err.getvalue().splitlines()
        if rc == 2:
            assert len(lines) == 1 and lines[0].startswith("imugen: error: "), lines
            assert list(out_dir.iterdir()) == []
            return
        assert rc == 0, (rc, lines)
        assert all(ln.startswith(("imugen: warning: ", str(out))) for ln in lines), lines
        table = pd.read_csv(out, comment="#")
        assert len(table) >= 2 and np.isfinite(table.to_numpy(float)).all()


@FUZZ
@given(kml_doc(), choose)
def test_fuzz_kml(data, options):
    check_ingest(data, "f.kml", *options)


@FUZZ
@given(kmz_doc(), choose)
def test_fuzz_kmz(data, options):
    check_ingest(data, "f.kmz", *options)


@FUZZ
@given(gpx_doc(), choose)
def test_fuzz_gpx(data, options):
    check_ingest(data, "f.gpx", *options)


@FUZZ
@given(csv_doc(), st.sampled_from([[], ["--origin=40,-105,1600"], ["--dt=1"]]))
def test_fuzz_csv(data, options):
    check_ingest(data, "f.csv", *options)


@FUZZ
@given(
    enu_doc(),
    mostly(st.just(["--origin=40,-105,1600"]), st.sampled_from([["--origin=40,-105,nan"], []])),
)
def test_fuzz_enu_text(data, options):
    check_ingest(data, "f.txt", *options)


# --- GNSS logs: NMEA, IGC, GeoJSON, NavSatFix and lettered / NUL-padded CSV (issue 22) ----------
def nmea_sum(body: str) -> str:
    x = 0
    for ch in body:
        x ^= ord(ch)
    return f"{x:02X}"


def _ddmm(value: float, deg_digits: int) -> str:
    v = abs(value)
    d = int(v)
    return f"{d:0{deg_digits}d}{(v - d) * 60:07.4f}"


@st.composite
def nmea_doc(draw) -> bytes:
    lines = []
    hostile = draw(st.booleans())

    def leaf(good, bad):
        return draw(mostly(good, bad) if hostile else good)

    for k in range(draw(mostly(st.integers(2, 6), st.integers(0, 8)))):
        talker = leaf(st.just("GP"), st.sampled_from(["GN", "GL", "BD", "G", "GPX", ""]))
        kind = leaf(st.sampled_from(["GGA", "RMC"]), st.sampled_from(["GSV", "VTG", ""]))
        lat, lon = 40 + k * 1e-4, -105 + k * 1e-4
        tod = f"{12:02d}{0:02d}{k % 60:02d}" + draw(st.sampled_from([".00", ".0", ".", ""]))
        f_lat, f_lon = _ddmm(lat, 2), _ddmm(lon, 3)
        hemi = ("N", "W")
        if hostile and draw(st.integers(0, 2)) == 0:
            tod = draw(st.sampled_from(["", "246000", "1200", "12000x", "9" * 50, "120000.-1"]))
        if hostile and draw(st.integers(0, 2)) == 0:
            f_lat, f_lon = (
                draw(st.sampled_from([("", ""), ("4000.0", "10500.0")]))
                if draw(st.booleans())
                else (draw(numbers), draw(numbers))
            )
        if hostile and draw(st.integers(0, 3)) == 0:
            hemi = (
                draw(st.sampled_from(["", "n", "X", "S"])),
                draw(st.sampled_from(["", "E", "Q"])),
            )
        if kind == "GGA":
            quality = leaf(st.just("1"), st.sampled_from(["0", "", "6", "x"]))
            height = leaf(st.just("1600.0"), numbers)
            geoid = leaf(st.just("-20.0"), numbers)
            fields = [tod, f_lat, hemi[0], f_lon, hemi[1], quality, "08", "0.9", height, "M",
                      geoid, "M", "", ""]  # fmt: skip
        else:
            status = leaf(st.just("A"), st.sampled_from(["V", "", "a"]))
            date = leaf(st.just("010124"), st.sampled_from(["", "310299", "000000", "01012", "991399"]))  # fmt: skip
            fields = [tod, status, f_lat, hemi[0], f_lon, hemi[1], "0.0", "", date, "", "", "A"]
        if hostile and draw(st.integers(0, 3)) == 0:
            fields = fields[: draw(st.integers(0, len(fields)))]  # a short sentence
        body = ",".join([f"{talker}{kind}", *fields])
        star = leaf(st.just("*" + nmea_sum(body)), st.sampled_from(["", "*00", "*G1", "*"]))
        lines.append("$" + body + star)
    end = draw(st.sampled_from(["\r\n", "\n", "\r"]))
    return end.join(lines).encode("ascii", errors="replace")


@st.composite
def igc_doc(draw) -> bytes:
    lines = ["AXXX001"]
    date = draw(mostly(st.just("HFDTE160722"), st.sampled_from(["", "HFDTEDATE:160722,01", "HFDTE310299", "HFDTE", "HFDTE99999999"])))  # fmt: skip
    if date:
        lines.append(date)
    hostile = draw(st.booleans())
    for k in range(draw(mostly(st.integers(2, 6), st.integers(0, 8)))):
        hh, mm, ss = 12, k // 60, k % 60
        tod = f"{hh:02d}{mm:02d}{ss:02d}"
        lat = f"{43:02d}{50420 + 3 * k:05d}N"
        lon = f"{80:03d}{26585 + 3 * k:05d}W"
        valid = draw(
            mostly(st.just("A"), st.sampled_from(["V", "X", ""])) if hostile else st.just("A")
        )
        p_alt = f"{draw(mostly(st.integers(0, 9999), st.integers(-9999, 99999))):05d}"
        g_alt = f"{draw(mostly(st.integers(0, 9999), st.integers(-9999, 99999))):05d}"
        rec = f"B{tod}{lat}{lon}{valid}{p_alt}{g_alt}"
        if hostile and draw(st.integers(0, 2)) == 0:
            i = draw(st.integers(1, max(1, len(rec) - 1)))
            rec = rec[:i] + draw(st.sampled_from(["", "x", "-", "9" * 40, " "])) + rec[i + 1 :]
        if hostile and draw(st.integers(0, 4)) == 0:
            rec = rec[: draw(st.integers(1, len(rec)))]
        lines.append(rec + draw(st.sampled_from(["", "000018009", "extension"])))
    return "\r\n".join(lines).encode("ascii", errors="replace")


geo_numbers = st.one_of(
    st.floats(-1.0, 1.0).map(lambda x: repr(40 + x * 0.01)),
    st.floats(allow_nan=True, allow_infinity=True).map(lambda x: json.dumps(x)),
    st.integers(-(10**30), 10**30).map(str),
    st.sampled_from(["1e400", "-1e400", "NaN", "Infinity", "true", "null", '"1"', "[]", "{}"]),
)


@st.composite
def geojson_position(draw, k: int, hostile: bool) -> str:
    if not hostile or draw(st.integers(0, 2)):
        pos = [repr(-105 + k * 1e-4), repr(40 + k * 1e-4)]
        if draw(st.booleans()):
            pos.append(repr(1600.0 + k))
    else:
        pos = draw(st.lists(geo_numbers, min_size=0, max_size=5))
    return "[" + ",".join(pos) + "]"


@st.composite
def geojson_geometry(draw, depth: int = 0) -> str:
    kinds = ["LineString", "LineString", "MultiLineString", "Point", "Polygon", "Junk"]
    if depth < 3:
        kinds.append("GeometryCollection")
    kind = draw(st.sampled_from(kinds))
    hostile = draw(st.integers(0, 3)) == 0
    n = draw(mostly(st.integers(2, 5), st.integers(0, 6)))
    line = "[" + ",".join(draw(geojson_position(k, hostile)) for k in range(n)) + "]"
    if kind == "LineString":
        coords = line if not hostile or draw(st.booleans()) else draw(geo_numbers)
        return f'{{"type": "LineString", "coordinates": {coords}}}'
    if kind == "MultiLineString":
        lines = ",".join([line] * draw(st.integers(0, 3)))
        return f'{{"type": "MultiLineString", "coordinates": [{lines}]}}'
    if kind == "GeometryCollection":
        kids = ",".join(draw(st.lists(geojson_geometry(depth + 1), max_size=3)))
        return f'{{"type": "GeometryCollection", "geometries": [{kids}]}}'
    if kind == "Point":
        return '{"type": "Point", "coordinates": [1, 2]}'
    if kind == "Polygon":
        return '{"type": "Polygon", "coordinates": [[[0, 0], [1, 1], [0, 1], [0, 0]]]}'
    return draw(st.sampled_from(['{"type": 7}', "[]", "null", '{"type": "Feature"}']))


@st.composite
def geojson_doc(draw) -> bytes:
    features = []
    for _ in range(draw(mostly(st.just(1), st.integers(0, 3)))):
        props = {}
        if draw(st.booleans()):
            props["name"] = draw(mostly(names, json_values))
        if draw(st.booleans()):
            n = draw(st.integers(0, 6))
            props["coordTimes"] = [draw(mostly(good_times, times)) for _ in range(n)]
            if draw(st.integers(0, 5)) == 0:
                props["coordTimes"] = draw(json_values)
        features.append(
            f'{{"type": "Feature", "properties": {json.dumps(props)}, '
            f'"geometry": {draw(geojson_geometry())}}}'
        )
    if len(features) == 1 and draw(st.booleans()):
        text = features[0]
    else:
        text = f'{{"type": "FeatureCollection", "features": [{",".join(features)}]}}'
    if draw(st.integers(0, 9)) == 0:  # deep nesting
        d = draw(st.sampled_from([50, 500, 5000]))
        text = '{"type": "GeometryCollection", "geometries": [' * d + text + "]}" * d
    data = text.encode(draw(mostly(st.just("utf-8"), st.sampled_from(["utf-8-sig", "utf-16"]))))
    if draw(st.integers(0, 9)) == 0:
        i = draw(st.integers(0, len(data)))
        data = data[:i] + draw(st.binary(max_size=4)) + data[i + 1 :]
    return data


NS = 10**9
WEIRD_STAMPS = ["1e25", "-1", "0", "nan", "", "1" * 40, "1700000000.5e9", "-1e25",
                "253402300800000000000", "9" * 400]  # fmt: skip


@st.composite
def navsatfix_doc(draw) -> bytes:
    cols = ["%time", "field.header.seq", "field.header.stamp", "field.header.frame_id",
            "field.status.status", "field.status.service", "field.latitude", "field.longitude",
            "field.altitude", "field.position_covariance_type"]  # fmt: skip
    if draw(st.integers(0, 4)) == 0:
        cols = draw(st.permutations(cols))[: draw(st.integers(2, len(cols)))]
    delim = draw(mostly(st.just(","), st.sampled_from([";", "\t", " "])))
    hostile = draw(st.booleans())
    all_no_fix = draw(st.integers(0, 3)) == 0  # a driver that never sets the status
    if all_no_fix:
        cols = [*cols, *(f"field.position_covariance{i}" for i in range(9))]
    lines = [delim.join(cols)]
    t0 = draw(mostly(st.just(1_700_000_000 * NS), st.integers(0, 2**64)))
    for k in range(draw(mostly(st.integers(2, 6), st.integers(0, 8)))):
        row = {
            "%time": str(t0 + k * NS + 5_000_000),
            "field.header.seq": str(k),
            "field.header.stamp": str(t0 + k * NS),
            "field.header.frame_id": "gps",
            "field.status.status": "-1" if all_no_fix else draw(
                mostly(st.just("0"), st.sampled_from(["-1", "2", "", "x"]))
            ),
            "field.status.service": "1",
            "field.latitude": repr(30.2 + k * 1e-4),
            "field.longitude": repr(-97.6 + k * 1e-4),
            "field.altitude": draw(
                mostly(st.just(repr(150.0 + k)), st.sampled_from(["nan", "-nan", ""]) | numbers)
            ),
            "field.position_covariance_type": "0",
            **{f"field.position_covariance{i}": draw(mostly(st.just("4.0"), numbers))
               for i in range(9)},
        }  # fmt: skip
        if hostile:
            key = draw(st.sampled_from(["field.header.stamp", "%time", "field.latitude", "field.longitude"]))  # fmt: skip
            row[key] = draw(st.sampled_from(WEIRD_STAMPS) if "time" in key or "stamp" in key else numbers)  # fmt: skip
        cells = [row.get(c, "0") for c in cols]
        if draw(st.integers(0, 9)) == 0:
            cells = cells[:-1]
        lines.append(delim.join(cells))
    return "\n".join(lines).encode()


@st.composite
def lettered_csv_doc(draw) -> bytes:
    def lettered(value: float, pos: str, neg: str, width: int) -> str:
        letter = pos if value >= 0 else neg
        num = f"{abs(value):0{width}.5f}"
        return draw(st.sampled_from([num + letter, letter + num]))

    header = draw(mostly(st.just(["time", "lat", "lon", "alt"]), st.sampled_from([["lat", "lon"], ["lat", "lon", "t"], ["Latitude", "Longitude", "height"]])))  # fmt: skip
    delim = draw(st.sampled_from([",", ";", "\t"]))
    nul = draw(st.integers(0, 2)) == 0
    hostile = draw(st.booleans())
    lines = [delim.join(header)]
    for k in range(draw(mostly(st.integers(2, 6), st.integers(0, 8)))):
        cells = []
        for h in header:
            h = h.lower()
            if h.startswith("lat"):
                cell = lettered(-42.8 + k * 1e-4, "N", "S", 8)
            elif h.startswith("lon"):
                cell = lettered(147.4 + k * 1e-4, "E", "W", 9)
            elif h.startswith("t"):
                good = st.sampled_from([f"2024-01-01T00:00:{k:02d}Z", str(1704067200 + k)])
                cell = draw(mostly(good, times | numbers) if hostile else good)
            else:
                cell = draw(mostly(st.just(repr(10.0 + k)), numbers) if hostile else st.just("10"))
            if hostile and draw(st.integers(0, 3)) == 0:
                cell = draw(st.sampled_from(["-42.8S", "S-42.8", "N", "42.8NN", "W097.6E", "", "S" + "9" * 60]))  # fmt: skip
            if nul:
                cell = cell + "\x00" * draw(st.integers(0, 4))
            cells.append(cell)
        lines.append(delim.join(cells))
    data = "\n".join(lines).encode()
    if nul and draw(st.integers(0, 4)) == 0:
        data += draw(st.binary(min_size=1, max_size=40))  # a binary tail
    return data


@st.composite
def columbus_doc(draw) -> bytes:
    """Columbus V-900/V-990 CSV: NUL-padded fixed-width fields, DATE yymmdd + TIME hhmmss."""
    lat_name, lon_name = draw(st.sampled_from([("LATITUDE N/S", "LONGITUDE E/W"),
                                               ("LATITUDE N", "LONGITUDE E"),
                                               ("LATITUDEN/S", "LONGITUDEE/W")]))  # fmt: skip
    header = ["INDEX", "TAG", "DATE", "TIME", lat_name, lon_name, "HEIGHT", "SPEED", "HEADING",
              "VOX"]  # fmt: skip
    hostile = draw(st.booleans())
    lines = [",".join(header)]
    for k in range(draw(mostly(st.integers(2, 6), st.integers(0, 8)))):
        cells = [str(k + 1), "T", "231114", f"2213{k:02d}", f"{48.1371 + k * 1e-4:.6f}N",
                 f"{11.575 + k * 1e-4:.6f}E", "520", "43", "4", ""]  # fmt: skip
        if hostile:
            j = draw(st.sampled_from([2, 3, 4, 5, 6]))
            cells[j] = draw(st.sampled_from(["", "991399", "236161", "x", "48.1S", "N"]) | numbers)
        cells = [c + "\x00" * draw(st.integers(0, 4)) for c in cells]
        lines.append(",".join(cells))
    return "\r\n".join(lines).encode()


@st.composite
def dashcam_doc(draw) -> bytes:
    """70mai GPSData*.txt: $V02 session lines (also mid-file), epoch rows, A/V status."""
    hostile = draw(st.booleans())
    lines = ["$V02"]
    t = 1_700_000_000
    for k in range(draw(mostly(st.integers(2, 8), st.integers(0, 10)))):
        if k and draw(st.integers(0, 5)) == 0:
            lines.append("$V02")
            t += draw(st.sampled_from([1, 30, 5000]))
        t += draw(mostly(st.just(1), st.sampled_from([0, -3])))
        status = draw(mostly(st.just("A"), st.just("V")))
        cells = [str(t), status, f"{48.1371 + k * 1e-4:.6f}", f"{11.575 + k * 1e-5:.6f}", "350",
                 "1200", "-85", "3", "47", "NO20231114-221320-000000F.MP4", "0", "0", "0"]  # fmt: skip
        if hostile and draw(st.integers(0, 3)) == 0:
            j = draw(st.sampled_from([0, 2, 3]))
            cells[j] = draw(st.sampled_from(["", "x", "999", "-91"]) | numbers)
        if hostile and draw(st.integers(0, 5)) == 0:
            cells = cells[: draw(st.integers(1, 4))]
        lines.append(",".join(cells))
    return "\n".join(lines).encode()


# --- the formats read through GPSBabel: FIT (binary), TCX (XML), OziExplorer PLT (text) --------
def fit_crc(data: bytes, crc: int = 0) -> int:
    """CRC-16 of the FIT protocol (Garmin FIT SDK, section 3.3.2)."""
    table = [0x0000, 0xCC01, 0xD801, 0x1400, 0xF001, 0x3C00, 0x2800, 0xE401,
             0xA001, 0x6C00, 0x7800, 0xB401, 0x5000, 0x9C01, 0x8801, 0x4400]  # fmt: skip
    for b in data:
        for nib in (b & 0xF, b >> 4):
            tmp = table[crc & 0xF]
            crc = (crc >> 4) & 0x0FFF
            crc ^= tmp ^ table[nib]
    return crc


@st.composite
def fit_doc(draw) -> bytes:
    """A FIT activity: a file_id message, then ``record`` messages (timestamp, position in
    semicircles, altitude scaled by 5 with offset 500), with hostile values and framing."""
    import struct

    semi = 2**31 / 180
    body = bytes([0x40, 0, 0]) + struct.pack("<HB", 0, 1) + bytes([0, 1, 0x00])  # file_id
    body += bytes([0x00, 4])  # type: activity
    fields = [(253, 4, 0x86), (0, 4, 0x85), (1, 4, 0x85), (2, 2, 0x84)]
    body += bytes([0x41, 0, 0]) + struct.pack("<HB", 20, len(fields))
    body += b"".join(bytes(f) for f in fields)
    hostile = draw(st.booleans())
    t0 = draw(mostly(st.just(1_000_000_000), st.integers(0, 2**32 - 1)))
    for k in range(draw(mostly(st.integers(2, 6), st.integers(0, 8)))):
        ts = (t0 + k) % 2**32
        lat, lon = int((40 + k * 1e-4) * semi), int((-105 + k * 1e-4) * semi)
        alt = (1600 + 500) * 5  # 1600 m: (h + 500) * 5
        if hostile and draw(st.integers(0, 2)) == 0:
            lat = draw(st.sampled_from([0x7FFFFFFF, -(2**31), 2**31 - 1, 0]))
        if hostile and draw(st.integers(0, 2)) == 0:
            lon = draw(st.integers(-(2**31), 2**31 - 1))
        if hostile and draw(st.integers(0, 3)) == 0:
            alt = draw(st.sampled_from([0xFFFF, 0]))
        body += bytes([0x01]) + struct.pack("<IiiH", ts, lat, lon, alt)
    head = struct.pack("<BBHI4s", 14, 0x10, 2093, len(body), b".FIT")
    data = head + struct.pack("<H", fit_crc(head)) + body
    data += struct.pack("<H", fit_crc(data))
    if draw(st.integers(0, 5)) == 0:  # truncated, or a byte changed
        i = draw(st.integers(0, len(data) - 1))
        data = data[:i] + (draw(st.binary(max_size=2)) if draw(st.booleans()) else b"")
    return data


@st.composite
def tcx_doc(draw) -> bytes:
    hostile = draw(st.booleans())
    points = []
    for k in range(draw(mostly(st.integers(2, 5), st.integers(0, 6)))):
        lat, lon = repr(40 + k * 1e-4), repr(-105 + k * 1e-4)
        if hostile and draw(st.integers(0, 2)) == 0:
            lat, lon = draw(numbers), draw(numbers)
        when = draw(mostly(st.just(f"2024-01-01T00:00:{k:02d}Z"), times))
        alt = draw(mostly(st.just("1600"), numbers))
        points.append(
            f"<Trackpoint><Time>{xml_text(when)}</Time><Position><LatitudeDegrees>"
            f"{xml_text(lat)}</LatitudeDegrees><LongitudeDegrees>{xml_text(lon)}"
            f"</LongitudeDegrees></Position><AltitudeMeters>{xml_text(alt)}</AltitudeMeters>"
            "</Trackpoint>"
        )
    return (
        '<?xml version="1.0" encoding="UTF-8"?><TrainingCenterDatabase '
        'xmlns="http://www.garmin.com/xmlschemas/TrainingCenterDatabase/v2"><Activities>'
        '<Activity Sport="Biking"><Id>2024-01-01T00:00:00Z</Id><Lap StartTime='
        f'"2024-01-01T00:00:00Z"><Track>{"".join(points)}</Track></Lap></Activity>'
        "</Activities></TrainingCenterDatabase>"
    ).encode()


@st.composite
def plt_doc(draw) -> bytes:
    lines = ["OziExplorer Track Point File Version 2.1", "WGS 84", "Altitude is in Feet",
             "Reserved 3", "0,2,255,track,0,0,2,8421376"]  # fmt: skip
    n = draw(mostly(st.integers(2, 5), st.integers(0, 6)))
    lines.append(str(draw(mostly(st.just(n), st.integers(-1, 10)))))
    hostile = draw(st.booleans())
    for k in range(n):
        lat, lon = repr(40 + k * 1e-4), repr(-105 + k * 1e-4)
        feet = draw(mostly(st.just("5249"), st.sampled_from(["-777", ""]) | numbers))
        days = f"{45292.0 + 10 * k / 86400:.7f}"
        if hostile and draw(st.integers(0, 2)) == 0:
            lat, lon, days = draw(numbers), draw(numbers), draw(numbers)
        lines.append(
            f"{lat},{lon},{int(k == 0)},{feet},{days},01-Jan-24,00:{k // 6:02d}:{10 * k % 60:02d}"
        )
    return "\r\n".join(lines).encode()


def _gpsbabel():
    import shutil

    import pytest

    if not shutil.which("gpsbabel"):
        pytest.skip("GPSBabel is not installed (apt-get install gpsbabel)")


@FUZZ
@given(nmea_doc(), st.sampled_from([[], ["--max-gap-s=1"], ["--gaps=bridge"]]))
@example(b"$GPRMC", [])  # issue 22: a sentence without fields (IndexError)
@example(b"$GPGGA,120000,4000.0,N", [])
def test_fuzz_nmea(data, options):
    check_ingest(data, "f.nmea", *options)


@FUZZ
@given(igc_doc(), st.just([]))
@example(b"AXXX\r\nHFDTE160722\r\nB", [])
def test_fuzz_igc(data, options):
    check_ingest(data, "f.igc", *options)


@FUZZ
@given(geojson_doc(), choose)
def test_fuzz_geojson(data, options):
    check_ingest(data, "f.geojson", *options)


STAMP_1E25 = (
    "%time,field.header.stamp,field.status.status,field.latitude,field.longitude,field.altitude\n"
    + "".join(f"{k},{10**25 + 2 * k * NS},0,{30.2 + k * 1e-4},-97.6,150\n" for k in range(10))
).encode()


@FUZZ
@given(navsatfix_doc())
@example(STAMP_1E25)  # issue 22: a stamp of 1e25 ns (ValueError: year out of range)
def test_fuzz_navsatfix(data):
    check_ingest(data, "fix.csv")


@FUZZ
@given(columbus_doc())
def test_fuzz_columbus_csv(data):
    check_ingest(data, "GPS001.CSV")


@FUZZ
@given(dashcam_doc())
def test_fuzz_dashcam_70mai(data):
    check_ingest(data, "GPSData000001.txt")


@FUZZ
@given(lettered_csv_doc())
def test_fuzz_lettered_and_nul_padded_csv(data):
    check_ingest(data, "log.csv")


# --- pose trajectories: TUM, EuRoC ground truth, CSV with named pose columns (issue 28) -------
POSE_HEADERS = {
    "tum": "# timestamp tx ty tz qx qy qz qw",
    "euroc": "#timestamp [ns],p_RS_R_x [m],p_RS_R_y [m],p_RS_R_z [m],q_RS_w [],q_RS_x [],"
    "q_RS_y [],q_RS_z []",
    "csv": "t,x,y,z,qw,qx,qy,qz",
}


@st.composite
def pose_doc(draw) -> bytes:
    kind = draw(st.sampled_from(sorted(POSE_HEADERS)))
    hostile = draw(st.booleans())
    sep = " " if kind == "tum" else ","
    lines = [POSE_HEADERS[kind]]
    for k in range(draw(mostly(st.integers(2, 12), st.integers(0, 14)))):
        t = str(1403636579758555392 + k * 5_000_000) if kind == "euroc" else repr(0.01 * k)
        p = [draw(mostly(st.floats(-5, 5).map(repr), numbers)) if hostile else repr(0.1 * k)
             for _ in range(3)]  # fmt: skip
        q = [draw(numbers) for _ in range(4)] if hostile else ["1", "0", "0", "0"]
        if kind == "tum":
            q = q[1:] + q[:1]
        cells = [draw(mostly(st.just(t), numbers)) if hostile else t, *p, *q]
        lines.append(sep.join(cells[: draw(mostly(st.just(8), st.integers(1, 9)))]))
    return "\n".join(lines).encode()


@FUZZ
@given(
    pose_doc(),
    mostly(
        st.sampled_from([["--origin=40,-105,1600"], ["--origin=40,-105,1600", "--pose-world=ned"]]),
        st.sampled_from([[], ["--pose-world=ecef"], ["--origin=40,-105,1600", "--pose-world=flu"]]),
    ),
)
def test_fuzz_pose(data, options):
    check_ingest(data, "poses.txt", *options)


@FUZZ
@given(st.one_of(fit_doc().map(lambda d: (d, "f.fit")), tcx_doc().map(lambda d: (d, "f.tcx")),
                 plt_doc().map(lambda d: (d, "f.plt"))), choose)  # fmt: skip
def test_fuzz_gpsbabel_formats(doc, options):
    _gpsbabel()
    check_ingest(doc[0], doc[1], *options)
