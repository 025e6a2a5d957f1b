"""GeoJSON reader: LineString, MultiLineString, Feature(Collection), coordTimes."""

from __future__ import annotations

import json
from datetime import UTC, datetime

import numpy as np
import pytest

from imugen.core.errors import InputError
from imugen.ingest.readers import read_route_file
from imugen.ingest.stage import ingest


def _w(tmp_path, obj, name="t.geojson"):
    p = tmp_path / name
    p.write_text(json.dumps(obj) if not isinstance(obj, str) else obj)
    return p


def test_real_segmented_tracks(shared_file):
    path = shared_file("g_segmented_tracks.geojson")
    doc = json.loads(path.read_text())
    cands = read_route_file(path)
    assert [(p.name, p.n_points) for p in cands] == [
        (f["properties"]["name"], len(f["geometry"]["coordinates"])) for f in doc["features"]
    ]
    for p, f in zip(cands, doc["features"], strict=True):
        c = np.array(f["geometry"]["coordinates"])
        np.testing.assert_array_equal(p.lon_deg, c[:, 0])
        np.testing.assert_array_equal(p.lat_deg, c[:, 1])
        assert not p.altitude_trusted and np.all(p.alt_m == 0)
    assert ingest(path, path="With Times").meta["points_out"] == 23


def test_collections_multilines_times_and_heights(tmp_path):
    t = [datetime(2024, 5, 1, 10, 0, s, tzinfo=UTC) for s in range(3)]
    iso = [x.isoformat() for x in t]
    doc = {
        "type": "FeatureCollection",
        "features": [
            {
                "type": "Feature",
                "properties": {},
                "geometry": {"type": "Point", "coordinates": [1, 2]},
            },
            {
                "type": "Feature",
                "properties": {"name": "ride", "coordTimes": iso},
                "geometry": {
                    "type": "LineString",
                    "coordinates": [[7.0, 46.0, 500], [7.001, 46.0], [7.002, 46.0, 510]],
                },
            },
            {
                "type": "Feature",
                "properties": None,
                "geometry": {
                    "type": "GeometryCollection",
                    "geometries": [
                        {
                            "type": "MultiLineString",
                            "coordinates": [
                                [[7, 46], [7, 46.01]],
                                [[8, 46], [8, 46.01], [8, 46.02]],
                            ],
                        }
                    ],
                },
            },
        ],
    }
    cands = read_route_file(_w(tmp_path, doc))
    assert [(p.name, p.n_points) for p in cands] == [
        ("ride", 3),
        ("feature 3 [1]", 2),
        ("feature 3 [2]", 3),
    ]
    ride = cands[0]
    np.testing.assert_array_equal(ride.time_unix_s, [x.timestamp() for x in t])
    np.testing.assert_array_equal(ride.alt_missing, [False, True, False])
    assert ride.altitude_trusted and cands[1].time_unix_s is None


@pytest.mark.parametrize(
    "text, message",
    [
        ("{not json", "not valid GeoJSON"),
        ('{"type": "Point", "coordinates": [1, 2]}', "no LineString"),
        ('{"type": "LineString", "coordinates": [[1, true]]}', "position 1 .* is not"),
        ('{"type": "LineString", "coordinates": 5}', "not an array"),
        ('{"type": "GeometryCollection", "geometries": [' * 3000 + "]}" * 3000, "GeoJSON"),
    ],
)
def test_refusals(tmp_path, text, message):
    with pytest.raises(InputError, match=message):
        read_route_file(_w(tmp_path, text))
