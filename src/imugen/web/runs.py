"""Run folders: configuration from the form, Snakemake processes, progress from the log."""

from __future__ import annotations

import json
import os
import re
import secrets
import signal
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import yaml

from imugen.core.errors import InputError

RUN_ID = re.compile(r"^[0-9a-f]{12}$")
PROGRESS = re.compile(r"^(\d+) of (\d+) steps \((\d+(?:\.\d+)?)%\) done", re.M)
RULE = re.compile(r"^(?:local)?rule (\w+):", re.M)


def safe_name(name: str, default: str = "route") -> str:
    """A file name that cannot leave its folder: letters, digits, ``._-``; no leading dot."""
    base = Path(str(name).replace("\\", "/")).name
    s = re.sub(r"[^A-Za-z0-9._-]", "_", base).lstrip(".")[:100]
    return s or default


@dataclass
class Run:
    """One run folder."""

    root: Path

    @property
    def id(self) -> str:
        return self.root.name

    @property
    def config_path(self) -> Path:
        return self.root / "config" / "config.yaml"

    @property
    def log_path(self) -> Path:
        return self.root / "run.log"

    def state(self) -> dict:
        p = self.root / "state.json"
        st = json.loads(p.read_text()) if p.exists() else {"status": "new"}
        if st.get("status") == "running" and not _alive(st.get("pid")):
            st["status"] = "finished" if (self.root / ".done").exists() else "failed"
            self.save_state(st)
        return st

    def save_state(self, st: dict) -> None:
        tmp = self.root / ".state.json.tmp"
        tmp.write_text(json.dumps(st))
        os.replace(tmp, self.root / "state.json")

    def config(self) -> dict:
        return yaml.safe_load(self.config_path.read_text()) if self.config_path.exists() else {}

    def write_config(self, cfg: dict) -> None:
        self.config_path.parent.mkdir(parents=True, exist_ok=True)
        tmp = self.config_path.with_suffix(".tmp")
        tmp.write_text(yaml.safe_dump(cfg, sort_keys=False))
        os.replace(tmp, self.config_path)

    def route_files(self) -> list[Path]:
        d = self.root / "input"
        return sorted(p for p in d.iterdir() if p.is_file()) if d.is_dir() else []

    def progress(self) -> dict:
        """Jobs done of total, current stage, elapsed and estimated time left, log tail."""
        st = self.state()
        text = self.log_path.read_text(errors="replace") if self.log_path.exists() else ""
        done = total = 0
        for m in PROGRESS.finditer(text):
            done, total = int(m.group(1)), int(m.group(2))
        if not total:
            m = re.search(r"^total\s+(\d+)$", text, re.M)
            total = int(m.group(1)) if m else 0
        rules = RULE.findall(text)
        start = st.get("started")
        end = st.get("ended") or time.time()
        elapsed = (end - start) if start else 0.0
        left = (
            elapsed * (total - done) / done
            if done and total and st["status"] == "running"
            else None
        )
        return {
            "status": st["status"],
            "done": done,
            "total": total,
            "stage": rules[-1] if rules else "",
            "elapsed_s": round(elapsed, 1),
            "left_s": None if left is None else round(left, 1),
            "log": "\n".join(text.splitlines()[-40:]),
        }

    def start(self, snakefile: Path, cores: int = 2) -> None:
        st = self.state()
        if st["status"] == "running":
            raise InputError(self.id, "is already running")
        (self.root / ".done").unlink(missing_ok=True)
        base = [sys.executable, "-m", "snakemake", "-s", str(snakefile), "-d", str(self.root)]
        # a cancelled run leaves Snakemake's lock: release it (no other process uses this folder)
        subprocess.run([*base, "--unlock"], capture_output=True, timeout=120)
        cmd = [*base, f"-j{cores}", "--rerun-incomplete", "--printshellcmds"]
        script = (
            f"{' '.join(map(_q, cmd))} && touch {_q(str(self.root / '.done'))} && "
            f"echo 'imugen: results in {self.root / 'results'}'"
        )
        with open(self.log_path, "w") as log:
            proc = subprocess.Popen(
                ["/bin/sh", "-c", script],
                stdout=log,
                stderr=subprocess.STDOUT,
                cwd=self.root,
                start_new_session=True,
            )
        self.save_state({"status": "running", "pid": proc.pid, "started": time.time()})

    def cancel(self) -> None:
        st = self.state()
        if st["status"] != "running":
            return
        try:
            os.killpg(st["pid"], signal.SIGTERM)
        except ProcessLookupError:
            pass
        for _ in range(100):
            if not _alive(st["pid"]):
                break
            time.sleep(0.1)
        st.update(status="cancelled", ended=time.time())
        self.save_state(st)


def _q(s: str) -> str:
    return "'" + s.replace("'", "'\"'\"'") + "'"


def _alive(pid) -> bool:
    if not pid:
        return False
    try:
        done, _ = os.waitpid(pid, os.WNOHANG)
        if done:
            return False
    except ChildProcessError:
        pass
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    return True


class Runs:
    """The run folders under ``workdir/runs``."""

    def __init__(self, workdir: Path):
        self.dir = Path(workdir) / "runs"
        self.dir.mkdir(parents=True, exist_ok=True)

    def new(self) -> Run:
        rid = secrets.token_hex(6)
        root = self.dir / rid
        (root / "input").mkdir(parents=True)
        return Run(root)

    def get(self, rid: str) -> Run:
        if not RUN_ID.match(rid or "") or not (self.dir / rid).is_dir():
            raise InputError(rid, "no such run")
        return Run(self.dir / rid)

    def all(self) -> list[Run]:
        runs = [Run(p) for p in self.dir.iterdir() if p.is_dir() and RUN_ID.match(p.name)]
        return sorted(runs, key=lambda r: r.root.stat().st_mtime, reverse=True)
