"""Hostile and malformed inputs (issue 16): linear time, bounds, one-line refusals, no output.

Oracles: the growth of reading time with the size of adversarial inputs (a linear reader
takes about 8x longer for 8x the input, a quadratic one 64x), the bounds of
:mod:`imugen.ingest.limits` named in the message, exit status 2 with exactly one stderr line and no
file written, and the regression files of ``tests/data/hostile/``.
"""

from __future__ import annotations

import io
import os
import subprocess
import sys
import tempfile
import time
import zipfile
from pathlib import Path

import pytest

from imugen import cli
from imugen.core.errors import InputError
from imugen.ingest import limits
from imugen.ingest.readers import read_route_file

HOSTILE = Path(__file__).resolve().parents[1] / "data" / "hostile"
KML_HEAD = '<kml xmlns="http://www.opengis.net/kml/2.2"><Placemark><name>P</name>'


def kml_line(coords: str) -> bytes:
    return (KML_HEAD + f"<LineString><coordinates>{coords}</coordinates></LineString>"
            "</Placemark></kml>").encode()  # fmt: skip


def gpx_points(lat: str, n: int = 2) -> bytes:
    pts = "".join(f'<trkpt lat="{lat}" lon="2"/>' for _ in range(n))
    return f"<gpx><trk><trkseg>{pts}</trkseg></trk></gpx>".encode()


def kmz(member: bytes, name: str = "doc.kml") -> bytes:
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", zipfile.ZIP_DEFLATED) as zf:
        zf.writestr(name, member)
    return buf.getvalue()


def refused_or_read(path: Path) -> None:
    try:
        read_route_file(path)
    except InputError:
        pass


def read_seconds(path: Path, data: bytes) -> float:
    path.write_bytes(data)
    best = float("inf")
    for _ in range(5):
        t0 = time.perf_counter()
        refused_or_read(path)
        best = min(best, time.perf_counter() - t0)
    return best


# Adversarial inputs of size ~n: each defeated an earlier reader with super-linear matching
# (whitespace around commas, the number pattern, the CSV header unit pattern) or is plain
# bulk (many points, many rows).
ADVERSARIAL = {
    "kml_spaces_in_coordinates": ("a.kml", lambda n: kml_line("1,2,3" + " " * n + "1,2,3 x")),
    "kml_long_number": ("b.kml", lambda n: kml_line("1" * n + "x,2")),
    "kmz_spaces": ("c.kmz", lambda n: kmz(kml_line("1,2" + " " * n + "1,2 x"))),
    "gpx_long_number": ("d.gpx", lambda n: gpx_points("1" * n + "x")),
    "csv_long_header": ("e.csv", lambda n: f"lat,lon,a{' ' * n}b\n1,2,3\n".encode()),
    "csv_quotes": ("f.csv", lambda n: ('lat,lon,"' + '"' * n + "\n1,2,3\n").encode()),
    "kml_many_tuples": ("g.kml", lambda n: kml_line(" ".join(["2,1.5,3"] * (n // 8)))),
    "enu_many_rows": ("h.txt", lambda n: b"1 2 3\n" * (n // 6)),
    "iso_time_long": ("i.csv", lambda n: f"lat,lon,time\n1,2,{'2' * n}\n1,2.1,x\n".encode()),
}


@pytest.mark.parametrize("case", sorted(ADVERSARIAL))
def test_readers_are_linear_on_adversarial_inputs(case, tmp_path):
    """Reading time for 8x the input grows at most 3x more than linearly (quadratic: 64x)."""
    name, make = ADVERSARIAL[case]
    n = 1 << 15
    small = read_seconds(tmp_path / name, make(n))
    large = read_seconds(tmp_path / name, make(8 * n))
    # 20 ms of slack absorbs scheduling noise on a shared machine (quadratic cases took seconds)
    assert large <= 24 * small + 0.02, (case, small, large)


# --- one line, exit 2, nothing written ----------------------------------------------------------
def ingest_cli(src: Path, tmp_path: Path, *options: str, capsys) -> tuple[int, list[str], Path]:
    out_dir = Path(tempfile.mkdtemp(dir=tmp_path))
    out = out_dir / "route.csv"
    rc = cli.main(["ingest", str(src), "-o", str(out), *options])
    return rc, capsys.readouterr().err.splitlines(), out_dir


def assert_refused(src: Path, tmp_path: Path, fragment: str, *options: str, capsys) -> str:
    rc, lines, out_dir = ingest_cli(src, tmp_path, *options, capsys=capsys)
    assert rc == 2, lines
    assert len(lines) == 1 and lines[0].startswith(f"imugen: error: {src}: "), lines
    assert fragment in lines[0], lines[0]
    assert list(out_dir.iterdir()) == []
    return lines[0]


REGRESSIONS = {
    "year_9999_offset.kml": "time out of range (years 1 to 9999 in UTC)",
    "year_1_offset.gpx": "time out of range (years 1 to 9999 in UTC)",
    "utf32_declared.kml": "unsupported text encoding",
    "bom_utf8_declared_latin1.kml": "UTF-8 byte-order mark but declares encoding 'ISO-8859-1'",
    "enu_1e308.txt": "km from the first row (farther than two points near the Earth can be)",
    "enu_nan.txt": "line 2: not a finite number: 'nan'",
    "csv_inf_height.csv": "not a finite number: 'inf'",
    "csv_time_nan.csv": "time is neither ISO-8601 nor seconds",
    "csv_meta_not_json.csv": "'# imugen:' metadata comment is malformed",
    "csv_meta_list.csv": "malformed (not a JSON object)",
    "csv_meta_origin_nan.csv": "malformed (NaN is not allowed)",
    "csv_meta_origin_string.csv": "malformed (origin is not",
    "csv_meta_notes_int.csv": "malformed (notes is not a list of strings)",
    "csv_meta_start_bad.csv": "malformed (start_time_utc: not an ISO-8601",
    "kml_when_garbage.kml": "<when> 2: not an ISO-8601 date-time",
    "csv_decimal_comma_with_commas.csv": "decimal commas? separate the fields with ';'",
    "gpx_lat_hex.gpx": "not a number: '0x10'",
    "kml_ansi_name.kml": "not well-formed XML",
}


@pytest.mark.parametrize("name", sorted(REGRESSIONS))
def test_regression_files_are_refused_in_one_line(name, tmp_path, capsys):
    src = HOSTILE / name
    options = ["--origin", "40,-105,1600"] if name.startswith("enu") else []
    assert_refused(src, tmp_path, REGRESSIONS[name], *options, capsys=capsys)


def test_every_regression_file_is_listed():
    assert sorted(p.name for p in HOSTILE.iterdir()) == sorted(REGRESSIONS)


def test_generated_hostile_files(tmp_path, capsys):
    """Cases too big to commit, built here: nesting, a deep JSON comment, huge names/tokens."""
    cases = {
        "nested.kml": (
            KML_HEAD + "<MultiGeometry>" * 2000 + "</MultiGeometry>" * 2000 + "</Placemark></kml>",
            "more than 100 levels of XML nesting",
        ),
        "deep_meta.csv": ("# imugen: " + "[" * 100_000 + "\nlat,lon\n1,2\n1.1,2\n", "malformed"),
        "long_name.kml": (
            KML_HEAD.replace("<name>P</name>", "<name>" + "N" * 200_000 + "</name>")
            + "<LineString><coordinates>2,1 2.001,1</coordinates></LineString></Placemark></kml>",
            "more than 1,000 characters in a name (the limit; set IMUGEN_MAX_NAME_CHARS",
        ),
        "long_token.gpx": (gpx_points("1" * 30_000).decode(), "a value longer than 100 characters"),
        "long_header.csv": (
            "lat,lon," + "x" * 30_000 + "\n1,2,3\n1.1,2,3\n",
            "IMUGEN_MAX_NAME_CHARS",
        ),
    }
    for name, (text, fragment) in cases.items():
        src = tmp_path / name
        src.write_text(text)
        line = assert_refused(src, tmp_path, fragment, capsys=capsys)
        assert len(line) < 400  # nothing of the hostile content is echoed at length


def test_control_characters_are_escaped_in_messages(tmp_path, capsys):
    src = tmp_path / "esc.csv"
    src.write_text('# imugen: {"path": "\\u001b[2J\\rgotcha"}\nlat,lon\n1,2\n1.001,2\n')
    line = assert_refused(src, tmp_path, "no path named", "--path", "other", capsys=capsys)
    assert "\x1b" not in line and "\r" not in line and "\\x1b[2J\\rgotcha" in line


def test_non_finite_and_hostile_options_refused(tmp_path, capsys):
    src = tmp_path / "ok.csv"
    src.write_text("lat,lon\n1,2\n1.001,2\n")
    for options, fragment in (
        (["--max-speed-kmh", "nan"], "--max-speed-kmh: nan must be a positive number"),
        (["--max-extent-km", "inf"], "--max-extent-km: inf must be a positive number"),
        (["--gap-warn-s", "-1"], "--gap-warn-s"),
        (["--origin", "nan,2,3"], "--origin"),
        (["--dt", "1e308"], "--dt"),
    ):
        rc, lines, out_dir = ingest_cli(src, tmp_path, *options, capsys=capsys)
        assert rc == 2 and len(lines) == 1 and fragment in lines[0], lines
        assert list(out_dir.iterdir()) == []


# --- bounds and non-regular files ---------------------------------------------------------------
def test_bounds_are_named_and_configurable(tmp_path, capsys, monkeypatch):
    rows = "".join(f"{i} {i} 0\n" for i in range(11))
    src = tmp_path / "eleven.txt"
    src.write_text(rows)
    origin = ["--origin", "40,-105,1600"]
    assert ingest_cli(src, tmp_path, *origin, capsys=capsys)[0] == 0
    monkeypatch.setenv("IMUGEN_MAX_POINTS", "10")
    assert_refused(src, tmp_path, "more than 10 points (the limit; set IMUGEN_MAX_POINTS", *origin,
                   capsys=capsys)  # fmt: skip
    monkeypatch.setenv("IMUGEN_MAX_POINTS", "ten")
    rc, lines, _ = ingest_cli(src, tmp_path, *origin, capsys=capsys)
    assert rc == 2 and lines == [
        "imugen: error: IMUGEN_MAX_POINTS: 'ten' is not a positive integer"
    ]
    monkeypatch.delenv("IMUGEN_MAX_POINTS")
    monkeypatch.setenv("IMUGEN_MAX_INPUT_BYTES", str(len(rows) - 1))
    assert_refused(src, tmp_path, f"more than {len(rows) - 1:,} bytes", *origin, capsys=capsys)
    monkeypatch.delenv("IMUGEN_MAX_INPUT_BYTES")
    nested = tmp_path / "folders.kml"
    nested.write_text(KML_HEAD.replace("<Placemark>", "<Folder>" * 10 + "<Placemark>")
                      + "<LineString><coordinates>2,1 2.001,1</coordinates></LineString>"
                      + "</Placemark>" + "</Folder>" * 10 + "</kml>")  # fmt: skip
    assert ingest_cli(nested, tmp_path, capsys=capsys)[0] == 0
    monkeypatch.setenv("IMUGEN_MAX_DEPTH", "8")
    assert_refused(nested, tmp_path, "more than 8 levels of XML nesting", capsys=capsys)
    monkeypatch.setenv("IMUGEN_MAX_XML_ELEMENTS", "5")
    monkeypatch.delenv("IMUGEN_MAX_DEPTH")
    assert_refused(nested, tmp_path, "more than 5 XML elements", capsys=capsys)


def test_kmz_member_bounded_by_the_input_bound(tmp_path, capsys, monkeypatch):
    """A KMZ far under the input bound whose KML inflates past it (a zip bomb of spaces)."""
    src = tmp_path / "bomb.kmz"
    src.write_bytes(kmz(kml_line("2,1" + " " * (8 << 20) + "2.001,1")))
    assert src.stat().st_size < 64 << 10
    monkeypatch.setenv("IMUGEN_MAX_INPUT_BYTES", str(4 << 20))
    assert_refused(src, tmp_path, "decompresses to more than 4194304 bytes", capsys=capsys)


def test_large_file_read_stops_at_the_bound(tmp_path, monkeypatch):
    """A 4 GiB sparse file is refused after reading bound + 1 bytes, not 4 GiB."""
    big = tmp_path / "big.csv"
    with big.open("wb") as fh:
        fh.truncate(4 << 30)
    read = []
    real = os.read

    def counting(fd, n):
        data = real(fd, n)
        read.append(len(data))
        return data

    monkeypatch.setattr(os, "read", counting)
    monkeypatch.setenv("IMUGEN_MAX_INPUT_BYTES", str(1 << 20))
    with pytest.raises(InputError, match="IMUGEN_MAX_INPUT_BYTES"):
        limits.read_input(big)
    assert sum(read) == (1 << 20) + 1


@pytest.mark.parametrize("kind", ["fifo", "directory", "device"])
def test_non_regular_files_refused_without_blocking(kind, tmp_path):
    if kind == "fifo":
        src = tmp_path / "f.kml"
        os.mkfifo(src)
    elif kind == "directory":
        src = tmp_path / "d.kml"
        src.mkdir()
    else:
        src = Path("/dev/zero")
    # in a subprocess with a timeout: a blocking open or an endless read fails the test
    r = subprocess.run([sys.executable, "-m", "imugen", "ingest", str(src), "-o",
                        str(tmp_path / "o.csv")], capture_output=True, text=True, timeout=60)  # fmt: skip
    assert r.returncode == 2 and len(r.stderr.splitlines()) == 1, r.stderr
    assert (
        "FIFO" if kind == "fifo" else "directory" if kind == "directory" else "device"
    ) in r.stderr
    assert not (tmp_path / "o.csv").exists()


# --- dialects that are read ---------------------------------------------------------------------
DIALECTS = {
    "quoted.csv": ('name,lat,lon\n"Main St, 5",40.0,-105.0\n"Elm ""x""",40.001,-105.0\n', "utf-8"),
    "semicolon.csv": ("lat;lon;alt\n40,0;-105,0;1600,5\n40,001;-105,0;1601,5\n", "utf-8"),
    "utf16.csv": ("lat\tlon\tname\n40.0\t-105.0\tZürich\n40.001\t-105.0\tÅ\n", "utf-16"),
    "utf8bom.csv": ("lat,lon\n40.0,-105.0\n40.001,-105.0\n", "utf-8-sig"),
    "utf32.csv": ("lat,lon\n40.0,-105.0\n40.001,-105.0\n", "utf-32"),
}


@pytest.mark.parametrize("name", sorted(DIALECTS))
def test_csv_dialects_are_read(name, tmp_path):
    text, encoding = DIALECTS[name]
    src = tmp_path / name
    src.write_bytes(text.encode(encoding))
    (p,) = read_route_file(src)
    assert list(p.lat_deg) == [40.0, 40.001] and list(p.lon_deg) == [-105.0, -105.0]
    if name == "semicolon.csv":
        assert list(p.alt_m) == [1600.5, 1601.5] and any("decimal comma" in n for n in p.notes)


def test_utf16_without_bom_is_cleaned_and_said(tmp_path):
    # NUL bytes between ASCII characters (UTF-16 without a byte-order mark, or NUL-padded
    # fields) are removed with a warning by the GNSS CSV reader rather than refused
    src = tmp_path / "u.csv"
    src.write_bytes("lat,lon\n1,2\n1.001,2\n".encode("utf-16-le"))
    (p,) = read_route_file(src)
    assert p.n_points == 2 and any("NUL" in w for w in p.warnings)


# --- a numba cache that cannot be written -------------------------------------------------------
def test_numba_cache_write_failure_does_not_fail(tmp_path):
    """Empty cache + RLIMIT_FSIZE too small for any cache file: the kernel still runs."""
    import resource
    import signal

    mod = tmp_path / "kernel.py"
    mod.write_text(
        "from imugen.core.jit import njit\n\n@njit(cache=True)\ndef f(n):\n"
        "    s = 0.0\n    for i in range(n):\n        s += i\n    return s\n\nprint(f(10))\n"
    )

    def small_files():
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
        resource.setrlimit(resource.RLIMIT_FSIZE, (200, 200))

    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path / "cache"))
    r = subprocess.run([sys.executable, str(mod)], capture_output=True, text=True, env=env,
                       preexec_fn=small_files, timeout=120)  # fmt: skip
    assert r.returncode == 0 and r.stdout.strip() == "45.0", r.stderr


def test_candidate_listing_is_bounded(tmp_path, capsys):
    marks = "".join(
        f"<Placemark><name>p{i}</name><LineString><coordinates>2,1 2.001,1</coordinates>"
        "</LineString></Placemark>"
        for i in range(500)
    )
    src = tmp_path / "many.kml"
    src.write_text(f"<kml>{marks}</kml>")
    line = assert_refused(src, tmp_path, "holds 500 candidate paths", capsys=capsys)
    assert "[8] 'p7'" in line and "[9]" not in line and "and 492 more" in line
