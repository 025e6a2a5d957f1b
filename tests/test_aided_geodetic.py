"""GNSS, scenarios, companions and the aided filter on ``geodetic`` truths (n = ECEF).

Oracles on stand-ins of long routes (windows of the analytic routes of
``test_truth_long``: a drive 250 km from its origin, an airliner crossing 180 deg):

* ideal increments and noiseless fixes stay on the truth (the filter's Earth model in ECEF
  is the mechanization's);
* the receiver's errors, rotated to the local level at the antenna, have the preset's
  horizontal and vertical sigmas (vertical not mixed into horizontal), and are correlated
  along the ECEF axes;
* Monte-Carlo NEES of position, velocity and attitude inside the chi-square bounds with
  realistic GNSS noise (horizontal and vertical sigmas differ, so a per-ECEF-axis update
  would not be consistent);
* the same drive expressed as a wgs84 truth near its origin and as a geodetic truth, with the
  same draws, gives the same aided errors in the local level;
* a spoofing offset lies along its azimuth in the local level; the barometer measures the
  ellipsoidal height.
"""

from __future__ import annotations

import importlib.util
import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from scipy.stats import chi2

from imugen import aided as A
from imugen import companions as CP
from imugen import earth as E
from imugen import gnss as G
from imugen import rotations as R
from imugen import scenarios as SC
from imugen import simulate as SIM
from imugen import truth
from imugen.tables import truth as col



def _sibling(name):
    """A sibling test module (the suite runs with ``--import-mode=importlib``)."""
    spec = importlib.util.spec_from_file_location(name, Path(__file__).with_name(f"{name}.py"))
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


TA = _sibling("test_aided")  # car scene, receivers and error helpers
TL = _sibling("test_truth_long")  # analytic long routes
SCENES, enu_input = TL.SCENES, TL.enu_input
LEVER, ORIGIN, errors, nees, quiet_receiver = TA.LEVER, TA.ORIGIN, TA.errors, TA.nees, TA.quiet_receiver
RATE = 100.0
SPAN = 60.0


def long_truth(name, t0, span=SPAN):
    """``span`` s from ``t0`` at 100 Hz of a stand-in of test_truth_long (geodetic)."""
    make, vehicle, _ = SCENES[name]
    enu, meta = enu_input(make(), t0 + np.arange(0.0, span + 1e-9, 1.0))
    df, tm = truth.build_truth(enu, meta, rate_hz=RATE, earth="auto", vehicle=vehicle,
                               verbose=False)  # fmt: skip
    assert tm["earth"] == "geodetic"
    return df, col.origin_frame(tm)


def arrays(df):
    return tuple(
        df[list(c)].to_numpy() if not isinstance(c, str) else df[c].to_numpy()
        for c in (col.TIME, col.POS, col.VEL, col.QUAT, col.GYRO)
    )


def increments(df):
    return (
        df[["dtheta_x_rad", "dtheta_y_rad", "dtheta_z_rad"]].to_numpy()[None],
        df[["dv_x_mps", "dv_y_mps", "dv_z_mps"]].to_numpy()[None],
    )


def local(frame, p_n, x_n):
    """Vectors ``x_n`` (..., J, 3) resolved in the local level at the positions ``p_n`` (J, 3)."""
    return np.einsum("jik,...jk->...ji", frame.C_ln(p_n), x_n)


@pytest.fixture(scope="module")
def road():
    return long_truth("road 264 km", 10_000.0)  # 250 km from the origin


@pytest.fixture(scope="module")
def airliner():
    return long_truth("airliner 7,600 km", 14_420.0)  # 3,580 km out, crossing 180 deg


@pytest.mark.parametrize("name", ["road", "airliner"])
def test_ideal_inputs_stay_on_truth(name, request):
    df, frame = request.getfixturevalue(name)
    t, p, v, q, w = arrays(df)
    if name == "airliner":
        lon = np.degrees(E.geodetic_from_ecef(p)[1])
        assert lon.max() > 179.0 and lon.min() < -179.0  # the window crosses 180 deg
    dth, dv = increments(df)
    Om = E.earth_rate_n(frame)
    gn = G.simulate_gnss(t, p, v, q, w, quiet_receiver(latency=0.1), lever_arm_b_m=LEVER,
                         omega_ie_n=Om, frame=frame)  # fmt: skip
    tun = A.Tuning.from_grade("industrial")
    opts = A.Options(gnss_bias=False)
    P0 = A.initial_covariance(tun, opts, 1e-3, 1e-3, 1e-5)
    init = A.initial_state(0, p[0], v[0], q[0], P0)
    free = replace(gn, fix=np.zeros_like(gn.fix))
    e0 = errors(A.run(dth, dv, 1 / RATE, frame, free, tun, opts, init), p, v, q)[0]
    print(name, "free", np.abs(e0[:, :3]).max(), np.abs(e0[:, 6:]).max())
    assert np.max(np.abs(e0[:, :3])) < 1e-4
    assert np.max(np.abs(e0[:, 6:])) < 1e-7
    gq = replace(gn, sigma_p_n=gn.sigma_p_n + 0.01, sigma_v_n=gn.sigma_v_n + 0.01)
    r1 = A.run(dth, dv, 1 / RATE, frame, gq, tun, opts, init)
    e1 = errors(r1, p, v, q)[0]
    print(name, "aided", [np.abs(e1[:, a : a + 3]).max() for a in (0, 3, 6)])
    assert np.max(np.abs(e1[:, :3])) < 5e-5
    assert np.max(np.abs(e1[:, 3:6])) < 5e-5
    assert np.max(np.abs(e1[:, 6:])) < 5e-6
    assert np.max(np.abs(r1.gyro_bias)) < 1e-7 and np.max(np.abs(r1.accel_bias)) < 1e-5
