"""Start-up of a shard job: what a simulate + navigate job must not import (issue 14)."""

import subprocess
import sys

CODE = """
import sys
from imugen.simulate import stage as S
from imugen.simulate.options import SimulateOptions
opts = SimulateOptions(grade="industrial", sequences=1, seed=1, shard=0, static_s=2.0)
S.run(None, sys.argv[1], opts)
import imugen.navigate.stage  # noqa: F401  (the navigation: navigator, mechanize, kernel)
names = ("pandas", "scipy.linalg", "pyproj", "matplotlib", "jsonschema")
heavy = [m for m in names if m in sys.modules]
print(",".join(heavy))
"""


def test_simulate_job_imports_no_pandas_scipy_linalg_pyproj(tmp_path):
    """A job that ran the sensor kernel (numba typing context loaded) has not imported pandas,
    scipy.linalg (numba's BLAS probe; numba's own import loads the bare ``scipy`` package),
    pyproj or matplotlib."""
    r = subprocess.run(
        [sys.executable, "-c", CODE, str(tmp_path / "s.parquet")],
        capture_output=True,
        text=True,
        check=True,
    )
    assert "numba.np.arraymath" not in r.stderr
    assert r.stdout.strip() == ""


def test_cli_parser_imports_no_pyproj():
    code = "import sys, imugen.cli; print('pyproj' in sys.modules, 'pandas' in sys.modules)"
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert r.stdout.split() == ["False", "False"]
