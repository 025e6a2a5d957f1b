"""An untimed flight follows its input within the input's noise and never flies below the
input's heights (issue 27): the path is rounded at the input's own spacing and its turns are
bounded by the bank limit at the speed flown (:func:`imugen.truth.flight.flight_corner`),
not by a fixed 2 km; the heights are floored at the input's (:func:`imugen.truth.fit.floor_heights`)."""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from imugen import truth
from imugen.truth.fit import fit_path

AIRLINER = truth.VEHICLES["airliner"]
NOISE = (3.0, 6.0)  # horizontal, vertical [m]
NOISE_3D = float(np.sqrt(2 * NOISE[0] ** 2 + NOISE[1] ** 2))  # 7.3 m


def _logger_flight(seed=7, dt=5.0, ground=400.0):
    """A logger's untimed airliner flight (ENU, m): a taxi with a 60 m radius turn, the
    take-off roll, a climb at 10 m/s through a 15 km radius turn to 2,000 m above the
    runway, a 3 deg descent to the same elevation and the roll-out, a point every 5 s of the
    flight with 3 m horizontal and 6 m vertical noise."""
    dd = 1.0
    segs = [(400.0, 0.0), (0.5 * np.pi * 60.0, 1 / 60.0), (500.0, 0.0), (1600.0, 0.0),
            (3000.0, 0.0), (0.5 * np.pi * 15e3, -1 / 15e3), (60e3, 0.0)]  # fmt: skip
    kap = np.concatenate([np.full(int(length / dd), k) for length, k in segs])
    d = np.arange(len(kap) + 1) * dd
    psi = np.r_[0.0, np.cumsum(kap * dd)] + np.pi / 2
    x = np.r_[0.0, np.cumsum(np.cos(psi[:-1]) * dd)]
    y = np.r_[0.0, np.cumsum(np.sin(psi[:-1]) * dd)]
    taxi_end = 900.0 + 0.5 * np.pi * 60.0
    roll_end = taxi_end + 1600.0
    v = np.where(d < taxi_end, 8.0, np.sqrt(64.0 + 4.0 * np.maximum(d - taxi_end, 0.0)))
    v = np.where(d > roll_end, np.minimum(75.0 + 0.01 * (d - roll_end), 200.0), v)
    h = np.minimum(ground + np.cumsum(np.where(d > roll_end, 10.0 / v, 0.0) * dd), ground + 2e3)
    d_td = d[-1] - 1500.0
    tan3 = np.tan(np.radians(3.0))
    h = np.where(
        d > d_td - 2e3 / tan3, np.maximum(np.minimum(h, ground + tan3 * (d_td - d)), ground), h
    )
    v = np.where(d > d_td - 40e3, np.minimum(v, 70.0 + 0.004 * np.maximum(d_td - d, 0.0)), v)
    v = np.where(d > d_td, np.maximum(70.0 - 0.04 * (d - d_td), 8.0), v)
    t = np.r_[0.0, np.cumsum(dd / (0.5 * (v[1:] + v[:-1])))]
    ts = np.arange(0.0, t[-1], dt)
    P = np.column_stack([np.interp(ts, t, c) for c in (x, y, h)])
    rng = np.random.default_rng(seed)
    P[:, :2] += rng.normal(0.0, NOISE[0], (len(ts), 2))
    P[:, 2] += rng.normal(0.0, NOISE[1], len(ts))
    return P


def test_untimed_flight_follows_its_input_within_the_noise_and_above_its_heights():
    y = _logger_flight()
    df, meta = truth.enu_table(y, None, (46.5, 7.5, 0.0))
    tr, m = truth.build_truth(df, meta, rate_hz=10, vehicle="airliner", earth="flat", verbose=False)
    fit = m["fit"]
    assert m["gate"] == [], m["gate"]
    # within the noise (5.1 / 33 m measured); the fixed 2 km rounding was 64 / 341 m off
    assert fit["rms_distance_m"] <= NOISE_3D
    assert fit["max_distance_m"] <= 6.0 * NOISE_3D
    old = fit_path(y, AIRLINER, 2000.0)[2]
    assert old["rms_distance_m"] > 5.0 * fit["rms_distance_m"]
    # the turns are an airliner's: within the bank limit at the speed flown
    assert m["plausibility"]["warnings"] == []
    # never below the input's heights: every sample at or above the lowest of the input
    # points around its nearest one (the runway on the ground, the noise's lower edge aloft)
    P = tr[["e_m", "n_m", "u_m"]].to_numpy()
    _, k = cKDTree(y[:, :2]).query(P[:, :2])
    lowest = np.min([y[np.clip(k + j, 0, len(y) - 1), 2] for j in range(-2, 3)], axis=0)
    assert np.min(P[:, 2] - lowest) >= -0.5
    assert "height_floor" in fit
