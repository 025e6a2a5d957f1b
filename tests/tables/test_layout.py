"""The results layout: one map of ``results/`` for the rules and the loader."""

from pathlib import Path

import pytest

from imugen.dataset import extra_path, find_routes
from imugen.tables import layout


def test_paths_with_wildcards_and_values():
    assert layout.truth() == "results/{route}/truth.parquet"
    assert layout.shard("imu") == "results/{route}/imu/{grade}/shard-{shard}.parquet"
    assert layout.shard("nav", "city", "tactical", layout.shard_label(12)) == (
        "results/city/nav/tactical/shard-012.parquet"
    )
    assert layout.shard_label(1234) == "1234"
    assert layout.sidecar(layout.shard("gnss"), "labels") == (
        "results/{route}/gnss/{grade}/shard-{shard}.labels.parquet"
    )
    assert layout.metrics("r", "g", root="out") == "out/r/metrics/g.parquet"
    assert layout.rmse("r", "html") == "results/r/rmse.html"
    assert layout.figure("figure8", "svg", "r") == "results/r/figures/figure8.svg"
    assert layout.allan("consumer", "png") == "results/allan/consumer/allan.png"
    assert layout.grade_file("mine") == "results/grades/mine.yaml"
    with pytest.raises(ValueError, match="unknown shard kind"):
        layout.shard("labels")


def test_the_loader_finds_what_the_layout_names(tmp_path):
    root = tmp_path / "results"
    for route in ("a", "b"):
        Path(layout.truth(route, root=root)).parent.mkdir(parents=True)
        Path(layout.truth(route, root=root)).touch()
    imu = Path(layout.shard("imu", "a", "consumer", "000", root=root))
    imu.parent.mkdir(parents=True)
    imu.touch()
    Path(layout.sidecar(imu, "labels")).touch()
    (routes,) = find_routes(root, "consumer")  # route b has no shards of the grade
    assert (routes.name, routes.shards) == ("a", (imu,))
    assert extra_path(imu, "gnss") == Path(layout.shard("gnss", "a", "consumer", "000", root=root))
    assert layout.beside(str(imu), "aided") == layout.shard(
        "aided", "a", "consumer", "000", root=root
    )
