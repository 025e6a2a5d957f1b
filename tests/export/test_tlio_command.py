"""The TLIO command (imugen.export.tlio.train_command) against TLIO's own argument parser:
``src/main_net.py`` of CathIAS/TLIO at commit d7051c4 (2023-08-07, master), its options listed
here as they are declared there, and its window arithmetic (``network/train.py``,
``arg_conversion``): the exported rows fill the network's window exactly."""

import argparse
import shlex

import pytest

from imugen.export import tlio

TLIO_VERSION = "CathIAS/TLIO@d7051c4 (2023-08-07)"
# (option, type) of main_net.py at TLIO_VERSION; bool options come in --x / --no-x pairs
TLIO_OPTIONS = (
    ("--root_dir", str), ("--out_dir", str), ("--model_path", str), ("--continue_from", str),
    ("--out_name", str), ("--lr", float), ("--batch_size", int), ("--epochs", int),
    ("--arch", str), ("--input_dim", int), ("--output_dim", int), ("--workers", int),
    ("--dataset_style", str), ("--imu_freq", float), ("--imu_base_freq", float),
    ("--accel_bias_range", float), ("--gyro_bias_range", float),
    ("--perturb_gravity_theta_range", float), ("--past_time", float), ("--window_time", float),
    ("--future_time", float), ("--sample_freq", float), ("--rpe_window", float),
)  # fmt: skip
TLIO_FLAGS = ("--cpu",)
TLIO_BOOLS = ("persistent_workers", "do_bias_shift", "perturb_gravity", "save_plot")
DEFAULTS = {"imu_freq": 200.0, "window_time": 1.0, "past_time": 0.0, "future_time": 0.0,
            "sample_freq": 20.0}  # fmt: skip


def tlio_parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(prog=f"main_net.py ({TLIO_VERSION})", exit_on_error=False)
    for name, typ in TLIO_OPTIONS:
        key = name[2:]
        ap.add_argument(name, type=typ, default=DEFAULTS.get(key))
    for name in TLIO_FLAGS:
        ap.add_argument(name, action="store_true")
    ap.add_argument("--mode", default="train", choices=["train", "test", "eval"])
    for b in TLIO_BOOLS:
        g = ap.add_mutually_exclusive_group()
        g.add_argument(f"--{b}", dest=b, action="store_true")
        g.add_argument(f"--no-{b}", dest=b, action="store_false")
    return ap


def parse(cmd: str) -> argparse.Namespace:
    words = shlex.split(cmd)
    assert words[:2] == ["python3", "src/main_net.py"]
    return tlio_parser().parse_args(words[2:])


@pytest.mark.parametrize("rate", [50.0, 100.0, 200.0, 400.0])
def test_command_parses_and_fills_the_window_with_the_exported_rows(rate):
    a = parse(tlio.train_command("out/tlio", rate))
    assert a.mode == "train" and a.root_dir == "out/tlio"
    # TLIO's arg_conversion: integers, and the window is window_time * imu_freq rows of the
    # file, whose rows are at the export's rate
    assert a.imu_freq == rate
    assert (a.window_time * a.imu_freq).is_integer() and (a.imu_freq / a.sample_freq).is_integer()
    assert int(a.window_time * a.imu_freq) == int(rate)
    t = parse(tlio.train_command("out/tlio", rate, mode="test", model_path="m.pt"))
    assert t.mode == "test" and t.model_path == "m.pt"


def test_the_former_list_options_are_refused():
    """The README's former command: TLIO reads <split>_list.txt under --root_dir now."""
    for old in ("--train_list", "--val_list", "--test_list"):
        with pytest.raises((argparse.ArgumentError, SystemExit)):
            tlio_parser().parse_args([old, "x"])
