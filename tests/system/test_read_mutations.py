"""Byte mutations of every new format end in a result or one InputError, never a traceback."""

from __future__ import annotations

import json
import random

import pytest

from imugen.core.errors import InputError
from imugen.ingest.stage import ingest

SEEDS = {
    "log.nmea": (
        b"$GPRMC,222507.00,A,4249.96542,S,14726.73195,E,0.013,,231019,,,A*6F\r\n"
        b"$GPGGA,222507.00,4249.96542,S,14726.73195,E,1,09,0.96,30.0,M,-8.8,M,,*61\r\n"
        b"$GPRMC,222508,A,4249.96545,S,14726.73187,E,0.027,,231019,,,A*4D\r\n"
        b"$GPGGA,222508,4249.96545,S,14726.73187,E,1,09,0.96,30.0,M,-8.8,M,,*44\r\n"
        b"$GPGGA,222509.,4249.96546,S,14726.73184,E,1,08,0.96,30.0,M,-8.8,M,,*6A\r\n"
    ),
    "f.igc": (
        b"AXXX001\r\nHFDTE160722\r\n"
        b"B1941314350420N08026585WA004380046300712000018009\r\n"
        b"B1942164350396N08026557WA004380046300712046999009\r\n"
        b"B1942224350352N08026500WA004390046300712076390008\r\n"
    ),
    "t.geojson": json.dumps(
        {
            "type": "FeatureCollection",
            "features": [
                {
                    "type": "Feature",
                    "properties": {"name": "a", "coordTimes": ["2024-01-01T00:00:00Z"] * 3},
                    "geometry": {
                        "type": "MultiLineString",
                        "coordinates": [[[7, 46, 5], [7, 46.01]], [[8, 46], [8, 46.001, 3]]],
                    },
                }
            ],
        }
    ).encode(),
    "ros.csv": (
        b"%time,field.header.stamp,field.status.status,field.latitude,field.longitude,"
        b"field.altitude\n1,1700000000000000000,0,30.2,-97.6,150\n"
        b"2,1700000001000000000,0,30.2001,-97.6,nan\n3,1700000002000000000,-1,30.2002,-97.6,1\n"
    ),
    "hemi.csv": b"time,lat,lon,alt\n2024-01-01T00:00:00Z,30.2N,097.6W,1\n1704067201,30.2001N,W097.6,\n",
    "nul.csv": b"lat\x00\x00,lon\x00\x00,t\x00\n30.2\x00\x00,40\x00\x00,0\x00\n30.21\x00,40\x00,9\x00\n",
}
INSERTS = [
    b"9" * 300,
    b",",
    b"-",
    b".",
    b"\x00",
    b"N",
    b"W",
    b"[",
    b"{",
    b'"',
    b"e999",
    b"nan",
    b"*",
]


def _mutate(data: bytes, rng: random.Random) -> bytes:
    b = bytearray(data)
    for _ in range(rng.randint(1, 6)):
        i = rng.randrange(len(b)) if b else 0
        op = rng.random()
        if op < 0.4 and b:
            b[i] = rng.randrange(256)
        elif op < 0.7:
            b[i:i] = rng.choice(INSERTS)
        else:
            del b[i : i + rng.randint(1, 20)]
    return bytes(b)


@pytest.mark.parametrize("name", sorted(SEEDS))
def test_mutations_refused_in_one_line(tmp_path, name):
    assert len(ingest(_write(tmp_path, name, SEEDS[name]), path=1).table) >= 2  # seed is valid
    rng = random.Random(name)
    for _ in range(60):
        f = _write(tmp_path, name, _mutate(SEEDS[name], rng))
        try:
            ingest(f, path=1)
        except InputError as exc:
            assert "\n" not in str(exc)


def _write(tmp_path, name, data):
    f = tmp_path / name
    f.write_bytes(data)
    return f
