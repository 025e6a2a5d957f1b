"""Formats read through GPSBabel: refusal without it, conversion with it (a stand-in or real)."""

from __future__ import annotations

import re
import shutil
import stat
import subprocess
import sys

import pytest

from imugen.core.errors import InputError
from imugen.ingest.readers import babel, read_route_file
from imugen.ingest.stage import ingest

GPX = (
    '<gpx version="1.1"><trk><name>ride</name><trkseg>'
    '<trkpt lat="46.0" lon="7.0"><ele>500</ele><time>2024-01-01T00:00:00Z</time></trkpt>'
    '<trkpt lat="46.001" lon="7.0"><ele>501</ele><time>2024-01-01T00:00:10Z</time></trkpt>'
    "</trkseg></trk></gpx>"
)


def _fake_gpsbabel(tmp_path, monkeypatch, body: str):
    """Put an executable `gpsbabel` (Python) first on the PATH."""
    bindir = tmp_path / "bin"
    bindir.mkdir()
    exe = bindir / "gpsbabel"
    exe.write_text(f"#!{sys.executable}\nimport sys, time\nargs = sys.argv[1:]\n{body}\n")
    exe.chmod(exe.stat().st_mode | stat.S_IEXEC)
    monkeypatch.setenv("PATH", str(bindir))
    return exe


def test_refused_without_gpsbabel(tmp_path, monkeypatch):
    f = tmp_path / "ride.fit"
    f.write_bytes(b"\x0e\x10\x00\x00.FIT" + bytes(64))
    monkeypatch.setenv("PATH", str(tmp_path))
    with pytest.raises(InputError, match=r"install GPSBabel.*gpsbabel -t -r -i garmin_fit"):
        read_route_file(f)


def test_converted_by_gpsbabel(tmp_path, monkeypatch):
    _fake_gpsbabel(
        tmp_path,
        monkeypatch,
        "assert args[args.index('-i') + 1] == 'garmin_fit' and args[args.index('-o') + 1] == 'gpx'\n"
        f"open(args[args.index('-F') + 1], 'w').write({GPX!r})",
    )
    f = tmp_path / "ride.FIT"
    f.write_bytes(b"\x0e\x10" + bytes(30))
    (p,) = read_route_file(f)
    assert (p.name, p.n_points, list(p.alt_m)) == ("ride", 2, [500.0, 501.0])
    assert p.notes[-1] == "converted from garmin_fit to GPX by GPSBabel"


def test_gpsbabel_failure_and_timeout(tmp_path, monkeypatch):
    _fake_gpsbabel(
        tmp_path,
        monkeypatch,
        "if 'slow' in args[args.index('-f') + 1]:\n    time.sleep(5)\n"
        "sys.stderr.write('fit: bad header\\n'); sys.exit(1)",
    )
    f = tmp_path / "x.fit"
    f.write_bytes(bytes(16))
    with pytest.raises(InputError, match="could not convert the file: fit: bad header"):
        read_route_file(f)
    monkeypatch.setattr(babel, "TIMEOUT_S", 0.5)
    s = tmp_path / "slow.tcx"
    s.write_text("<x/>")
    with pytest.raises(InputError, match=r"within 0\.5 s"):
        read_route_file(s)


@pytest.mark.skipif(shutil.which("gpsbabel") is None, reason="gpsbabel not installed")
def test_real_fit_file(shared_file, tmp_path):
    path = shared_file("g_bike_garmin_edge800.fit")
    gpx = tmp_path / "direct.gpx"
    cmd = ["gpsbabel", "-t", "-i", "garmin_fit", "-f", str(path), "-o", "gpx", "-F", str(gpx)]
    subprocess.run(cmd, check=True, capture_output=True, timeout=120)
    segs = re.findall(r"<trkseg>(.*?)</trkseg>", gpx.read_text(), re.S)
    cands = read_route_file(path)
    assert [p.n_points for p in cands] == [s.count("<trkpt") for s in segs]
    assert all(p.time_unix_s is not None for p in cands) and len(cands) > 1
    ing = ingest(path, path="longest", vehicle="bicycle")
    assert ing.meta["points_in"] == max(p.n_points for p in cands)  # here also the longest
