"""Tests of the KML/KMZ reader (imugen.ingest.readers.kml).

Expected values are computed here independently of the reader: literal numbers of
small crafted files, and regular expressions / ``datetime.strptime`` over the raw text
of real files.
"""

from __future__ import annotations

import calendar
import io
import re
import zipfile
from datetime import datetime
from pathlib import Path

import numpy as np
import pytest

from imugen.core.errors import InputError
from imugen.ingest.readers import kml as kml_mod
from imugen.ingest.readers.kml import read_kml, read_kmz

from helpers import DATA as DATA_DIR
from helpers import REPO

DATA = DATA_DIR / "kml"
NS22 = "http://www.opengis.net/kml/2.2"
GX = "http://www.google.com/kml/ext/2.2"


def write(tmp_path: Path, text: str | bytes, name: str = "route.kml") -> Path:
    path = tmp_path / name
    path.write_bytes(text.encode("utf-8") if isinstance(text, str) else text)
    return path


def doc(body: str, ns: str | None = NS22, gx: bool = True) -> str:
    """A KML document with ``body`` inside ``<kml>``."""
    attrs = f' xmlns="{ns}"' if ns else ""
    if gx:
        attrs += f' xmlns:gx="{GX}"'
    return f'<?xml version="1.0" encoding="UTF-8"?>\n<kml{attrs}>\n{body}\n</kml>\n'


def placemark(geometry: str, name: str | None = "P") -> str:
    name_el = f"<name>{name}</name>" if name is not None else ""
    return f"<Placemark>{name_el}{geometry}</Placemark>"


def utc(text: str) -> float:
    """Independent ISO 'YYYY-mm-ddTHH:MM:SSZ' -> POSIX seconds."""
    return float(calendar.timegm(datetime.strptime(text, "%Y-%m-%dT%H:%M:%SZ").timetuple()))


ABS_LINE = (
    "<LineString><altitudeMode>absolute</altitudeMode>"
    "<coordinates>-7.99,31.63,450 -7.98,31.64,460.5</coordinates></LineString>"
)


# --------------------------------------------------------------------------- namespaces


@pytest.mark.parametrize(
    "ns",
    [
        "http://earth.google.com/kml/2.0",
        "http://earth.google.com/kml/2.1",
        "http://www.opengis.net/kml/2.2",
        "http://www.opengis.net/kml/2.3",
        None,
    ],
)
def test_namespace_variants(tmp_path, ns):
    path = write(tmp_path, doc(f"<Document>{placemark(ABS_LINE, 'Road')}</Document>", ns, False))
    (p,) = read_kml(path)
    assert p.name == "Road"
    assert p.kind == "LineString"
    np.testing.assert_array_equal(p.lon_deg, [-7.99, -7.98])
    np.testing.assert_array_equal(p.lat_deg, [31.63, 31.64])
    np.testing.assert_array_equal(p.alt_m, [450.0, 460.5])
    assert p.altitude_mode == "absolute"
    assert p.altitude_trusted
    assert p.time_unix_s is None
    assert p.notes == []


def test_prefixed_kml_namespace(tmp_path):
    text = (
        f'<k:kml xmlns:k="{NS22}"><k:Document><k:Placemark><k:LineString>'
        "<k:altitudeMode>absolute</k:altitudeMode><k:coordinates>1,2,3 4,5,6</k:coordinates>"
        "</k:LineString></k:Placemark></k:Document></k:kml>"
    )
    (p,) = read_kml(write(tmp_path, text))
    np.testing.assert_array_equal(p.alt_m, [3.0, 6.0])


# ------------------------------------------------------------------------ coordinates


def test_messy_coordinates(tmp_path):
    coords = (
        "\r\n\t  -7.5,31.5,100\t\t-7.6,31.6,101 <!-- a comment -->\r\n"
        "+008.5,+031.25,-2.5e1\n   \n-7.7 , 31.7, 102\r\n\t"
    )
    line = (
        f"<LineString><altitudeMode>absolute</altitudeMode><coordinates>{coords}"
        "</coordinates></LineString>"
    )
    text = doc(placemark(line)).replace("\n", "\r\n")
    (p,) = read_kml(write(tmp_path, text))
    np.testing.assert_array_equal(p.lon_deg, [-7.5, -7.6, 8.5, -7.7])
    np.testing.assert_array_equal(p.lat_deg, [31.5, 31.6, 31.25, 31.7])
    np.testing.assert_array_equal(p.alt_m, [100.0, 101.0, -25.0, 102.0])
    assert p.altitude_trusted


def test_two_d_tuples_among_3d_are_missing_heights(tmp_path):
    # issue 27: a 2-D tuple among 3-D ones has no height (interpolated by ingestion), not 0 m
    line = (
        "<LineString><altitudeMode>absolute</altitudeMode>"
        "<coordinates>1.5,2.5 3.5,4.5,7</coordinates></LineString>"
    )
    (p,) = read_kml(write(tmp_path, doc(placemark(line))))
    np.testing.assert_array_equal(p.lon_deg, [1.5, 3.5])
    np.testing.assert_array_equal(p.lat_deg, [2.5, 4.5])
    np.testing.assert_array_equal(p.alt_m, [0.0, 7.0])
    np.testing.assert_array_equal(p.alt_missing, [True, False])
    assert p.altitude_trusted
    assert any("2-D" in n and "1 of 2" in n and "missing" in n for n in p.notes)


@pytest.mark.parametrize(
    ("coords", "bad"),
    [("1,2,3 1,x,3 4,5,6", "2"), ("1,2,3 4,5,6 7", "3"), ("1,2,3,4,5,6", "1")],
)
def test_bad_tuple_names_placemark_and_tuple(tmp_path, coords, bad):
    line = f"<LineString><coordinates>{coords}</coordinates></LineString>"
    path = write(tmp_path, doc(placemark(line, "Main road")))
    with pytest.raises(InputError) as info:
        read_kml(path)
    assert info.value.source == str(path)
    assert "Main road" in info.value.message
    assert f"tuple {bad} " in info.value.message


def test_placemark_timestamp_on_linestring_is_ignored(tmp_path):
    pm = (
        "<Placemark><name>L</name><TimeStamp><when>2020-01-01T00:00:00Z</when></TimeStamp>"
        f"{ABS_LINE}</Placemark>"
    )
    (p,) = read_kml(write(tmp_path, doc(pm)))
    assert p.time_unix_s is None
    assert p.n_points == 2


# ------------------------------------------------------------------------------ tracks

WHENS = ["2020-01-01T00:00:00Z", "2020-01-01T00:00:01Z", "2020-01-01T00:00:03Z"]
COORDS = ["-7.99 31.63 450", "-7.9899 31.6301 451", "-7.9898 31.6302 452.5"]


def _track(tag: str, interleaved: bool, mode: str = "absolute") -> str:
    w = [f"<when>{t}</when>" for t in WHENS]
    c = [f"<{tag.replace('Track', 'coord')}>{x}</{tag.replace('Track', 'coord')}>" for x in COORDS]
    items = [x for pair in zip(w, c, strict=True) for x in pair] if interleaved else w + c
    return f"<{tag}><altitudeMode>{mode}</altitudeMode>{''.join(items)}</{tag}>"


def _check_track(p):
    assert p.kind == "Track"
    np.testing.assert_array_equal(p.lon_deg, [-7.99, -7.9899, -7.9898])
    np.testing.assert_array_equal(p.lat_deg, [31.63, 31.6301, 31.6302])
    np.testing.assert_array_equal(p.alt_m, [450.0, 451.0, 452.5])
    np.testing.assert_array_equal(p.time_unix_s, [utc(t) for t in WHENS])
    assert p.time_unix_s[0] == 1577836800.0  # 2020-01-01T00:00:00Z, known epoch


@pytest.mark.parametrize("interleaved", [True, False])
def test_gx_track(tmp_path, interleaved):
    body = (
        f"<Document><Folder>{placemark(_track('gx:Track', interleaved), 'T')}</Folder></Document>"
    )
    (p,) = read_kml(write(tmp_path, doc(body)))
    assert p.name == "T"
    assert p.altitude_mode == "absolute"
    _check_track(p)


def test_kml23_track_without_prefix_directly_under_kml(tmp_path):
    body = placemark(_track("Track", interleaved=False), name=None)
    text = doc(body, ns="http://www.opengis.net/kml/2.3", gx=False)
    (p,) = read_kml(write(tmp_path, text))
    assert p.name == "Placemark 1"
    _check_track(p)


def test_empty_coord_skipped_with_its_when(tmp_path):
    track = (
        "<gx:Track><altitudeMode>absolute</altitudeMode>"
        f"<when>{WHENS[0]}</when><when>2020-01-01T00:00:02Z</when>"
        f"<when>{WHENS[1]}</when><when>{WHENS[2]}</when>"
        f"<gx:coord>{COORDS[0]}</gx:coord><gx:coord>  </gx:coord>"
        f"<gx:coord>{COORDS[1]}</gx:coord><gx:coord>{COORDS[2]}</gx:coord></gx:Track>"
    )
    (p,) = read_kml(write(tmp_path, doc(placemark(track))))
    _check_track(p)
    assert any("skipped 1 empty <coord>" in n for n in p.notes)


def test_track_count_mismatch_refused(tmp_path):
    track = (
        f"<gx:Track><when>{WHENS[0]}</when><when>{WHENS[1]}</when>"
        f"<gx:coord>{COORDS[0]}</gx:coord></gx:Track>"
    )
    path = write(tmp_path, doc(placemark(track, "Walk")))
    with pytest.raises(InputError, match=r"2 <when> but 1 <coord>") as info:
        read_kml(path)
    assert info.value.source == str(path)
    assert "Walk" in info.value.message


def test_bad_when_refused(tmp_path):
    track = (
        f"<gx:Track><when>{WHENS[0]}</when><when>yesterday noon</when>"
        f"<gx:coord>{COORDS[0]}</gx:coord><gx:coord>{COORDS[1]}</gx:coord></gx:Track>"
    )
    path = write(tmp_path, doc(placemark(track, "Walk")))
    with pytest.raises(InputError, match="yesterday noon") as info:
        read_kml(path)
    assert "Walk" in info.value.message
    assert "<when> 2" in info.value.message


def test_bad_coord_refused(tmp_path):
    track = (
        f"<gx:Track><when>{WHENS[0]}</when><when>{WHENS[1]}</when>"
        f"<gx:coord>{COORDS[0]}</gx:coord><gx:coord>1 two 3</gx:coord></gx:Track>"
    )
    with pytest.raises(InputError, match=r"Walk.*tuple 2 '1 two 3'"):
        read_kml(write(tmp_path, doc(placemark(track, "Walk"))))


def test_track_timezone_offset(tmp_path):
    track = (
        "<gx:Track><when>2020-01-01T01:00:00+01:00</when><when>2020-01-01T00:00:00.5Z</when>"
        f"<gx:coord>{COORDS[0]}</gx:coord><gx:coord>{COORDS[1]}</gx:coord></gx:Track>"
    )
    (p,) = read_kml(write(tmp_path, doc(placemark(track))))
    np.testing.assert_array_equal(p.time_unix_s, [1577836800.0, 1577836800.5])


def test_multitrack_each_track_is_a_candidate(tmp_path):
    t1 = "".join(
        f"<when>{w}</when><gx:coord>{c}</gx:coord>" for w, c in zip(WHENS, COORDS, strict=True)
    )
    t2 = f"<when>{WHENS[0]}</when><gx:coord>1 2 3</gx:coord>"
    mt = (
        "<gx:MultiTrack><altitudeMode>absolute</altitudeMode><gx:interpolate>0</gx:interpolate>"
        f"<gx:Track>{t1}</gx:Track><gx:Track>{t2}</gx:Track></gx:MultiTrack>"
    )
    paths = read_kml(write(tmp_path, doc(placemark(mt, "Day"))))
    assert [p.name for p in paths] == ["Day [1]", "Day [2]"]
    assert [p.n_points for p in paths] == [3, 1]
    _check_track(paths[0])  # altitudeMode inherited from the MultiTrack
    assert paths[1].altitude_trusted
    np.testing.assert_array_equal(paths[1].alt_m, [3.0])


# -------------------------------------------------------------- structure and names


def test_multigeometry_nested(tmp_path):
    mg = (
        "<MultiGeometry>"
        "<LineString><coordinates>1,1,1 2,2,2</coordinates></LineString>"
        "<Point><coordinates>9,9,9</coordinates></Point>"
        "<MultiGeometry><LineString><coordinates>3,3,3 4,4,4 5,5,5</coordinates></LineString>"
        "<Polygon><outerBoundaryIs><LinearRing><coordinates>0,0 1,0 1,1 0,0</coordinates>"
        "</LinearRing></outerBoundaryIs></Polygon></MultiGeometry>"
        "<LineString><coordinates>6,6 7,7</coordinates></LineString>"
        "</MultiGeometry>"
    )
    paths = read_kml(write(tmp_path, doc(placemark(mg, "Bus"))))
    assert [p.name for p in paths] == ["Bus [1]", "Bus [2]", "Bus [3]"]
    assert [p.n_points for p in paths] == [2, 3, 2]
    np.testing.assert_array_equal(paths[1].lon_deg, [3.0, 4.0, 5.0])
    assert all(p.kind == "LineString" for p in paths)


def test_placemarks_anywhere_in_document_order(tmp_path):
    body = (
        placemark(ABS_LINE, "top")
        + "<Document><name>D</name>"
        + placemark("<Point><coordinates>1,2</coordinates></Point>", "pt")
        + "<Folder><Folder><Folder>"
        + placemark(ABS_LINE, None)
        + "</Folder></Folder>"
        + placemark(ABS_LINE, "  spaced name \n")
        + "</Folder></Document>"
    )
    paths = read_kml(write(tmp_path, doc(body)))
    # "Placemark k" counts every Placemark of the file (the Point one included).
    assert [p.name for p in paths] == ["top", "Placemark 3", "spaced name"]


def test_polygons_linear_rings_and_overlays_are_not_paths(tmp_path):
    ring = "<LinearRing><coordinates>0,0,0 1,0,0 1,1,0 0,0,0</coordinates></LinearRing>"
    body = (
        "<Document>"
        + placemark(f"<Polygon><outerBoundaryIs>{ring}</outerBoundaryIs></Polygon>", "poly")
        + placemark(ring, "ring")
        + "<GroundOverlay><name>g</name><LatLonBox><north>1</north></LatLonBox></GroundOverlay>"
        + placemark(ABS_LINE, "road")
        + placemark("<Model><Location><longitude>1</longitude></Location></Model>", "m")
        + "</Document>"
    )
    paths = read_kml(write(tmp_path, doc(body)))
    assert [p.name for p in paths] == ["road"]


def test_polygon_only_file_refused(tmp_path):
    ring = "<LinearRing><coordinates>0,0,0 1,0,0 1,1,0 0,0,0</coordinates></LinearRing>"
    pt = "<Point><coordinates>1,2</coordinates></Point>"
    body = (
        "<Document>"
        + placemark(f"<Polygon><outerBoundaryIs>{ring}</outerBoundaryIs></Polygon>")
        + placemark(pt)
        + placemark(pt)
        + "</Document>"
    )
    path = write(tmp_path, doc(body))
    with pytest.raises(InputError) as info:
        read_kml(path)
    assert info.value.source == str(path)
    assert "no path (LineString, Track) found" in info.value.message
    assert "2 Points, 1 Polygons" in info.value.message


# --------------------------------------------------------------------- altitudeMode


@pytest.mark.parametrize(
    ("element", "trusted", "kept"),
    [
        ("<altitudeMode>absolute</altitudeMode>", True, True),
        ("<altitudeMode>relativeToGround</altitudeMode>", False, True),
        ("<gx:altitudeMode>relativeToSeaFloor</gx:altitudeMode>", False, True),
        ("<altitudeMode>clampToGround</altitudeMode>", False, False),
        ("<gx:altitudeMode>clampToSeaFloor</gx:altitudeMode>", False, False),
        ("", False, True),  # KML default: heights kept as written, untrusted
    ],
)
def test_altitude_mode_policy(tmp_path, element, trusted, kept):
    line = f"<LineString>{element}<coordinates>1,2,300 3,4,310</coordinates></LineString>"
    (p,) = read_kml(write(tmp_path, doc(placemark(line))))
    mode = re.sub(r"<[^>]*>", "", element) or None
    assert p.altitude_mode == mode
    assert p.altitude_trusted is trusted
    np.testing.assert_array_equal(p.alt_m, [300.0, 310.0] if kept else [0.0, 0.0])
    if not kept:
        assert f"altitudes ignored (altitudeMode {mode}): set to 0 m" in p.notes
    elif not trusted:
        assert any((mode or "no altitudeMode") in n and "not trusted" in n for n in p.notes)


# --------------------------------------------------------------- refusals and safety


def test_not_kml_refused(tmp_path):
    text = '<?xml version="1.0"?><gpx xmlns="http://www.topografix.com/GPX/1/1"><trk/></gpx>'
    path = write(tmp_path, text)
    with pytest.raises(InputError, match=r"not a KML file.*<gpx>") as info:
        read_kml(path)
    assert info.value.source == str(path)


@pytest.mark.parametrize(
    "text",
    [
        doc(placemark(ABS_LINE)).replace("</Placemark>", ""),
        "lon,lat,alt\n1,2,3\n",
        b"\x89PNG\r\n\x1a\n\x00\x00\x00\rIHDR",
        b"",
    ],
)
def test_malformed_refused(tmp_path, text):
    path = write(tmp_path, text)
    with pytest.raises(InputError) as info:
        read_kml(path)
    assert info.value.source == str(path)


def test_missing_file_refused(tmp_path):
    with pytest.raises(InputError):
        read_kml(tmp_path / "nope.kml")


def test_xxe_refused_without_leaking(tmp_path):
    secret = tmp_path / "secret.txt"
    token = "TOKEN-5f0c3a91-never-print-me"
    secret.write_text(token)
    targets = [secret.as_uri()]
    if Path("/etc/hostname").is_file():
        targets.append("file:///etc/hostname")
    for target in targets:
        text = (
            f'<?xml version="1.0"?>\n<!DOCTYPE kml [<!ENTITY xxe SYSTEM "{target}">]>\n'
            + doc(
                placemark("<LineString><coordinates>&xxe;</coordinates></LineString>", "&xxe;")
            ).split("\n", 1)[1]
        )
        path = write(tmp_path, text)
        with pytest.raises(InputError) as info:
            read_kml(path)
        assert "refused" in info.value.message
        assert token not in str(info.value)


def test_billion_laughs_refused(tmp_path):
    ents = ['<!ENTITY lol0 "lol">'] + [
        f'<!ENTITY lol{i} "{f"&lol{i - 1};" * 10}">' for i in range(1, 10)
    ]
    text = (
        '<?xml version="1.0"?>\n<!DOCTYPE kml [' + "".join(ents) + "]>\n"
        f'<kml xmlns="{NS22}"><Placemark><name>&lol9;</name>{ABS_LINE}</Placemark></kml>'
    )
    with pytest.raises(InputError, match=r"refused.*DOCTYPE"):
        read_kml(write(tmp_path, text))


# ------------------------------------------------------------------------------- KMZ


def make_zip(tmp_path: Path, members: list[tuple[str, bytes]], name: str = "r.kmz") -> Path:
    path = tmp_path / name
    with zipfile.ZipFile(path, "w", compression=zipfile.ZIP_DEFLATED) as zf:
        for member, data in members:
            zf.writestr(member, data)
    return path


KML_A = doc(placemark(ABS_LINE, "from A")).encode()
KML_B = doc(placemark(ABS_LINE, "from B")).encode()


def test_kmz_doc_kml(tmp_path):
    path = make_zip(
        tmp_path,
        [("a.kml", KML_A), ("files/x.kml", KML_A), ("doc.kml", KML_B), ("files/i.png", b"\x89")],
    )
    (p,) = read_kmz(path)
    assert p.name == "from B"
    (q,) = read_kml(write(tmp_path, KML_B))
    for attr in ("lat_deg", "lon_deg", "alt_m"):
        np.testing.assert_array_equal(getattr(p, attr), getattr(q, attr))


def test_kmz_first_root_kml_when_no_doc_kml(tmp_path):
    path = make_zip(tmp_path, [("sub/doc.kml", KML_A), ("route.kml", KML_B), ("other.kml", KML_A)])
    (p,) = read_kmz(path)
    assert p.name == "from B"


def test_kmz_without_root_kml_refused(tmp_path):
    path = make_zip(tmp_path, [("sub/doc.kml", KML_A), ("readme.txt", b"hi")])
    with pytest.raises(InputError, match=r"no \.kml") as info:
        read_kmz(path)
    assert info.value.source == str(path)


def test_kmz_not_a_zip_refused(tmp_path):
    path = write(tmp_path, KML_A, "route.kmz")
    with pytest.raises(InputError, match=r"not a KMZ \(zip\) archive") as info:
        read_kmz(path)
    assert info.value.source == str(path)


@pytest.mark.parametrize(
    "member", ["../evil.kml", "/evil.kml", "a/../../evil.kml", "C:/evil.kml", "..\\evil.kml"]
)
def test_kmz_unsafe_member_refused(tmp_path, member):
    path = tmp_path / "evil.kmz"
    with zipfile.ZipFile(path, "w") as zf:
        zf.writestr(zipfile.ZipInfo(member), KML_A)
    with pytest.raises(InputError, match=r"absolute or '\.\.' path"):
        read_kmz(path)
    assert not (tmp_path.parent / "evil.kml").exists()


def test_kmz_member_errors_name_the_archive(tmp_path):
    path = make_zip(tmp_path, [("doc.kml", b"<gpx/>")])
    with pytest.raises(InputError, match=r"doc\.kml.*not a KML file") as info:
        read_kmz(path)
    assert info.value.source == str(path)


def test_kmz_size_bound_from_header(tmp_path, monkeypatch):
    monkeypatch.setattr(kml_mod, "KMZ_MAX_MEMBER_BYTES", 4096)
    padded = KML_A.replace(b"<Placemark>", b"<!--" + b" " * 10_000 + b"--><Placemark>")
    path = make_zip(tmp_path, [("doc.kml", padded)])

    def no_open(*_args, **_kwargs):
        raise AssertionError("the member must be refused before it is inflated")

    with monkeypatch.context() as m:
        m.setattr(zipfile.ZipFile, "open", no_open)
        with pytest.raises(InputError, match="decompresses to more than 4096 bytes"):
            read_kmz(path)
    # Under the bound it is read.
    monkeypatch.setattr(kml_mod, "KMZ_MAX_MEMBER_BYTES", 20_000)
    assert read_kmz(path)[0].name == "from A"


def test_kmz_lying_header_refused(tmp_path, monkeypatch):
    """A member whose headers claim a small size but which inflates to more."""
    monkeypatch.setattr(kml_mod, "KMZ_MAX_MEMBER_BYTES", 4096)
    padded = KML_A.replace(b"<Placemark>", b"<!--" + b" " * 10_000 + b"--><Placemark>")
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", compression=zipfile.ZIP_DEFLATED) as zf:
        zf.writestr("doc.kml", padded)
    raw = bytearray(buf.getvalue())
    size = len(padded).to_bytes(4, "little")
    lie = (1000).to_bytes(4, "little")
    # Uncompressed size sits at offset 22 of the local header and 24 of the central one.
    local_at = raw.index(b"PK\x03\x04")
    central_at = raw.index(b"PK\x01\x02")
    assert raw[local_at + 22 : local_at + 26] == size
    assert raw[central_at + 24 : central_at + 28] == size
    raw[local_at + 22 : local_at + 26] = lie
    raw[central_at + 24 : central_at + 28] = lie
    path = write(tmp_path, bytes(raw), "lie.kmz")
    with zipfile.ZipFile(path) as zf:
        assert zf.getinfo("doc.kml").file_size == 1000  # the lie is what a reader sees
    with pytest.raises(InputError):
        read_kmz(path)


@pytest.mark.parametrize(
    "field, value, expected",
    [
        # compression method 9 (deflate64): zipfile raises NotImplementedError
        ("method", 9, "cannot be read .*compression method"),
        # general-purpose flag bit 0 (encrypted): zipfile raises RuntimeError
        ("flags", 1, "cannot be read .*encrypted"),
    ],
)
def test_kmz_unreadable_member_is_one_input_error(tmp_path, field, value, expected):
    """A member zipfile cannot open (a compression method it lacks, an encrypted member) is the
    user's file: one InputError naming the archive and the member, no traceback."""
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", compression=zipfile.ZIP_DEFLATED) as zf:
        zf.writestr("doc.kml", KML_A)
    raw = bytearray(buf.getvalue())
    local_at, central_at = raw.find(b"PK\x03\x04"), raw.find(b"PK\x01\x02")
    # flags at offset 6 (local) / 8 (central), method at 8 / 10
    off = {"flags": (6, 8), "method": (8, 10)}[field]
    for base, o in zip((local_at, central_at), off, strict=True):
        raw[base + o : base + o + 2] = value.to_bytes(2, "little")
    path = write(tmp_path, bytes(raw), "odd.kmz")
    with pytest.raises(InputError, match=rf"doc\.kml.*{expected}") as info:
        read_kmz(path)
    assert info.value.source == str(path)


def test_kmz_stream_longer_than_header_refused(tmp_path, monkeypatch):
    """Bytes are counted while reading: a stream yielding more than its header says."""
    monkeypatch.setattr(kml_mod, "KMZ_MAX_MEMBER_BYTES", 4096)
    path = make_zip(tmp_path, [("doc.kml", KML_A)])  # header: small, under the bound
    padded = KML_A.replace(b"<Placemark>", b"<!--" + b" " * 10_000 + b"--><Placemark>")
    monkeypatch.setattr(zipfile.ZipFile, "open", lambda *_a, **_k: io.BytesIO(padded))
    with pytest.raises(InputError, match="decompresses to more than 4096 bytes"):
        read_kmz(path)


def test_kmz_real_zip_bomb_refused_from_header(tmp_path):
    """A member inflating to 1 MiB over the real limit is refused without inflating it."""
    n = kml_mod.KMZ_MAX_MEMBER_BYTES + (1 << 20)
    path = tmp_path / "bomb.kmz"
    chunk = b" " * (1 << 20)
    with zipfile.ZipFile(path, "w", compression=zipfile.ZIP_DEFLATED, compresslevel=1) as zf:
        with zf.open("doc.kml", "w", force_zip64=True) as fh:
            for _ in range(n // len(chunk)):
                fh.write(chunk)
    assert path.stat().st_size < n // 100
    with pytest.raises(InputError, match="decompresses to more than"):
        read_kmz(path)


# ----------------------------------------------------------------------- real files


def _regex_paths(text: str) -> list[tuple[str, str, int]]:
    """(name, altitudeMode, number of tuples) of every Placemark holding a LineString."""
    out = []
    for block in re.findall(r"<Placemark\b.*?</Placemark>", text, flags=re.S):
        lines = re.findall(r"<LineString>(.*?)</LineString>", block, flags=re.S)
        for line in lines:
            name = re.search(r"<name>(.*?)</name>", block, flags=re.S)
            mode = re.search(r"<altitudeMode>(.*?)</altitudeMode>", line)
            coords = re.search(r"<coordinates>(.*?)</coordinates>", line, flags=re.S)
            out.append(
                (
                    name.group(1).strip() if name else "",
                    mode.group(1) if mode else "",
                    len(coords.group(1).split()),
                )
            )
    return out


def test_real_sparkfun_picks_linestring_ignores_polygons():
    path = DATA / "a_sparkfun_rally_course_ge_pro.kml"
    text = path.read_text()
    expected = _regex_paths(text)
    assert len(expected) == 1 and expected[0][2] == 138  # the shared README says 138
    assert text.count("<Polygon>") == 19
    (p,) = read_kml(path)
    assert (p.name, p.kind, p.n_points) == ("path", "LineString", 138)
    first = re.search(r"<coordinates>\s*([^\s]+)", text).group(1).split(",")
    assert (p.lon_deg[0], p.lat_deg[0]) == (float(first[0]), float(first[1]))


def test_real_google_samples_all_paths():
    path = DATA / "c_google_kml_samples.kml"
    expected = _regex_paths(path.read_text())
    assert len(expected) == 6
    paths = read_kml(path)
    assert [(p.name, p.altitude_mode or "", p.n_points) for p in paths] == expected
    for p in paths:
        assert p.kind == "LineString"
        assert p.altitude_trusted is (p.altitude_mode == "absolute")
        if p.altitude_mode == "clampToGround":
            assert np.all(p.alt_m == 0.0)
        elif p.altitude_mode is None:  # default mode: heights kept as written (0 in this file)
            assert np.all(p.alt_m == 0.0) and any("kept as written" in n for n in p.notes)
        else:
            assert np.all(p.alt_m > 0.0)


def test_real_limassol_newline_coords():
    path = DATA / "c_limassol_tour_newline_coords.kml"
    text = path.read_text()
    assert "\r\n" in path.read_bytes().decode()
    expected = _regex_paths(text)
    assert len(expected) == 1 and expected[0][2] == 1812
    (p,) = read_kml(path)
    assert (p.name, p.n_points) == (expected[0][0], 1812)
    last = re.findall(r"([-\d.]+),([-\d.]+),([-\d.]+)\s*</coordinates>", text)[-1]
    assert (p.lon_deg[-1], p.lat_deg[-1]) == (float(last[0]), float(last[1]))


def _regex_track(text: str, coord_tag: str) -> tuple[list[float], int]:
    body = re.search(r"<(?:gx:)?Track>(.*?)</(?:gx:)?Track>", text, flags=re.S).group(1)
    times = [utc(t) for t in re.findall(r"<when>(.*?)</when>", body)]
    n_coords = len(re.findall(rf"<{coord_tag}>", body))
    return times, n_coords


def test_real_kml23_track(shared_file):
    path = shared_file("b_kml23_track_no_gx_prefix.kml")
    times, n = _regex_track(path.read_text(), "coord")
    assert n == len(times) == 7
    (p,) = read_kml(path)
    assert (p.kind, p.n_points) == ("Track", 7)
    np.testing.assert_array_equal(p.time_unix_s, times)


def test_real_mapfinity_gx_track(shared_file):
    path = shared_file("b_mapfinity_hike_austin_gxtrack.kml")
    times, n = _regex_track(path.read_text(), "gx:coord")
    assert n == len(times) == 451
    (p,) = read_kml(path)  # the two TimeStamp-only Placemarks are not paths
    assert (p.name, p.kind, p.n_points) == ("Track", "Track", 451)
    assert p.altitude_mode == "absolute" and p.altitude_trusted
    np.testing.assert_array_equal(p.time_unix_s, times)
    assert p.time_unix_s[-1] - p.time_unix_s[0] == times[-1] - times[0]


def test_real_pacific_route(shared_file):
    path = shared_file("f_pacific_route_antimeridian.kml")
    (p,) = read_kml(path)
    assert (p.name, p.n_points) == ("Path", 4)
    np.testing.assert_array_equal(p.lon_deg, [140.615728, 166.492918, -157.876012, -127.622914])
    assert not p.altitude_trusted


# ----------------------------------------------------------------- shipped example


def test_example_route_resource():
    path = REPO / "resources" / "example_route.kml"
    (p,) = read_kml(path)
    assert p.kind == "LineString"
    assert p.altitude_mode == "absolute" and p.altitude_trusted
    # Independent great-circle distances (spherical Earth, good to 0.5 %).
    lat, lon = np.radians(p.lat_deg), np.radians(p.lon_deg)
    h = (
        np.sin(np.diff(lat) / 2) ** 2
        + np.cos(lat[:-1]) * np.cos(lat[1:]) * np.sin(np.diff(lon) / 2) ** 2
    )
    ds = 2 * 6371000.0 * np.arcsin(np.sqrt(h))
    assert 3000.0 < ds.sum() < 5000.0
    assert ds.max() < 31.0 and ds.min() > 1.0
    assert np.all(np.abs(np.diff(p.alt_m)) / ds <= 0.08)
    assert 450.0 <= p.alt_m.min() and p.alt_m.max() <= 500.0
    assert 30.0 <= np.ptp(p.alt_m) <= 40.0
    assert abs(p.lat_deg.mean() - 31.63) < 0.05 and abs(p.lon_deg.mean() + 7.99) < 0.05


def test_2d_tuples_among_3d_are_missing_heights_not_0m(tmp_path):
    """Issue 27 (a phone's mountain run): 2-D tuples among 3-D ones are missing heights,
    interpolated by ingestion, never 0 m; a path of 2-D tuples only stays at 0 m, untrusted."""
    from imugen.ingest.readers import read_route_file
    from imugen.ingest.stage import ingest

    f = tmp_path / "run.kml"
    f.write_text(
        "<kml><Placemark><name>run</name><LineString><altitudeMode>absolute</altitudeMode>"
        "<coordinates>7.0,46.0,800 7.0001,46.0,801 7.0002,46.0 7.0003,46.0 7.0004,46.0,803 "
        "7.0005,46.0,804</coordinates></LineString></Placemark></kml>"
    )
    (p,) = read_route_file(f)
    np.testing.assert_array_equal(p.alt_missing, [False, False, True, True, False, False])
    alt = ingest(f, dt=1.0, vehicle="pedestrian").table["alt_m"].to_numpy()
    np.testing.assert_allclose(alt, [800, 801, 801 + 2 / 3, 801 + 4 / 3, 803, 804])
    f.write_text(f.read_text().replace(",800", "").replace(",801", "").replace(",803", "")
                 .replace(",804", ""))  # fmt: skip
    (p,) = read_route_file(f)
    assert p.alt_missing is None and not p.altitude_trusted and np.all(p.alt_m == 0)
