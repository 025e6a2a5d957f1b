"""6-DoF pose trajectories: TUM, EuRoC ground truth, CSV with named pose columns, ROS 2 bags.

Every reader returns one candidate path of kind ``pose``: positions ``enu_m`` (m) in the
file's own world frame and the attitude ``attitude`` (quaternions, scalar first, pose body ->
world) with ``attitude_frame = "world"``; :mod:`imugen.ingest.stage` puts the world on the
Earth (``--pose-world``, ``--origin``). Times are seconds (POSIX when they look like dates,
else relative).

TUM
    ``t x y z qx qy qz qw`` per line (scalar **last**), ``#`` comments, spaces or commas.
EuRoC ground truth (``state_groundtruth_estimate0/data.csv``, ``mav0/.../data.csv``)
    ``#timestamp`` [ns], ``p_RS_R_{x,y,z}`` [m], ``q_RS_{w,x,y,z}`` (scalar **first**), then
    velocity and biases (ignored).
CSV with named pose columns
    A header naming a time (``t``, ``time``, ``time_s``, ``timestamp``, ``stamp``; a ``_ns``,
    ``_us``, ``_ms`` suffix or ``[ns]`` gives its unit), a position (``x y z``, ``px py pz``,
    ``p_x ..``, ``pos_x ..``, ``tx ty tz``, ``position_x ..``) and a quaternion (``qw qx qy
    qz``, ``q_w ..``, ``quat_w ..``, ``orientation_w ..``), in any order.
ROS 2 bag (its folder, its ``metadata.yaml``, or the sqlite3 ``.db3`` / ``.mcap`` file in it)
    Every topic of ``geometry_msgs/msg/PoseStamped``, ``PoseWithCovarianceStamped``,
    ``nav_msgs/msg/Odometry`` or ``TransformStamped`` is a candidate named by its topic
    (``--path=/ground_truth/odom`` chooses one); header stamps (read with ``rosbags``).
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from imugen.core.errors import InputError
from imugen.ingest import limits
from imugen.ingest.route import RoutePath, parse_number

_SPLIT = re.compile(r"[\s,]+")
_TIME = tuple(
    f"{n}{u}" for n in ("t", "time", "timestamp", "stamp") for u in ("", "_s", "_ms", "_us", "_ns")
)
_POS = (
    ("x", "y", "z"),
    ("px", "py", "pz"),
    ("p_x", "p_y", "p_z"),
    ("pos_x", "pos_y", "pos_z"),
    ("tx", "ty", "tz"),
    ("position_x", "position_y", "position_z"),
    ("x_m", "y_m", "z_m"),
)
_QUAT = (
    ("qw", "qx", "qy", "qz"),
    ("q_w", "q_x", "q_y", "q_z"),
    ("quat_w", "quat_x", "quat_y", "quat_z"),
    ("orientation_w", "orientation_x", "orientation_y", "orientation_z"),
)
_EUROC = ("p_rs_r_x", "p_rs_r_y", "p_rs_r_z", "q_rs_w", "q_rs_x", "q_rs_y", "q_rs_z")
POSIX_AFTER_S = 3.0e8
"""Times above this many seconds (1979) are POSIX dates, below relative seconds."""
BAG_KINDS = (
    "geometry_msgs/msg/PoseStamped",
    "geometry_msgs/msg/PoseWithCovarianceStamped",
    "nav_msgs/msg/Odometry",
    "geometry_msgs/msg/TransformStamped",
)
"""Message types a bag's pose topic may have."""


def _name(field: str) -> str:
    """Lower-case column name without ``#``, quotes and a bracketed unit."""
    n = field.strip().strip('"').lstrip("#").strip().lower()
    return re.sub(r"\s*[\[(].*$", "", n)


def _header(head: bytes) -> list[str] | None:
    """Column names of the first non-empty line when it is a CSV header, else None."""
    try:
        text = head.decode("utf-8-sig", errors="strict")
    except UnicodeDecodeError:
        return None
    for line in text.splitlines():
        s = line.strip()
        if not s:
            continue
        if s.startswith("# imugen:"):
            return None  # written by imugen ingest: the text reader's
        if "," not in s:
            return None  # a comment (TUM's "# timestamp tx ty ...") or a row: no CSV header
        return [_name(f) for f in s.split(",")]
    return None


def _group(names: list[str], groups) -> list[int] | None:
    for g in groups:
        if all(c in names for c in g):
            return [names.index(c) for c in g]
    return None


def claims(head: bytes) -> str | None:
    """The pose format of a file's first bytes: ``"euroc"``, ``"csv"``, ``"tum"`` or None."""
    names = _header(head)
    if names:
        if all(c in names for c in _EUROC):
            return "euroc"
        if _group(names, _POS) and _group(names, _QUAT) and any(n in names for n in _TIME):
            return "csv"
        return None
    try:
        text = head.decode("utf-8-sig", errors="replace")
    except UnicodeDecodeError:  # pragma: no cover - errors="replace"
        return None
    lines = [ln.split("#", 1)[0].strip() for ln in text.splitlines()[:-1]]
    lines = [ln for ln in lines if ln]
    if lines and all(len([t for t in _SPLIT.split(ln) if t]) == 8 for ln in lines[:5]):
        return "tum"
    return None


def _decode(data: bytes, path: Path) -> str:
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise InputError(path, f"is not UTF-8 text (byte offset {exc.start})") from None


def _numbers(rows, path: Path, ncol: int | None = None) -> np.ndarray:
    out = []
    for lineno, toks in rows:
        if ncol is not None and len(toks) != ncol:
            raise InputError(path, f"line {lineno}: {len(toks)} fields where {ncol} are expected")
        try:
            out.append([parse_number(t) for t in toks])
        except ValueError as exc:
            raise InputError(path, f"line {lineno}: {exc}") from None
        if len(out) > limits.current().points:
            limits.check(path, "points", len(out), f"line {lineno}")
    if not out:
        raise InputError(path, "has no pose rows")
    return np.asarray(out, float)


def _path(path: Path, fmt: str, t, p, q, notes=(), time_scale=1.0, t0=None) -> RoutePath:
    """A pose candidate; ``t`` relative to ``t0`` when given (integer clocks keep precision)."""
    t = np.asarray(t, float) * time_scale
    absolute = False
    if t0 is not None:
        start = float(t0) * time_scale
        absolute = start > POSIX_AFTER_S
        t = t + (start if absolute else 0.0)
    elif len(t) and np.nanmin(t) > POSIX_AFTER_S:
        absolute = True
    return RoutePath(
        name=path.stem,
        kind="pose",
        lat_deg=np.empty(0),
        lon_deg=np.empty(0),
        alt_m=np.empty(0),
        enu_m=np.asarray(p, float),
        time_unix_s=t,
        time_is_absolute=absolute,
        notes=[f"{fmt} pose trajectory", *notes],
        attitude=np.asarray(q, float),
        attitude_frame="world",
    )


def read_tum(path: str | Path, data: bytes) -> list[RoutePath]:
    """TUM trajectory (``t x y z qx qy qz qw``)."""
    path = Path(path)
    rows = []
    for lineno, line in enumerate(_decode(data, path).splitlines(), 1):
        s = line.split("#", 1)[0].strip()
        if s:
            rows.append((lineno, [t for t in _SPLIT.split(s) if t]))
    a = _numbers(rows, path, 8)
    return [_path(path, "TUM", a[:, 0], a[:, 1:4], a[:, [7, 4, 5, 6]])]


def _csv_rows(data: bytes, path: Path):
    """Header names and the numeric text fields of a CSV (``#`` header allowed)."""
    lines = [(i, ln.strip()) for i, ln in enumerate(_decode(data, path).splitlines(), 1)]
    lines = [(i, s) for i, s in lines if s]
    if not lines:
        raise InputError(path, "is empty")
    names = [_name(f) for f in lines[0][1].split(",")]
    rows = [(i, [f.strip() for f in s.split(",")]) for i, s in lines[1:] if not s.startswith("#")]
    return names, rows


def _raw_header(data: bytes, path: Path) -> list[str]:
    """Header fields as written (case and units kept)."""
    first = next(ln for ln in _decode(data, path).splitlines() if ln.strip())
    return first.split(",")


def _integer_clock(rows, j: int, path: Path) -> tuple[np.ndarray, int] | None:
    """Integer times of column ``j`` relative to the first (exact), or None if not integers."""
    try:
        ticks = [int(toks[j]) for _, toks in rows]
    except (ValueError, IndexError):
        return None
    return np.asarray([k - ticks[0] for k in ticks], float), ticks[0]


def read_euroc(path: str | Path, data: bytes) -> list[RoutePath]:
    """EuRoC ground-truth CSV (``#timestamp`` ns, ``p_RS_R_*``, ``q_RS_*`` scalar first)."""
    path = Path(path)
    names, rows = _csv_rows(data, path)
    a = _numbers(rows, path, len(names))
    cols = [names.index(c) for c in _EUROC]
    clock = _integer_clock(rows, 0, path)
    if clock is None:
        return [_path(path, "EuRoC", a[:, 0], a[:, cols[:3]], a[:, cols[3:]], time_scale=1e-9)]
    rel, t0 = clock
    return [_path(path, "EuRoC", rel, a[:, cols[:3]], a[:, cols[3:]], time_scale=1e-9, t0=t0)]


def read_pose_csv(path: str | Path, data: bytes) -> list[RoutePath]:
    """CSV with named time, position and quaternion columns."""
    path = Path(path)
    names, rows = _csv_rows(data, path)
    a = _numbers(rows, path, len(names))
    it = next(names.index(n) for n in _TIME if n in names)
    ip, iq = _group(names, _POS), _group(names, _QUAT)
    raw_name = _raw_header(data, path)[it].lower()
    unit = next((u for u in ("ns", "us", "ms") if f"_{u}" in raw_name or f"[{u}]" in raw_name), "s")
    scale = {"s": 1.0, "ms": 1e-3, "us": 1e-6, "ns": 1e-9}[unit]
    note = f"time column {names[it]!r} in {unit}"
    clock = _integer_clock(rows, it, path) if unit != "s" else None
    if clock is None:
        return [_path(path, "CSV", a[:, it], a[:, ip], a[:, iq], [note], time_scale=scale)]
    rel, t0 = clock
    return [_path(path, "CSV", rel, a[:, ip], a[:, iq], [note], time_scale=scale, t0=t0)]


def is_bag(path: Path, head: bytes) -> bool:
    """A ROS 2 bag's storage file (sqlite3 ``.db3``, ``.mcap``) or its ``metadata.yaml``."""
    suffix = path.suffix.lower()
    if path.name == "metadata.yaml" and b"rosbag2_bagfile_information" in head:
        return True
    return suffix in (".db3", ".mcap") or head.startswith(b"\x89MCAP")


def read_ros2_bag(path: str | Path) -> list[RoutePath]:
    """The poses of each of a ROS 2 bag's pose topics (module docstring)."""
    path = Path(path)
    folder = path.parent
    try:
        from rosbags.highlevel import AnyReader
        from rosbags.typesys import Stores, get_typestore
    except ImportError:  # pragma: no cover - rosbags is a dependency
        raise InputError(path, "reading ROS 2 bags needs the rosbags package") from None
    per_topic: dict[str, tuple[list, list, list]] = {}
    try:
        with AnyReader([folder], default_typestore=get_typestore(Stores.ROS2_HUMBLE)) as rd:
            cons = [c for c in rd.connections if c.msgtype in BAG_KINDS]
            if not cons:
                raise InputError(path, f"the bag has no pose topic ({', '.join(BAG_KINDS)})")
            count = 0
            for con, _t, raw in rd.messages(connections=cons):
                m = rd.deserialize(raw, con.msgtype)
                if con.msgtype.endswith("TransformStamped"):
                    tr, r = m.transform.translation, m.transform.rotation
                else:
                    pose = m.pose.pose if hasattr(m.pose, "pose") else m.pose
                    tr, r = pose.position, pose.orientation
                ns, pos, quat = per_topic.setdefault(con.topic, ([], [], []))
                ns.append(m.header.stamp.sec * 1_000_000_000 + m.header.stamp.nanosec)
                pos.append((tr.x, tr.y, tr.z))
                quat.append((r.w, r.x, r.y, r.z))
                count += 1
                if count > limits.current().points:
                    limits.check(path, "points", count, f"topic {con.topic}")
    except InputError:
        raise
    except Exception as exc:  # rosbags raises its own errors for broken bags
        msg = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise InputError(
            path, f"is not a readable ROS 2 bag ({limits.shorten(msg, 120)})"
        ) from None
    out = []
    for topic, (ns, pos, quat) in sorted(per_topic.items()):
        ticks = np.asarray(ns, np.int64)
        c = _path(path, "ROS 2 bag", ticks - ticks[0], pos, quat, [f"topic {topic}"], 1e-9,
                  int(ticks[0]))  # fmt: skip
        c.name = topic
        out.append(c)
    if not out:
        raise InputError(path, "the bag's pose topics hold no messages")
    return out
