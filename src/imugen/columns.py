"""Column names of the tables written by imugen (one place; every stage imports them).

ENU table (``imugen ingest``): one row per kept input point.
Truth table (``imugen truth``): one row per IMU sample, float64; see :data:`TRUTH_COLUMNS`.
Increment columns (``dtheta_*``, ``dv_*``) on row ``k`` belong to the interval
``[t_{k-1}, t_k]`` ending at that row; row 0 holds zeros.
"""

from __future__ import annotations

#: key of the JSON metadata in the Parquet schema metadata
METADATA_KEY = b"imugen"

# --- ENU table (ingestion) --------------------------------------------------------------
TIME = "time_s"
LAT = "lat_deg"
LON = "lon_deg"
ALT = "alt_m"
E = "e_m"
N = "n_m"
U = "u_m"
ENU = (E, N, U)

# --- truth table ------------------------------------------------------------------------
#: position p_n, metres (ENU of the route origin)
POS = (E, N, U)
#: velocity v_n relative to the Earth, m/s
VEL = ("v_e_mps", "v_n_mps", "v_u_mps")
#: attitude C_nb as a quaternion, scalar first
QUAT = ("q_w", "q_x", "q_y", "q_z")
#: roll, pitch, yaw of the body relative to the local level at the vehicle (unwrapped),
#: C_lb = Rz(yaw) Ry(-pitch) Rx(roll); yaw 0 faces East, +pi/2 faces North; pitch > 0 nose
#: up; roll > 0 right wing down (see :mod:`imugen.rotations`)
EULER = ("roll_rad", "pitch_rad", "yaw_rad")
#: angular rate omega_ib_b, rad/s (instantaneous, at the sample time)
GYRO = ("gyro_x_radps", "gyro_y_radps", "gyro_z_radps")
#: specific force f_b, m/s^2 (instantaneous, at the sample time)
ACCEL = ("accel_x_mps2", "accel_y_mps2", "accel_z_mps2")
#: exact angle increment of the interval ending at the row, rad
DTHETA = ("dtheta_x_rad", "dtheta_y_rad", "dtheta_z_rad")
#: exact (sculling-compensated) velocity increment of the interval ending at the row, m/s
DV = ("dv_x_mps", "dv_y_mps", "dv_z_mps")

TRUTH_COLUMNS = (TIME, *POS, *VEL, *QUAT, *EULER, *GYRO, *ACCEL, *DTHETA, *DV)

UNITS = {
    TIME: "s",
    **dict.fromkeys(POS, "m"),
    **dict.fromkeys(VEL, "m/s"),
    **dict.fromkeys(QUAT, "1"),
    **dict.fromkeys(EULER, "rad"),
    **dict.fromkeys(GYRO, "rad/s"),
    **dict.fromkeys(ACCEL, "m/s^2"),
    **dict.fromkeys(DTHETA, "rad"),
    **dict.fromkeys(DV, "m/s"),
}
