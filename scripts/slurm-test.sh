#!/usr/bin/env bash
# The Slurm test: a one-node Slurm cluster on this machine (munged, slurmctld, slurmd with a
# minimal slurm.conf written here), the job array that `otoatlas batch --emit-sbatch` writes
# submitted on a small cohort of phantom cases, the shards merged by `otoatlas cohort-report`,
# and every package verified. Needs root (the daemons) and Debian's slurm-wlm and munge.
#
#   bash scripts/slurm-test.sh [OTOATLAS_BINARY]     (default: target/debug/otoatlas)
#
# Bounded: the whole test gives up after 10 minutes; the daemons are stopped on every exit.
set -euo pipefail
cd "$(dirname "$0")/.."
exe=$(realpath "${1:-target/debug/otoatlas}")
[ -x "$exe" ] || { echo "slurm-test: no otoatlas binary at $exe (build it first)" >&2; exit 2; }
if [ "$(id -u)" -ne 0 ]; then
    echo "slurm-test: needs root to start the Slurm daemons" >&2
    exit 2
fi
for cmd in munged slurmctld slurmd sbatch; do
    command -v "$cmd" >/dev/null || { echo "slurm-test: $cmd is missing (apt-get install slurm-wlm munge)" >&2; exit 2; }
done

work=$(mktemp -d)
export SLURM_CONF=$work/slurm.conf
pids=()
cleanup() {
    scancel --user=root >/dev/null 2>&1 || true
    for p in "${pids[@]}"; do kill "$p" 2>/dev/null || true; done
    pkill -f "slurmctld -D -f $SLURM_CONF" 2>/dev/null || true
    pkill -f "slurmd -D -f $SLURM_CONF" 2>/dev/null || true
    wait 2>/dev/null || true
    rm -rf "$work" 2>/dev/null || true
}
trap cleanup EXIT
fail() {
    echo "slurm-test: FAILED: $*" >&2
    for log in "$work"/log/*.log; do echo "--- $log" >&2; tail -20 "$log" >&2; done
    exit 1
}

# munge: the key the package made (or a new one), the daemon if it is not running
if [ ! -s /etc/munge/munge.key ]; then
    mungekey --create >/dev/null 2>&1 || dd if=/dev/urandom of=/etc/munge/munge.key bs=1 count=128 2>/dev/null
    chown munge:munge /etc/munge/munge.key && chmod 400 /etc/munge/munge.key
fi
mkdir -p /run/munge && chown munge:munge /run/munge
pgrep -x munged >/dev/null || su -s /bin/sh munge -c /usr/sbin/munged || /usr/sbin/munged --force

host=$(hostname -s)
mkdir -p "$work/spool" "$work/state" "$work/log"
cat >"$SLURM_CONF" <<EOF
ClusterName=otoatlas-test
SlurmctldHost=$host(127.0.0.1)
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
SelectType=select/cons_tres
SelectTypeParameters=CR_Core
ReturnToService=2
StateSaveLocation=$work/state
SlurmdSpoolDir=$work/spool
SlurmctldPidFile=$work/slurmctld.pid
SlurmdPidFile=$work/slurmd.pid
SlurmctldLogFile=$work/log/slurmctld.log
SlurmdLogFile=$work/log/slurmd.log
MpiDefault=none
NodeName=$host NodeAddr=127.0.0.1 CPUs=$(nproc) State=UNKNOWN
PartitionName=test Nodes=$host Default=YES MaxTime=30 State=UP
EOF
slurmctld -D -f "$SLURM_CONF" >/dev/null 2>&1 & pids+=($!)
slurmd -D -f "$SLURM_CONF" >/dev/null 2>&1 & pids+=($!)
for _ in $(seq 60); do
    sinfo -h -o %T 2>/dev/null | grep -q idle && break
    sleep 1
done
sinfo -h -o %T 2>/dev/null | grep -q idle || fail "the node never came up"

# a small cohort of phantoms, the emitted job array, the merge
"$exe" --quiet phantom --out "$work/cohort" --cases 3 --seed 4242 --spacing 0.3 >/dev/null
"$exe" --quiet batch "$work/cohort" --out "$work/out" --jobs 1 --emit-sbatch "$work/cohort.sbatch" >/dev/null
grep -q '^#SBATCH --array=0-2$' "$work/cohort.sbatch" || fail "the script has no 3-task array"
timeout 600 sbatch --wait --quiet "$work/cohort.sbatch" || fail "the job array failed (logs: $work/out/slurm)"
"$exe" cohort-report "$work/out" --json >"$work/cohort.json" || fail "cohort-report exit $?"
python3 - "$work" <<'PY' || fail "the merged cohort is wrong"
import json, sys, pathlib
work = pathlib.Path(sys.argv[1])
cohort = json.loads((work / "cohort.json").read_text())
assert cohort["passed"], cohort
assert cohort["counts"] == {"cases": 3, "ok": 3, "failed": 0, "missing": 0}, cohort["counts"]
logs = sorted((work / "out" / "slurm").glob("*.log"))
assert len(logs) == 3, f"expected one log per array task, got {logs}"
for case in cohort["cases"]:
    assert case["report"], case
    assert (work / "out" / case["report"]).is_file(), case
PY
for package in "$work"/out/cases/*/package; do
    "$exe" --quiet verify "$package" >/dev/null || fail "verify rejected $package"
done
echo "slurm-test: ok (3 phantom cases as a 3-task job array, merged and verified)"
