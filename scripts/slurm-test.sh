#!/usr/bin/env bash
# The Slurm test: a private single-node cluster (munged, slurmctld, slurmd on this host, with a
# slurm.conf in a temporary folder and nothing written under /etc), a 4-shard sweep submitted
# as the job array `syncroad sweep --emit-slurm` writes, the shards collected, and the merged
# table compared with a local run's table. The daemons are stopped by their PIDs.
#
# Usage: bash scripts/slurm-test.sh [SYNCROAD_BINARY]
# Prints "skipped: Slurm not installed" and exits 0 when slurmctld/slurmd/munged/sbatch are
# missing, so the caller can report the skip; any other failure exits non-zero.
set -euo pipefail
cd "$(dirname "$0")/.."
repo="$(pwd)"
bin="${1:-$repo/target/release/syncroad}"

for tool in slurmctld slurmd munged sbatch; do
    if ! command -v "$tool" >/dev/null 2>&1 && [ ! -x "/usr/sbin/$tool" ]; then
        echo "skipped: Slurm not installed ($tool not found; apt-get install slurm-wlm munge)"
        exit 0
    fi
done
export PATH="$PATH:/usr/sbin"

d="$(mktemp -d /tmp/syncroad-slurm.XXXXXX)"
chmod 755 "$d"
host="$(hostname -s)"
cpus="$(nproc)"
munge_pid=""
cleanup() {
    for f in "$d/slurmd.pid" "$d/slurmctld.pid"; do
        if [ -f "$f" ]; then kill "$(cat "$f")" 2>/dev/null || true; fi
    done
    if [ -n "$munge_pid" ]; then kill "$munge_pid" 2>/dev/null || true; fi
    # Wait for the daemons to go before removing their folder.
    for f in "$d/slurmd.pid" "$d/slurmctld.pid"; do
        if [ -f "$f" ]; then
            for _ in $(seq 50); do kill -0 "$(cat "$f" 2>/dev/null)" 2>/dev/null || break; sleep 0.1; done
        fi
    done
    rm -rf "$d"
}
trap cleanup EXIT

# MUNGE: refuses root and insecure paths; run it as the munge user on its own socket.
mkdir -p "$d/munge"
chown munge:munge "$d/munge"
chmod 755 "$d/munge"
for p in /etc/munge /var/lib/munge /var/log/munge /run/munge; do
    mkdir -p "$p"
    chown munge:munge "$p"
done
chmod 700 /etc/munge
if [ ! -f /etc/munge/munge.key ]; then
    dd if=/dev/urandom of=/etc/munge/munge.key bs=1 count=1024 status=none
    chown munge:munge /etc/munge/munge.key
    chmod 400 /etc/munge/munge.key
fi
if ! munge -n 2>/dev/null | unmunge 2>/dev/null | grep -q 'STATUS: *Success'; then
    su -s /bin/sh munge -c "munged --pid-file=$d/munge/munged.pid"
    for _ in $(seq 50); do [ -s "$d/munge/munged.pid" ] && break; sleep 0.1; done
    munge_pid="$(cat "$d/munge/munged.pid")"
fi
munge -n | unmunge | grep -q 'STATUS: *Success' || { echo "munge does not authenticate" >&2; exit 1; }

mkdir -p "$d/state" "$d/spool" "$d/log"
cat > "$d/slurm.conf" <<EOF
ClusterName=syncroadtest
SlurmctldHost=$host
AuthType=auth/munge
ProctrackType=proctrack/pgid
TaskPlugin=task/none
SelectType=select/cons_tres
SelectTypeParameters=CR_Core
SlurmUser=root
StateSaveLocation=$d/state
SlurmdSpoolDir=$d/spool
SlurmctldPidFile=$d/slurmctld.pid
SlurmdPidFile=$d/slurmd.pid
SlurmctldLogFile=$d/log/ctld.log
SlurmdLogFile=$d/log/d.log
ReturnToService=2
NodeName=$host CPUs=$cpus State=UNKNOWN
PartitionName=debug Nodes=$host Default=YES MaxTime=INFINITE State=UP
EOF
export SLURM_CONF="$d/slurm.conf"
slurmctld -f "$SLURM_CONF"
slurmd -f "$SLURM_CONF"
for _ in $(seq 100); do
    if sinfo -h -o '%T' 2>/dev/null | grep -q idle; then break; fi
    sleep 0.2
done
sinfo -h -o '%T' | grep -q idle || { echo "the Slurm node never became idle" >&2; cat "$d/log/ctld.log" "$d/log/d.log" >&2; exit 1; }

# The sweep: the Sugiyama ring in SUMO, gain scale × delay scale, 2 seeds (16 points).
spec="$d/spec.json"
cat > "$spec" <<EOF
{
  "name": "slurm-test",
  "base": "$repo/scenarios/sugiyama-ring.json",
  "backend": "sumo",
  "axes": [
    {"field": "scale.gain", "values": [0.5, 2.5]},
    {"field": "scale.delay", "values": [0.5, 2.0]},
    {"field": "horizon_s", "values": [60]}
  ],
  "runs": ["protocol", "krauss-0.9"],
  "seeds": [1, 2]
}
EOF
"$bin" sweep "$spec" --out "$d/local" --no-plots >"$d/local.log" 2>&1 || { cat "$d/local.log" >&2; exit 1; }

# A site option passes through to the script (here a harmless --partition).
"$bin" sweep "$spec" --out "$d/cluster" --emit-slurm "$d/jobs" --shards 4 --max-running 2 \
    --partition debug --time 00:10:00 >/dev/null
grep -q '^#SBATCH --array=0-3%2$' "$d/jobs/sweep.sbatch"
grep -q '^#SBATCH --partition=debug$' "$d/jobs/sweep.sbatch"
sbatch --wait "$d/jobs/sweep.sbatch" >/dev/null
sbatch --wait "$d/jobs/collect.sbatch" >/dev/null
if ! cmp -s "$d/local/results.csv" "$d/cluster/merged/results.csv"; then
    echo "the merged table differs from the local one:" >&2
    diff "$d/local/results.csv" "$d/cluster/merged/results.csv" >&2 || true
    exit 1
fi
rows="$(($(wc -l < "$d/local/results.csv") - 1))"
# A resubmitted array finds every shard finished.
again="$(sbatch --parsable --wait "$d/jobs/sweep.sbatch")"
again="${again%%;*}"
for i in 0 1 2 3; do
    grep -q "ran 0 (0 failed), 4 finished before" "$d/jobs/logs/${again}_$i.out" \
        || { echo "resubmitted task $i ran points again:" >&2; cat "$d/jobs/logs/${again}_$i.out" >&2; exit 1; }
done
echo "passed: Slurm ran the 4-shard sweep ($rows points); the collected table equals the local one"
