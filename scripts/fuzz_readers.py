"""Run the structure-aware reader fuzz tests on a fresh seed (tests/system/test_fuzz_readers.py).

The test suite runs one fixed regression seed; this script draws other cases on demand:

    python scripts/fuzz_readers.py                      # a random seed, 1,000 cases per reader
    python scripts/fuzz_readers.py --seed=1234 --cases=5000
    python scripts/fuzz_readers.py --seed=1234 --reader=nmea --reader=navsatfix

It prints the seed first (a failure is replayed with the same ``--seed`` and ``--cases``) and
exits with pytest's status: 0 when every case ended in a table or one ``imugen: error:`` line.
A failing case is printed by Hypothesis, shrunk, with its ``@reproduce_failure`` blob.
"""

from __future__ import annotations

import argparse
import os
import secrets
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
READERS = ("kml", "kmz", "gpx", "csv", "enu_text", "nmea", "igc", "geojson", "navsatfix",
           "lettered_and_nul_padded_csv", "columbus_csv", "dashcam_70mai", "pose",
           "gpsbabel_formats")  # fmt: skip


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--seed", type=int, default=None, help="seed (default: a random one)")
    p.add_argument("--cases", type=int, default=1000, help="cases per reader")
    p.add_argument(
        "--reader", action="append", choices=READERS, help="only these readers (repeatable)"
    )
    a = p.parse_args(argv)
    if a.cases < 1:
        p.error("--cases must be at least 1")
    seed = secrets.randbelow(2**31) if a.seed is None else a.seed
    print(f"fuzz_readers: seed {seed}, {a.cases} cases per reader", flush=True)
    env = dict(os.environ, IMUGEN_FUZZ_SEED=str(seed), IMUGEN_FUZZ_EXAMPLES=str(a.cases))
    cmd = [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider",
           str(REPO / "tests" / "system" / "test_fuzz_readers.py")]  # fmt: skip
    if a.reader:
        cmd += ["-k", " or ".join(f"test_fuzz_{r}" for r in a.reader)]
    rc = subprocess.call(cmd, cwd=REPO, env=env)
    print(f"fuzz_readers: seed {seed}: {'PASS' if rc == 0 else 'FAIL'}", flush=True)
    return rc


if __name__ == "__main__":
    sys.exit(main())
