"""Run folders: configuration from the form, Snakemake processes, progress from the log.

Starting a run is serialized (a file lock over the work folder): a run that is running is never
started again, a run is started only while fewer than the cap run, and a refused start changes
nothing (not even ``run.log``). A run's process is known by its pid and its start time, so a
reused pid is never taken for it (nor signalled by Cancel).
"""

from __future__ import annotations

import contextlib
import fcntl
import json
import os
import re
import secrets
import signal
import stat
import subprocess
import sys
import tempfile
import time
import zipfile
from dataclasses import dataclass
from pathlib import Path

import yaml

from imugen.core.errors import InputError

RUN_ID = re.compile(r"^[0-9a-f]{12}$")
ERROR_LINE = re.compile(r"^imugen: error: (.+)$", re.M)
PROGRESS = re.compile(r"^(\d+) of (\d+) steps \((\d+(?:\.\d+)?)%\) done", re.M)
RULE = re.compile(r"^(?:local)?rule (\w+):", re.M)


def safe_name(name: str, default: str = "route") -> str:
    """A file name that cannot leave its folder: letters, digits, ``._-``; no leading dot."""
    base = Path(str(name).replace("\\", "/")).name
    s = re.sub(r"[^A-Za-z0-9._-]", "_", base).lstrip(".")[:100]
    return s or default


class Refused(InputError):
    """A request the run's state does not allow now (HTTP 409)."""

    status = 409


class Busy(Refused):
    """Too many runs or checks at once (HTTP 429)."""

    status = 429


@contextlib.contextmanager
def locked(path: Path):
    """An exclusive lock on ``path`` (created if missing) while the block runs."""
    fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o600)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX)
        yield
    finally:
        os.close(fd)


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
        if st.get("status") == "running" and not _alive(st.get("pid"), st.get("ticks")):
            st["status"] = "finished" if (self.root / ".done").exists() else "failed"
            st.setdefault("ended", time.time())
            self.save_state(st)
        return st

    @property
    def running(self) -> bool:
        return self.state()["status"] == "running"

    def save_state(self, st: dict) -> None:
        fd, tmp = tempfile.mkstemp(dir=self.root, prefix=".state.", suffix=".tmp")
        with os.fdopen(fd, "w") as f:
            f.write(json.dumps(st))
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
            "errors": ERROR_LINE.findall(text)[-10:] if st["status"] == "failed" else [],
        }

    def start(self, snakefile: Path, cores: int = 2) -> None:
        """Start Snakemake in this folder (under :func:`locked`; see :meth:`Runs.start`)."""
        with locked(self.root / ".start.lock"):
            if self.running:
                raise Refused(self.id, "is already running (cancel it first)")
            (self.root / ".done").unlink(missing_ok=True)
            base = [sys.executable, "-m", "snakemake", "-s", str(snakefile), "-d", str(self.root)]
            # a cancelled run leaves Snakemake's lock; its process is gone (checked above)
            subprocess.run([*base, "--unlock"], capture_output=True, timeout=120)
            cmd = [*base, f"--cores={cores}", "--rerun-incomplete", "--printshellcmds"]
            script = (
                f"{' '.join(map(_q, cmd))} && touch {_q(str(self.root / '.done'))} && "
                "echo 'imugen: results in results/'"
            )
            with open(self.log_path, "w") as log:
                proc = subprocess.Popen(
                    ["/bin/sh", "-c", script],
                    stdout=log,
                    stderr=subprocess.STDOUT,
                    cwd=self.root,
                    start_new_session=True,
                )
            self.save_state(
                {
                    "status": "running",
                    "pid": proc.pid,
                    "ticks": _start_ticks(proc.pid),
                    "started": time.time(),
                }
            )

    def cancel(self) -> None:
        with locked(self.root / ".start.lock"):
            st = self.state()
            if st["status"] != "running":
                return
            try:
                os.killpg(st["pid"], signal.SIGTERM)
            except ProcessLookupError:
                pass
            for _ in range(100):
                if not _alive(st["pid"], st.get("ticks")):
                    break
                time.sleep(0.1)
            st.update(status="cancelled", ended=time.time())
            self.save_state(st)

    def iter_results_zip(self, chunk: int = 1 << 20):
        """The run's ``results/`` as a zip archive, in pieces (nothing is written to disk).

        Regular files only: symbolic links (to files or folders) and special files are left
        out, and files are opened without following a link (``O_NOFOLLOW``), so the archive
        never holds anything from outside ``results/``.
        """
        sink = _Sink()
        top = self.root / "results"
        with zipfile.ZipFile(sink, "w", zipfile.ZIP_DEFLATED, compresslevel=1) as zf:
            for dirpath, dirnames, filenames in os.walk(top, followlinks=False):
                dirnames[:] = sorted(
                    d for d in dirnames if not os.path.islink(os.path.join(dirpath, d))
                )
                for name in sorted(filenames):
                    path = os.path.join(dirpath, name)
                    try:
                        fd = os.open(path, os.O_RDONLY | os.O_NOFOLLOW | os.O_NONBLOCK)
                    except OSError:  # a symbolic link (ELOOP), or gone
                        continue
                    with os.fdopen(fd, "rb") as f:
                        st = os.fstat(f.fileno())
                        if not stat.S_ISREG(st.st_mode):
                            continue
                        info = zipfile.ZipInfo(
                            os.path.relpath(path, self.root),
                            time.localtime(max(st.st_mtime, 315532800.0))[:6],  # zip: >= 1980
                        )
                        info.compress_type = zipfile.ZIP_DEFLATED
                        info.external_attr = 0o644 << 16
                        with zf.open(info, "w", force_zip64=True) as out:
                            while block := f.read(chunk):
                                out.write(block)
                                if sink.size >= chunk:
                                    yield sink.take()
                    if sink.size:
                        yield sink.take()
        yield sink.take()


class _Sink:
    """A write-only, non-seekable stream whose bytes are taken out as they come."""

    def __init__(self):
        self.parts: list[bytes] = []
        self.size = 0
        self.pos = 0

    def write(self, b) -> int:
        self.parts.append(bytes(b))
        self.size += len(b)
        self.pos += len(b)
        return len(b)

    def tell(self) -> int:
        return self.pos

    def flush(self) -> None:
        pass

    def take(self) -> bytes:
        out = b"".join(self.parts)
        self.parts.clear()
        self.size = 0
        return out


def _q(s: str) -> str:
    return "'" + s.replace("'", "'\"'\"'") + "'"


def _start_ticks(pid: int) -> int | None:
    """Start time of process ``pid`` in clock ticks since boot (Linux), None if unknown."""
    try:
        stat_line = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return None
    return int(stat_line.rsplit(")", 1)[1].split()[19])


def _alive(pid, ticks=None) -> bool:
    """Whether the run's process ``pid`` (started at ``ticks``) still runs."""
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
    except (ProcessLookupError, PermissionError):  # gone, or another user's process
        return False
    now = _start_ticks(pid)
    return ticks is None or now is None or now == ticks  # else: the pid was reused


class Runs:
    """The run folders under ``workdir/runs`` (private to the user: mode 0700)."""

    def __init__(self, workdir: Path):
        self.dir = Path(workdir) / "runs"
        self.dir.mkdir(parents=True, exist_ok=True, mode=0o700)

    def new(self) -> Run:
        rid = secrets.token_hex(6)
        root = self.dir / rid
        root.mkdir(mode=0o700)
        (root / "input").mkdir()
        return Run(root)

    def get(self, rid: str) -> Run:
        if not RUN_ID.match(rid or "") or not (self.dir / rid).is_dir():
            raise InputError(rid, "no such run")
        return Run(self.dir / rid)

    def all(self) -> list[Run]:
        runs = [Run(p) for p in self.dir.iterdir() if p.is_dir() and RUN_ID.match(p.name)]
        return sorted(runs, key=lambda r: r.root.stat().st_mtime, reverse=True)

    def start(self, run: Run, snakefile: Path, cores: int, max_running: int) -> None:
        """Start ``run`` unless it runs or ``max_running`` runs already run (one start at a
        time over the whole work folder)."""
        with locked(self.dir / ".start.lock"):
            if run.running:
                raise Refused(run.id, "is already running (cancel it first)")
            n = sum(r.running for r in self.all())
            if n >= max_running:
                raise Busy(
                    run.id,
                    f"{n} run{'s' if n > 1 else ''} already running (at most {max_running} at "
                    "once on this machine); start it when one has finished",
                )
            run.start(snakefile, cores)
