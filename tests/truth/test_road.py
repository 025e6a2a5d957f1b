"""The road profile of timed ground routes (:mod:`imugen.truth.road`): the truth's vertical is
the height profile against distance, exact at stops, in flat and ellipsoidal heights."""

from __future__ import annotations

import math

import numpy as np

from imugen import truth
from imugen.core import earth as ea
from imugen.core import rotations as rot
from imugen.tables import truth as col

ORIGIN = (45.0, 7.0, 300.0)


def _body_velocity(tr):
    q = tr[list(col.QUAT)].to_numpy()
    return np.einsum("kji,kj->ki", rot.quat_to_dcm(q), tr[list(col.VEL)].to_numpy())


def test_a_smooth_hill_is_kept_and_followed_exactly():
    """Noise-free hills of 600 m wavelength, 8 m high (grade <= 4.2 %), at 12 m/s: the profile
    smooths over the car's 50 m, so the truth keeps the hills (to 2 % of their height; the grade to 3 %), its
    velocity's pitch is the grade (no body vertical velocity) and the pitch is the hills'."""
    t = np.arange(0.0, 301.0, 1.0)
    x = 12.0 * t
    h = 4.0 * np.sin(2.0 * math.pi * x / 600.0)
    df, meta = truth.enu_table(np.column_stack([x, 0.0 * x, h]), t, ORIGIN)
    tr, meta = truth.build_truth(df, meta, rate_hz=50, earth="flat", verbose=False)
    tt = tr[col.TIME].to_numpy()
    u = tr[col.POS[2]].to_numpy()
    inner = (tt > 30.0) & (tt < 270.0)
    h_true = 4.0 * np.sin(2.0 * math.pi * 12.0 * tt / 600.0)
    assert np.abs(u - h_true)[inner].max() < 0.02 * 8.0
    assert np.abs(_body_velocity(tr)[:, 2]).max() < 1e-6
    grade = np.arctan(4.0 * 2.0 * math.pi / 600.0 * np.cos(2.0 * math.pi * 12.0 * tt / 600.0))
    assert np.abs(tr["pitch_rad"].to_numpy() - grade)[inner].max() < 0.03 * 0.042
    assert meta["fit"]["vertical"]["max_departure_m"] < 1e-3


def _height_step_stop(suspension):
    rng = np.random.default_rng(11)
    t = np.arange(0.0, 241.0, 1.0)
    s = np.where(t < 90.0, 8.0 * t, np.where(t < 150.0, 720.0, 720.0 + 8.0 * (t - 150.0)))
    h = np.where(t < 120.0, 0.0, 3.0) + rng.normal(scale=0.5, size=t.size)
    y = np.column_stack([s, 0.01 * s, h]) + rng.normal(scale=0.3, size=(t.size, 3)) * [1, 1, 0]
    df, meta = truth.enu_table(y, t, ORIGIN)
    return truth.build_truth(
        df, meta, rate_hz=20, earth="flat", verbose=False, vehicle_params={"suspension": suspension}
    )


def test_a_stop_with_a_height_step_stays_put():
    """GNSS heights step while the car waits (3 m over a 60 s stop, noise 0.5 m): the stop is
    still exactly still, vertically too, and the step becomes a slope spread over the road.
    The road profile is the subject: a rigid car (its attitude the path's); then the same
    car on its suspension (damped), whose body only pitches on top of that profile."""
    tr, meta = _height_step_stop("rigid")
    stops = meta["fit"]["stops"]
    assert stops, "the stop is found"
    tt = tr[col.TIME].to_numpy()
    p = tr[list(col.POS)].to_numpy()
    for a, b in stops:
        still = (tt >= a) & (tt <= b)
        assert np.ptp(p[still], axis=0).max() < 1e-9  # rounding of the spline sums
    # near a stop (the velocity's direction undefined) the pitch blends into the profile's
    # grade, which the velocity follows only nearly: millimetres per second there
    vb = _body_velocity(tr)
    away = np.all([np.abs(tt - a) > 3.0 for a in np.ravel(stops)], axis=0)
    assert np.abs(vb[away, 2]).max() < 1e-6
    assert np.abs(vb[:, 2]).max() < 0.005
    pitch = tr["pitch_rad"].to_numpy()
    assert np.abs(pitch).max() < math.radians(3.0)
    # on the suspension: the same positions (a rotation of the body only), the body turned
    # from the rigid one by R_s = Rx(phi_s) Ry(-theta_s) (roll then pitch on the suspension),
    # so the body velocity is the rigid one turned by R_s: theta_s the dive braking into the
    # stop and the squat leaving it (gradient x dv/dt, 2 m/s^2 from 8 m/s in 1 s), phi_s
    # nearly nothing on a nearly straight road
    td, md = _height_step_stop("damped")
    assert md["fit"]["stops"] == stops
    assert np.abs(td[list(col.POS)].to_numpy() - p).max() < 1e-9
    C_r = rot.quat_to_dcm(tr[list(col.QUAT)].to_numpy())
    R_s = np.einsum("kji,kjl->kil", C_r, rot.quat_to_dcm(td[list(col.QUAT)].to_numpy()))
    assert np.abs(R_s[:, 0, 1]).max() < 1e-9
    theta_s = np.arctan2(-R_s[:, 0, 2], R_s[:, 0, 0])
    phi_s = np.arctan2(R_s[:, 2, 1], R_s[:, 1, 1])
    vp = truth.VEHICLES["car"]
    assert np.abs(theta_s).max() > 0.5 * vp.pitch_gradient_radpmps2 * 2.0
    assert np.abs(theta_s).max() < 1.3 * vp.pitch_gradient_radpmps2 * vp.max_accel_mps2
    assert np.abs(phi_s).max() < 0.1 * np.abs(theta_s).max()
    np.testing.assert_allclose(
        _body_velocity(td), np.einsum("kji,kj->ki", R_s, vb), rtol=0, atol=1e-9
    )
    for a, b in stops:  # the body settles within 10 s of stopping, then stays put
        still = (tt >= a + 10.0) & (tt <= b)
        assert np.ptp(td[list(col.QUAT)].to_numpy()[still], axis=0).max() < 1e-9


def test_ellipsoidal_heights_far_from_the_origin():
    """A 25 km road east in ``wgs84`` over rolling hills of ellipsoidal height (n's Up drops
    49 m below the heights there): the truth's ellipsoidal height is the profile's to 1 cm
    and keeps within 2 % of the hills' height of the input heights."""
    lat0, lon0, h0 = ORIGIN
    frame = ea.OriginFrame.from_deg(lat0, lon0, h0, "wgs84")
    t = np.arange(0.0, 1001.0, 1.0)
    x = 25.0 * t
    lon = math.radians(lon0) + x / (ea.A_WGS84 * math.cos(math.radians(lat0)))
    hh = h0 + 5.0 * np.sin(2.0 * math.pi * x / 2000.0)
    y = frame.n_from_geodetic(np.full_like(x, math.radians(lat0)), lon, hh)
    df, meta = truth.enu_table(y, t, ORIGIN)
    tr, meta = truth.build_truth(df, meta, rate_hz=10, earth="wgs84", verbose=False)
    assert meta["earth"] == "wgs84"
    assert meta["fit"]["vertical"]["max_departure_m"] < 0.01
    tt = tr[col.TIME].to_numpy()
    h_truth = frame.geodetic_from_n(tr[list(col.POS)].to_numpy())[2]
    inner = (tt > 30.0) & (tt < 970.0)
    assert np.abs(h_truth - np.interp(tt, t, hh))[inner].max() < 0.02 * 10.0
