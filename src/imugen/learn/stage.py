"""The learn stage's face: the commands of ``workflow/rules/learn.smk``.

``imugen learn train`` (:func:`main_train`: :func:`imugen.learn.train.train`), ``imugen learn
correct`` (:func:`main_correct`: :func:`imugen.learn.correct.correct`) and ``imugen learn
table`` (:func:`main_table`: the benchmark's table, :mod:`imugen.learn.table`, written as CSV,
Markdown and a figure). Each command imports only its own module, inside its function, so
that PyTorch loads only for the commands that need it and each rule's code digest
(``code_digest("imugen.learn.stage:main_train")`` in the rule file) holds its command's code
alone: editing the table reruns no training.
"""

from __future__ import annotations

from pathlib import Path

from imugen.core.errors import InputError
from imugen.learn.options import CorrectOptions, TableOptions, TrainOptions


def main_train(options: TrainOptions, truth, output, grade) -> None:
    """``imugen learn train``: the reference network from the training routes' truths."""
    from imugen.learn.train import train

    train(truth, grade, output, options)


def main_correct(options: CorrectOptions, model, shard, output) -> None:
    """``imugen learn correct``: the network's IMU correction table of one shard."""
    from imugen.learn.correct import correct

    correct(model, shard, output, options)


def main_table(options: TableOptions, output, figure, aided, learned, split) -> None:
    """``imugen learn table``: ``<output>.csv``, ``<output>.md`` and ``<figure>.<format>``."""
    from imugen.core.io import atomic_output
    from imugen.core.plotting import save, style
    from imugen.learn.table import draw, markdown, pairs, rows

    splits = {}
    for item in split or ():
        route, sep, name = item.partition("=")
        if not (sep and route and name):
            raise InputError("--split", f"{item!r} is not ROUTE=SPLIT")
        splits[route] = name
    df = rows(pairs(aided, "--aided"), pairs(learned, "--learned"), splits, options.durations_s)
    stem = Path(output)
    with atomic_output(stem.with_suffix(".csv")) as tmp:
        df.to_csv(tmp, index=False)
    with atomic_output(stem.with_suffix(".md")) as tmp:
        Path(tmp).write_text(markdown(df))
    with style():
        save(draw(df), figure, options.formats, options.dpi)


__all__ = ["main_correct", "main_table", "main_train"]
