"""The learn stage's face (src/imugen/learn/stage.py): its commands through the command line,
and each command's code digest holding its own module only (workflow/rules/common.smk)."""

import ast
import functools
import hashlib
import types
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from imugen.cli import main
from imugen.tables import metrics as tmetrics

from helpers import REPO


class _WorkflowError(Exception):
    pass


@pytest.fixture(scope="module")
def code_files():
    """``code_files`` of workflow/rules/common.smk (its plain-Python part, run as is)."""
    text = (REPO / "workflow/rules/common.smk").read_text()
    source = text[text.index("SRC = Path(") : text.index("\n\n\nPRESETS = ")]
    ns = {
        "ast": ast, "functools": functools, "hashlib": hashlib, "Path": Path,
        "WorkflowError": _WorkflowError, "workflow": types.SimpleNamespace(basedir=str(REPO)),
    }  # fmt: skip
    exec(compile(source, "common.smk", "exec"), ns)

    def files(*modules):
        return {
            Path(f).relative_to(REPO / "src/imugen").as_posix() for f in ns["code_files"](*modules)
        }

    return files


def test_each_learn_command_digests_its_own_module(code_files):
    train = code_files("imugen.learn.stage:main_train")
    correct = code_files("imugen.learn.stage:main_correct")
    table = code_files("imugen.learn.stage:main_table")
    for files in (train, correct, table):
        assert {"learn/stage.py", "learn/options.py", "cli.py"} <= files
    assert {"learn/train.py", "learn/model.py", "stream/__init__.py"} <= train
    assert "learn/model.py" in correct and "tables/imu_correction.py" in correct
    assert {"learn/table.py", "figures/outage_drift.py", "tables/metrics.py"} <= table
    assert not {"learn/table.py", "learn/correct.py"} & train  # editing the table retrains nothing
    assert not {"learn/train.py", "learn/table.py"} & correct
    assert not {"learn/train.py", "learn/correct.py", "learn/model.py"} & table
    assert train | correct | table == code_files("imugen.learn.stage")  # the whole face
    with pytest.raises(_WorkflowError, match="no function main"):
        code_files("imugen.learn.stage:main")


def test_learn_table_through_the_command_line(tmp_path):
    df = pd.DataFrame({"sequence": np.arange(4), "rmse_total_m": 1.0})
    df["outage_30s_end_m"] = [1.0, 2.0, 3.0, np.nan]
    df["drift_30s_m"] = [10.0, 20.0, 30.0, 40.0]
    path = tmetrics.write(df, {"stage": "evaluate", "grade": "consumer"}, tmp_path / "m.parquet")
    argv = ["learn", "table", f"--output={tmp_path / 'table'}", f"--figure={tmp_path / 'fig'}",
            f"--aided=park,consumer={path}", "--split=park=test", "--durations=30",
            "--formats", "png"]  # fmt: skip
    assert main(argv) == 0
    tab = pd.read_csv(tmp_path / "table.csv")
    assert tab[["baseline", "sequences", "median_m"]].values.tolist() == [
        ["free_inertial", 4, 25.0],
        ["aided", 3, 2.0],
    ]
    assert (tmp_path / "table.md").is_file() and (tmp_path / "fig.png").stat().st_size > 1000
    assert main([*argv[:-3], "--split=park", "--formats", "png"]) == 2  # one-line error
