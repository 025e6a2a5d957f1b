"""Structure-aware fuzzing of every reader through ``imugen ingest`` (issue 16).

Hypothesis builds KML, KMZ, GPX, CSV and E N U files from their grammar with hostile leaves
(non-finite and overflowing numbers, times at the ends of the calendar, stray separators,
deep nesting, odd encodings, malformed ``# imugen:`` comments). Oracle for every case: the
command either succeeds with a table of finite numbers, or exits with status 2, one stderr
line ``imugen: error: ...`` and nothing written; any other exception fails the test. The
budget is fixed (``derandomize``, 200 cases per reader) so CI runs the same cases each time;
``IMUGEN_FUZZ_EXAMPLES=5000`` runs a deeper search locally.
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
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from imugen import cli

FUZZ = settings(
    max_examples=int(os.environ.get("IMUGEN_FUZZ_EXAMPLES", "200")),
    deadline=None,
    derandomize=True,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
)

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


choose = mostly(st.just(["--path", "1"]), st.sampled_from([[], ["--path", "2"], ["--path", "A"]]))


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
@given(csv_doc(), st.sampled_from([[], ["--origin", "40,-105,1600"], ["--dt", "1"]]))
def test_fuzz_csv(data, options):
    check_ingest(data, "f.csv", *options)


@FUZZ
@given(
    enu_doc(),
    mostly(
        st.just(["--origin", "40,-105,1600"]), st.sampled_from([["--origin", "40,-105,nan"], []])
    ),
)
def test_fuzz_enu_text(data, options):
    check_ingest(data, "f.txt", *options)
