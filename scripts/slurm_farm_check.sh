#!/usr/bin/env bash
# The README's farm run on a real Slurm: starts a single-node cluster on this machine (Debian's
# slurm-wlm and munge, daemons run as root, state in a temporary folder), submits
# scripts/farm.sbatch for SCENE with its outputs in a copy of the scene's folder layout, waits,
# and requires every file the array wrote to be byte-identical to the local run's in
# LOCAL_EXPORTS (reports are left out: they hold timings).
#
#   bash scripts/slurm_farm_check.sh BINARY SCENE LOCAL_EXPORTS
set -euo pipefail
bin="$(realpath "$1")"; scene="$(realpath "$2")"; local_exports="$(realpath "$3")"
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"

work="$(mktemp -d)"
state="$work/slurm"
mkdir -p "$state/spool" "$state/ctld" "$work/log"
node="$(hostname -s)"
cat > "$state/slurm.conf" <<CONF
ClusterName=scenebake-ci
SlurmctldHost=$node
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
StateSaveLocation=$state/ctld
SlurmdSpoolDir=$state/spool
SlurmctldPidFile=$state/slurmctld.pid
SlurmdPidFile=$state/slurmd.pid
SlurmctldLogFile=$work/log/slurmctld.log
SlurmdLogFile=$work/log/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
SchedulerType=sched/backfill
SelectType=select/cons_tres
SelectTypeParameters=CR_CPU
ReturnToService=2
MpiDefault=none
NodeName=$node CPUs=$(nproc) State=UNKNOWN
PartitionName=ci Nodes=$node Default=YES MaxTime=INFINITE State=UP
CONF
export SLURM_CONF="$state/slurm.conf"

cleanup() {
    pkill -F "$state/slurmd.pid" 2>/dev/null || true
    pkill -F "$state/slurmctld.pid" 2>/dev/null || true
}
trap cleanup EXIT
pgrep -x munged >/dev/null || { mkdir -p /run/munge && chown munge:munge /run/munge && runuser -u munge -- munged; }
slurmctld
slurmd
for _ in $(seq 60); do
    sinfo -h -o %T 2>/dev/null | grep -q idle && break
    sleep 1
done
sinfo

# The scene's folder layout: its folder copied, the folders beside it linked (but exports/), so
# `../meshes/...` resolves and `../exports/...` lands in this copy.
farm="$work/farm"
mkdir -p "$farm/exports"
scene_dir="$(dirname "$scene")"
for entry in "$(dirname "$scene_dir")"/*; do
    name="$(basename "$entry")"
    [ "$name" = exports ] || [ "$entry" = "$scene_dir" ] || ln -s "$entry" "$farm/$name"
done
cp -r "$scene_dir" "$farm/"
farm_scene="$farm/$(basename "$scene_dir")/$(basename "$scene")"

cd "$farm"
SCENEBAKE="$bin" sbatch --wait "$root/scripts/farm.sbatch" "$farm_scene"
for out in scenebake-*.out; do echo "== $out"; tail -n 5 "$out"; done

# Every file the array wrote, against the local run's.
reports="$(grep -oE '^report *= *"[^"]+"' "$farm_scene" | sed -E 's/.*"(.*)"/\1/' | xargs -rn1 basename)"
count=0
while IFS= read -r f; do
    name="$(basename "$f")"
    if grep -qxF "$name" <<<"$reports"; then continue; fi
    cmp "$f" "$local_exports/$name"
    count=$((count + 1))
done < <(find "$farm/exports" -type f | sort)
[ "$count" -gt 0 ] || { echo "error: the Slurm array wrote nothing" >&2; exit 1; }
echo "slurm_farm_check: $count files from the Slurm array are byte-identical to the local run"
