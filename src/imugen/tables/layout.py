"""Where the workflow writes each file: the one map of ``results/``.

The workflow's rules take their output paths from here (with Snakemake wildcards such as
``{route}`` as the default arguments) and the loader (:mod:`imugen.dataset`) finds the files
with the same functions, so the two cannot drift apart::

    results/grades/{grade}.yaml                    custom grade (config ``grades``)
    results/{route}/route.csv                      ingest: geodetic table
    results/{route}/enu.parquet                    ingest: local ENU    (imugen.tables.enu)
    results/{route}/truth.parquet                  truth                (imugen.tables.truth)
    results/{route}/{kind}/{grade}/shard-{shard}.parquet
        kind imu: IMU shard (+ .labels.parquet)    simulate             (imugen.tables.shard)
        kind nav: navigation errors                simulate --navigate  (imugen.tables.nav)
        kind gnss: GNSS epochs (+ .labels, .intervals)        aid       (imugen.tables.gnss)
        kind aided: aided navigation errors and state         aid       (imugen.tables.aided)
        kind companions: odometer/barometer (+ .labels)       aid       (imugen.tables.companions)
        kind estimates: the filter's state and sigmas   aid (aided.estimates) (imugen.tables.filter_estimates)
    results/{route}/metrics/{grade}.parquet        evaluate             (imugen.tables.metrics)
    results/{route}/rmse.{csv,md,tex,html}         RMSE table of the route
    results/{route}/figures/{name}.{ext}           figures
    results/{route}/datasets/{grade}.mat           MATLAB export
    results/{route}/datasets/{grade}/              dataset exports (one folder per format)
    results/allan/{grade}/static.parquet           still IMU of the Allan check
    results/allan/{grade}/allan.{json,png}         Allan check

Paths are ``str`` with ``/`` separators relative to the working directory (what Snakemake
wants); ``root`` replaces ``results``.
"""

from __future__ import annotations

RESULTS = "results"
"""The folder every result lies under."""
SHARD_KINDS = ("imu", "nav", "gnss", "aided", "companions", "estimates")
"""Per-shard tables, one folder each under a route (``{route}/{kind}/{grade}/``)."""
LABELS_SUFFIX = ".labels.parquet"
"""A shard's labels sidecar: ``shard-000.parquet`` -> ``shard-000.labels.parquet``."""


def shard_label(index: int) -> str:
    """``000``, ``001``, ... ``999``, ``1000``: at least three digits and no other leading
    zeros, so adding shards never renames existing ones."""
    return f"{int(index):03d}"


def grade_file(grade="{grade}", root=RESULTS) -> str:
    """The YAML file of a custom grade (written from the config)."""
    return f"{root}/grades/{grade}.yaml"


def route_dir(route="{route}", root=RESULTS) -> str:
    """The folder of one route's results."""
    return f"{root}/{route}"


def route_csv(route="{route}", root=RESULTS) -> str:
    """The geodetic table of the first ingest step."""
    return f"{route_dir(route, root)}/route.csv"


def enu(route="{route}", root=RESULTS) -> str:
    """The route in local ENU (:mod:`imugen.tables.enu`)."""
    return f"{route_dir(route, root)}/enu.parquet"


def truth(route="{route}", root=RESULTS) -> str:
    """The route's truth (:mod:`imugen.tables.truth`)."""
    return f"{route_dir(route, root)}/truth.parquet"


def shard_dir(kind: str, route="{route}", grade="{grade}", root=RESULTS) -> str:
    """The folder of one grade's shards of ``kind`` (:data:`SHARD_KINDS`)."""
    if kind not in SHARD_KINDS:
        raise ValueError(f"unknown shard kind {kind!r}; kinds: {', '.join(SHARD_KINDS)}")
    return f"{route_dir(route, root)}/{kind}/{grade}"


def shard(kind: str, route="{route}", grade="{grade}", shard="{shard}", root=RESULTS) -> str:
    """One shard's table of ``kind`` (:data:`SHARD_KINDS`)."""
    return f"{shard_dir(kind, route, grade, root)}/shard-{shard}.parquet"


def sidecar(path: str, name: str) -> str:
    """A sidecar of a shard table: ``sidecar(".../shard-000.parquet", "labels")`` is
    ``.../shard-000.labels.parquet`` (``name``: ``labels`` or ``intervals``)."""
    stem = str(path).removesuffix(".parquet")
    return f"{stem}.{name}.parquet"


def beside(imu_shard, kind: str):
    """The ``kind`` table written beside IMU shard ``.../{route}/imu/{grade}/{name}``
    (``.../{route}/{kind}/{grade}/{name}``); a :class:`~pathlib.Path` for a Path."""
    from pathlib import Path

    p = Path(imu_shard)
    out = p.parents[2] / kind / p.parent.name / p.name
    return out if isinstance(imu_shard, Path) else str(out)


def metrics(route="{route}", grade="{grade}", root=RESULTS) -> str:
    """Per-sequence metrics of one grade (:mod:`imugen.tables.metrics`)."""
    return f"{route_dir(route, root)}/metrics/{grade}.parquet"


def rmse(route="{route}", ext="csv", root=RESULTS) -> str:
    """The RMSE table of a route (``csv``, ``md``, ``tex``, ``html``)."""
    return f"{route_dir(route, root)}/rmse.{ext}"


def figures_dir(route="{route}", root=RESULTS) -> str:
    """The folder of a route's figures."""
    return f"{route_dir(route, root)}/figures"


def figure(name: str, ext="{ext}", route="{route}", root=RESULTS) -> str:
    """One figure file: ``figure("figure8", "png")``."""
    return f"{figures_dir(route, root)}/{name}.{ext}"


def dataset_mat(route="{route}", grade="{grade}", root=RESULTS) -> str:
    """The MATLAB export of one grade."""
    return f"{route_dir(route, root)}/datasets/{grade}.mat"


def datasets_dir(route="{route}", grade="{grade}", root=RESULTS) -> str:
    """The folder of one grade's dataset exports (one subfolder per format)."""
    return f"{route_dir(route, root)}/datasets/{grade}"


def allan_static(grade="{grade}", root=RESULTS) -> str:
    """The still IMU shard of a grade's Allan check."""
    return f"{root}/allan/{grade}/static.parquet"


def allan(grade="{grade}", ext="json", root=RESULTS) -> str:
    """A grade's Allan check: ``json`` (figures) or ``png`` (plot)."""
    return f"{root}/allan/{grade}/allan.{ext}"


def find_truths(root=RESULTS) -> list:
    """Truth files under ``root`` (one per route folder), sorted (:class:`~pathlib.Path`)."""
    from pathlib import Path

    return sorted(Path(root).glob("*/truth.parquet"))  # truth("*", root)


def find_shards(route_folder, grade: str, kind: str = "imu") -> list:
    """The shard tables of ``kind`` of one grade in a route folder, sorted (sidecars
    excluded; :class:`~pathlib.Path`)."""
    from pathlib import Path

    folder = Path(route_folder) / kind / grade
    return [p for p in sorted(folder.glob("shard-*.parquet")) if p.name.count(".") == 1]
