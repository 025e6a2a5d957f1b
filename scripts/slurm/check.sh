#!/usr/bin/env bash
# Prove the SLURM profile on a real SLURM: a one-node cluster on this machine, the workflow on a
# small config once locally (`snakemake -j2`) and once through snakemake-executor-plugin-slurm
# (`--workflow-profile workflow/profiles/slurm --executor slurm`), and the results compared:
# RMSE tables identical, IMU and navigation shard Parquet files bit-identical.
#
#   bash scripts/slurm/check.sh            # as root on Debian 12 (installs what is missing)
#
# Steps, each skipped when already done (the script can be run again):
#   1. Debian's slurm-wlm and munge (apt-get; root only).
#   2. munged, then slurmctld + slurmd for one node on localhost: CPUs = nproc, RealMemory from
#      /proc/meminfo, no accounting (/etc/slurm/slurm.conf written only when absent or ours).
#      A controller that already answers (`scontrol ping`) is used as it is.
#   3. The executor plugin in the current Python environment ($PYTHON, default: python on PATH).
#   4. Both runs in a scratch directory ($IMUGEN_SLURM_WORK, default: a new /tmp/imugen-slurm.*).
#   5. The comparison; one summary line; exit status 1 on any difference, 2 on a setup failure.
#   6. The daemons this script started are stopped again (the installation stays).
# Environment: PYTHON, IMUGEN_SLURM_WORK, SLURM_PARTITION (default: the cluster's default one),
# SLURM_ACCOUNT (default: none on our cluster, the plugin's guess on another one),
# SLURM_CORES (--cores of the SLURM run, default: one node's CPUs), SLURM_TIMEOUT (seconds
# allowed to the SLURM run, default 1200), KEEP_DAEMONS=1 (leave the daemons running).
set -euo pipefail

REPO=$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)
PYTHON=${PYTHON:-$(command -v python || command -v python3)}
PLUGIN_SPEC='snakemake-executor-plugin-slurm>=2.8,<3'
MARK='# written by imugen scripts/slurm/check.sh'
CONF=/etc/slurm/slurm.conf
T0=$(date +%s.%N)

say() { printf 'slurm-check: %s\n' "$*" >&2; }
die() { say "error: $*"; exit 2; }
elapsed() { awk -v a="$1" -v b="$(date +%s.%N)" 'BEGIN { printf "%.1f", b - a }'; }
is_root() { [ "$(id -u)" -eq 0 ]; }

# ---- daemons started here, stopped on exit ------------------------------------------------
STARTED=()  # pid files
# shellcheck disable=SC2317  # called by the EXIT trap
stop_daemons() {
  [ "${KEEP_DAEMONS:-0}" = 1 ] && return 0
  local i pidfile pid
  for ((i = ${#STARTED[@]} - 1; i >= 0; i--)); do
    pidfile=${STARTED[i]}
    [ -s "$pidfile" ] || continue
    pid=$(cat "$pidfile")
    kill "$pid" 2>/dev/null || continue
    for _ in $(seq 50); do kill -0 "$pid" 2>/dev/null || break; sleep 0.2; done
    say "stopped $(basename "$pidfile" .pid) (pid $pid)"
  done
}
trap stop_daemons EXIT

alive() { [ -s "$1" ] && kill -0 "$(cat "$1")" 2>/dev/null; }

# ---- 1. packages ------------------------------------------------------------------------
T_INSTALL=$(date +%s.%N)
if ! command -v slurmctld >/dev/null || ! command -v slurmd >/dev/null \
  || ! command -v munged >/dev/null || ! command -v sbatch >/dev/null; then
  is_root || die "slurm-wlm and munge are missing; install them as root (apt-get install slurm-wlm munge)"
  say "installing slurm-wlm and munge (apt-get)"
  export DEBIAN_FRONTEND=noninteractive
  apt-get update -q >/dev/null
  apt-get install -y -q --no-install-recommends slurm-wlm munge >/dev/null
fi
say "packages ready ($(elapsed "$T_INSTALL") s): $(slurmd -V)"

# ---- 2. munge ---------------------------------------------------------------------------
if ! munge -n 2>/dev/null | unmunge >/dev/null 2>&1; then
  is_root || die "munged is not running; start it as root"
  install -d -o munge -g munge -m 0700 /etc/munge /var/lib/munge /var/log/munge
  install -d -o munge -g munge -m 0755 /run/munge
  if [ ! -s /etc/munge/munge.key ]; then
    dd if=/dev/urandom of=/etc/munge/munge.key bs=1024 count=1 status=none
    chown munge:munge /etc/munge/munge.key
    chmod 0400 /etc/munge/munge.key
  fi
  runuser -u munge -- /usr/sbin/munged
  STARTED+=(/run/munge/munged.pid)
  for _ in $(seq 50); do munge -n 2>/dev/null | unmunge >/dev/null 2>&1 && break; sleep 0.2; done
  munge -n | unmunge >/dev/null || die "munged started but credentials do not decode"
  say "started munged"
fi

# ---- 3. slurm.conf, slurmctld, slurmd -----------------------------------------------------
HOST=$(hostname -s)
if ! scontrol ping 2>/dev/null | grep -q 'is UP'; then
  is_root || die "no SLURM controller answers; start one as root or run this script as root"
  if [ -e "$CONF" ] && ! grep -qF "$MARK" "$CONF"; then
    die "$CONF exists and is not ours, but no controller answers: start that cluster first"
  fi
  CPUS=$(nproc)
  MEM_MB=$(awk '/^MemTotal:/ { printf "%d", $2 / 1024 }' /proc/meminfo)
  install -d -o slurm -g slurm -m 0755 /var/spool/slurmctld /var/log/slurm
  install -d -m 0755 /var/spool/slurmd /run/slurm /etc/slurm
  cat >"$CONF" <<EOF
$MARK: a one-node test cluster on localhost
ClusterName=imugen
SlurmctldHost=$HOST(127.0.0.1)
SlurmUser=slurm
AuthType=auth/munge
CredType=cred/munge
StateSaveLocation=/var/spool/slurmctld
SlurmdSpoolDir=/var/spool/slurmd
SlurmctldPidFile=/run/slurm/slurmctld.pid
SlurmdPidFile=/run/slurm/slurmd.pid
SlurmctldLogFile=/var/log/slurm/slurmctld.log
SlurmdLogFile=/var/log/slurm/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
MpiDefault=none
SchedulerType=sched/backfill
SelectType=select/cons_tres
SelectTypeParameters=CR_Core_Memory
AccountingStorageType=accounting_storage/none
JobAcctGatherType=jobacct_gather/none
JobCompType=jobcomp/none
# finished jobs stay visible to squeue for 5 minutes: the executor plugin's status queries
# (--slurm-status-command squeue) rely on it, as sacct needs accounting
MinJobAge=300
ReturnToService=2
NodeName=$HOST NodeAddr=127.0.0.1 CPUs=$CPUS RealMemory=$MEM_MB State=UNKNOWN
PartitionName=debug Nodes=$HOST Default=YES MaxTime=INFINITE State=UP
EOF
  say "wrote $CONF (CPUs=$CPUS RealMemory=$MEM_MB)"
  slurmctld -c
  STARTED+=(/run/slurm/slurmctld.pid)
  for _ in $(seq 50); do scontrol ping 2>/dev/null | grep -q 'is UP' && break; sleep 0.2; done
  scontrol ping | grep -q 'is UP' || die "slurmctld did not come up (/var/log/slurm/slurmctld.log)"
  say "started slurmctld"
fi
if grep -qF "$MARK" "$CONF" 2>/dev/null && ! alive /run/slurm/slurmd.pid; then
  slurmd
  STARTED+=(/run/slurm/slurmd.pid)
  say "started slurmd"
fi
# wait for a node that can take jobs (ours: this host; another cluster: any node)
NODE_ARGS=()
grep -qF "$MARK" "$CONF" 2>/dev/null && NODE_ARGS=(-n "$HOST")
state=
for _ in $(seq 100); do
  state=$(sinfo -h -N "${NODE_ARGS[@]}" -o %t 2>/dev/null | grep -m1 -E '^(idle|mix|alloc)' || true)
  [ -n "$state" ] && break
  sleep 0.3
done
[ -n "$state" ] || { sinfo -N -l >&2 || true; die "no SLURM node is idle (sinfo above)"; }
# cores the SLURM run may hold at once (and the widest a shard group gets): one node's CPUs
SLURM_CORES=${SLURM_CORES:-$(sinfo -h -N "${NODE_ARGS[@]}" -o %c | sort -n | head -1)}
say "SLURM ready: node state $state, $SLURM_CORES CPUs per node"

# ---- 4. Python environment and the executor plugin ---------------------------------------
[ -x "$PYTHON" ] || die "no python found (set PYTHON)"
PATH="$(dirname "$PYTHON"):$PATH"  # `imugen` and `snakemake` of that environment, also in jobs
export PATH
"$PYTHON" -c 'import imugen, snakemake' 2>/dev/null \
  || die "$PYTHON cannot import imugen and snakemake: pip install -e . first"
if ! "$PYTHON" -c 'import snakemake_executor_plugin_slurm' 2>/dev/null; then
  say "installing $PLUGIN_SPEC into $("$PYTHON" -c 'import sys; print(sys.prefix)')"
  "$PYTHON" -m pip install --quiet "$PLUGIN_SPEC"
fi
PLUGIN_VERSION=$("$PYTHON" -m pip show snakemake-executor-plugin-slurm 2>/dev/null \
  | awk '/^Version:/ { print $2 }')
SNAKEMAKE_VERSION=$("$PYTHON" -m snakemake --version)
say "snakemake $SNAKEMAKE_VERSION, snakemake-executor-plugin-slurm $PLUGIN_VERSION"

# ---- 5. the two runs ----------------------------------------------------------------------
WORK=${IMUGEN_SLURM_WORK:-$(mktemp -d /tmp/imugen-slurm.XXXXXX)}
rm -rf "$WORK/local" "$WORK/slurm"
for d in local slurm; do
  mkdir -p "$WORK/$d/config"
  cat >"$WORK/$d/config/config.yaml" <<EOF
routes:
  example:
    file: $REPO/resources/example_route.kml
    vehicle: car
truth: {rate_hz: 10, earth: auto}
grades:
  consumer: {}
  mine:
    id: 101
    gyro: {white_noise: {value: 0.2, unit: deg_per_sqrt_h}}
    accel: {white_noise: {value: 0.05, unit: m_per_s_per_sqrt_h}}
simulate: {sequences: 4, sequences_per_shard: 2, seed: 7}
allan: {static_s: 300, rate_hz: 10, sequences: 2}
exports: {mat: true}
figures: {formats: [png]}
EOF
done
SMK=("$PYTHON" -m snakemake -s "$REPO/Snakefile")

say "local run: snakemake -j2 in $WORK/local"
T_LOCAL=$(date +%s.%N)
(cd "$WORK/local" && "${SMK[@]}" -j2 >"$WORK/local.log" 2>&1) \
  || { tail -40 "$WORK/local.log" >&2; die "the local run failed ($WORK/local.log)"; }
LOCAL_S=$(elapsed "$T_LOCAL")

# the partition as a user gives it (the cluster's default one unless SLURM_PARTITION is set)
PARTITION=${SLURM_PARTITION:-$(sinfo -h -o %P | sed -n 's/\*$//p' | head -1)}
RESOURCES=()
[ -n "$PARTITION" ] && RESOURCES+=("slurm_partition=$PARTITION")
[ -n "${SLURM_ACCOUNT:-}" ] && RESOURCES+=("slurm_account=$SLURM_ACCOUNT")
PLUGIN_ARGS=(--slurm-init-seconds-before-status-checks 5)  # jobs here take seconds, not 40 s
[ ${#RESOURCES[@]} -gt 0 ] && PLUGIN_ARGS+=(--default-resources "${RESOURCES[@]}")
# our cluster has no accounts; elsewhere the plugin guesses one unless SLURM_ACCOUNT is set
grep -qF "$MARK" "$CONF" 2>/dev/null && [ -z "${SLURM_ACCOUNT:-}" ] && PLUGIN_ARGS+=(--slurm-no-account)
# without accounting sacct fails ("accounting storage is disabled") and the plugin, which
# prefers sacct, would never see a job finish: ask squeue instead
NO_ACCOUNTING=0
sacct -X -n -S now >/dev/null 2>&1 || NO_ACCOUNTING=1
[ "$NO_ACCOUNTING" = 1 ] && PLUGIN_ARGS+=(--slurm-status-command squeue)
if [ "$NO_ACCOUNTING" = 1 ]; then
  # without that option the plugin would wait for ever: the workflow must refuse the README's
  # command in one line, before any submission (src/imugen/preflight.py)
  say "no accounting: the README's command without --slurm-status-command squeue must refuse"
  set +e
  (cd "$WORK/slurm" && timeout -k 10 120 "${SMK[@]}" \
    --workflow-profile "$REPO/workflow/profiles/slurm" --executor slurm --cores "$SLURM_CORES" \
    >"$WORK/refused.log" 2>&1)
  refused_rc=$?
  set -e
  if [ "$refused_rc" -eq 0 ] || [ "$refused_rc" -ge 124 ] \
    || ! tail -1 "$WORK/refused.log" | grep -q '^imugen: error: this SLURM cluster has no job accounting'; then
    tail -20 "$WORK/refused.log" >&2
    say "FAIL: without accounting the run was not refused in one line (exit $refused_rc)"
    exit 1
  fi
  say "  refused in one line: $(tail -1 "$WORK/refused.log" | cut -c1-100)..."
fi
say "SLURM run: --workflow-profile workflow/profiles/slurm --executor slurm (partition ${PARTITION:-default}) in $WORK/slurm"
T_SLURM=$(date +%s.%N)
say "  options: --cores $SLURM_CORES ${PLUGIN_ARGS[*]}"
# --verbose logs each sbatch call (read by the comparison below)
(cd "$WORK/slurm" && timeout -k 30 "${SLURM_TIMEOUT:-1200}" \
  "${SMK[@]}" --workflow-profile "$REPO/workflow/profiles/slurm" --executor slurm \
  --cores "$SLURM_CORES" "${PLUGIN_ARGS[@]}" --verbose >"$WORK/slurm.log" 2>&1) \
  || { tail -60 "$WORK/slurm.log" >&2; die "the SLURM run failed or timed out ($WORK/slurm.log)"; }
SLURM_S=$(elapsed "$T_SLURM")

# ---- 6. comparison ------------------------------------------------------------------------
set +e
"$PYTHON" - "$WORK" "$LOCAL_S" "$SLURM_S" "$(elapsed "$T0")" "$REPO" <<'EOF'
import hashlib
import re
import sys
from pathlib import Path

work, local_s, slurm_s, total_s = Path(sys.argv[1]), *sys.argv[2:5]
local, slurm = work / "local", work / "slurm"
problems = []


def files(root, pattern):
    return sorted(p.relative_to(root) for p in root.glob(pattern))


def sha(p):
    return hashlib.sha256(p.read_bytes()).hexdigest()


counts = {}
for kind, pattern in (
    ("RMSE tables", "results/*/rmse.csv"),
    ("IMU shards", "results/*/imu/*/shard-*.parquet"),
    ("nav shards", "results/*/nav/*/shard-*.parquet"),
):
    a, b = files(local, pattern), files(slurm, pattern)
    if not a:
        problems.append(f"no {kind} in the local run")
    if a != b:
        problems.append(f"{kind}: different file sets {sorted(set(a) ^ set(b))}")
    same = [p for p in a if p in b and sha(local / p) == sha(slurm / p)]
    problems += [f"{kind}: {p} differs" for p in a if p in b and p not in same]
    counts[kind] = len(same)

# where each rule ran: "localrule X:" on this host; each sbatch call (logged with --verbose)
# names its rules after --allowed-rules, and a group's call carries --local-groupid
log = (work / "slurm.log").read_text()
snakefile = (Path(sys.argv[5]) / "Snakefile").read_text()
block = re.search(r"^localrules:\n((?:[ \t]+\w+,?\n)+)", snakefile, flags=re.M)
declared = set(re.findall(r"\w+", block.group(1))) if block else set()
ran_local = set(re.findall(r"^localrule (\w+):", log, flags=re.M))
subs = [line for line in log.splitlines() if line.startswith("sbatch call: ")]
ran_slurm = set()
for line in subs:
    ran_slurm |= set(re.search(r"--allowed-rules ((?:\w+ )+)--", line).group(1).split())
groups = sum("--local-groupid" in line for line in subs)
if not subs:
    problems.append("no job was submitted to SLURM")
if ran_local - declared:
    problems.append(f"rules run locally but not in localrules: {sorted(ran_local - declared)}")
if ran_slurm & declared:
    problems.append(f"localrules submitted to SLURM: {sorted(ran_slurm & declared)}")
summary = ", ".join(f"{n} {k} identical" for k, n in counts.items())
status = "PASS" if not problems else "FAIL"
print(
    f"slurm-check: {status}: {summary}; {len(subs)} SLURM submissions ({groups} shard "
    f"groups; rules on SLURM: {' '.join(sorted(ran_slurm))}; on this host: "
    f"{' '.join(sorted(ran_local))}); "
    f"wall time: SLURM run {slurm_s} s, local run {local_s} s, whole check {total_s} s"
)
for p in problems:
    print(f"slurm-check:   {p}")
sys.exit(1 if problems else 0)
EOF
rc=$?
set -e
exit "$rc"
