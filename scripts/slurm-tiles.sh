#!/usr/bin/env bash
# Render farm recipe: a scene rendered as TX × TY tiles by a Slurm array job (one tile per
# task, `lancer render --crop`), merged (`lancer merge`) and compared with a full render.
# For a try on one machine it starts a one-node Slurm cluster on localhost (munged,
# slurmctld, slurmd with a minimal slurm.conf in a temporary folder), installing slurm-wlm
# and munge with apt when they are missing, and stops the daemons it started at the end.
# On a real cluster, keep the `job` script and the sbatch/merge lines only.
#
# Usage: scripts/slurm-tiles.sh [SCENE] [WIDTH] [HEIGHT] [TILES_X] [TILES_Y] [SPP]
# Environment: LANCER (binary, default target/release/lancer), DEVICE (auto|gpu|cpu, default
# auto), OUT (output folder, default a new temporary one).
set -euo pipefail
cd "$(dirname "$0")/.."

SCENE=$(realpath "${1:-scenes/cornell.toml}")
W=${2:-160}
H=${3:-120}
TX=${4:-2}
TY=${5:-2}
SPP=${6:-4}
DEVICE=${DEVICE:-auto}
LANCER=$(realpath "${LANCER:-target/release/lancer}")
N=$((TX * TY))
[ -x "$LANCER" ] || { echo "no lancer binary at $LANCER: cargo build --release" >&2; exit 2; }

if ! command -v slurmctld >/dev/null || ! command -v munged >/dev/null; then
  echo "== installing slurm-wlm and munge (apt)"
  [ "$(id -u)" -eq 0 ] || { echo "run as root to install slurm-wlm and munge" >&2; exit 2; }
  export DEBIAN_FRONTEND=noninteractive
  apt-get update -qq
  apt-get install -y -qq slurm-wlm munge >/dev/null
fi

WORK=$(mktemp -d /tmp/lancer-slurm.XXXXXX)
OUT=${OUT:-$WORK/out}
mkdir -p "$OUT" "$WORK/state" "$WORK/spool"
NODE=$(hostname -s)
STARTED=()

stop() {
  for pid in "${STARTED[@]}"; do kill "$pid" 2>/dev/null || true; done
  echo "== stopped the daemons started here; logs in $WORK"
}
trap stop EXIT

echo "== one-node cluster on $NODE in $WORK"
if ! pgrep -x munged >/dev/null; then
  [ -s /etc/munge/munge.key ] || mungekey --create --keyfile /etc/munge/munge.key 2>/dev/null \
    || /usr/sbin/create-munge-key -f
  chown munge:munge /etc/munge/munge.key && chmod 400 /etc/munge/munge.key
  mkdir -p /run/munge /var/log/munge /var/lib/munge
  chown munge:munge /run/munge /var/log/munge /var/lib/munge
  runuser -u munge -- /usr/sbin/munged
  STARTED+=("$(cat /run/munge/munged.pid)")
fi

cat >"$WORK/slurm.conf" <<EOF
ClusterName=lancer
SlurmctldHost=$NODE(127.0.0.1)
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
CredType=cred/munge
StateSaveLocation=$WORK/state
SlurmdSpoolDir=$WORK/spool
SlurmctldPidFile=$WORK/slurmctld.pid
SlurmdPidFile=$WORK/slurmd.pid
SlurmctldLogFile=$WORK/slurmctld.log
SlurmdLogFile=$WORK/slurmd.log
SlurmctldPort=6817
SlurmdPort=6818
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
JobCompType=jobcomp/none
MpiDefault=none
SchedulerType=sched/builtin
SelectType=select/cons_tres
SelectTypeParameters=CR_Core
ReturnToService=2
NodeName=$NODE NodeAddr=127.0.0.1 CPUs=$(nproc) State=UNKNOWN
PartitionName=tiles Nodes=$NODE Default=YES MaxTime=INFINITE State=UP
EOF
export SLURM_CONF=$WORK/slurm.conf
slurmctld -f "$SLURM_CONF"
STARTED+=("$(sleep 1; cat "$WORK/slurmctld.pid")")
slurmd -f "$SLURM_CONF" -N "$NODE"
STARTED+=("$(sleep 1; cat "$WORK/slurmd.pid")")
for _ in $(seq 30); do sinfo -h -o %T 2>/dev/null | grep -qx idle && break; sleep 1; done
sinfo

# The job: task k renders tile (k mod TX, k div TX) of a TX × TY grid.
cat >"$WORK/tile.sh" <<EOF
#!/usr/bin/env bash
set -euo pipefail
k=\$SLURM_ARRAY_TASK_ID
i=\$((k % $TX)); j=\$((k / $TX))
x0=\$((i * $W / $TX)); x1=\$(((i + 1) * $W / $TX))
y0=\$((j * $H / $TY)); y1=\$(((j + 1) * $H / $TY))
exec "$LANCER" -q render "$SCENE" --width $W --height $H --spp $SPP --device $DEVICE \\
  --crop \$x0 \$y0 \$x1 \$y1 -o "$OUT/tile-\$k.exr"
EOF
chmod +x "$WORK/tile.sh"

echo "== sbatch: $N tiles of $SCENE at ${W}x$H, $SPP spp"
JOB=$(sbatch --parsable --array=0-$((N - 1)) --cpus-per-task=1 \
  --output="$OUT/tile-%a.log" --wait "$WORK/tile.sh") || {
  echo "the array job failed: see $OUT/tile-*.log" >&2
  cat "$OUT"/tile-*.log >&2 || true
  exit 1
}
echo "job $JOB done"
cat "$OUT"/tile-*.log

echo "== merge"
"$LANCER" merge "$OUT"/tile-*.exr -o "$OUT/merged.exr"

echo "== full render and comparison"
"$LANCER" -q render "$SCENE" --width "$W" --height "$H" --spp "$SPP" --device "$DEVICE" \
  -o "$OUT/full.exr"
"$LANCER" compare "$OUT/full.exr" "$OUT/merged.exr" --threshold 0
if cmp -s "$OUT/full.exr" "$OUT/merged.exr"; then
  echo "merged.exr and full.exr are the same file, byte for byte"
else
  echo "merged.exr and full.exr differ in bytes" >&2
  exit 1
fi
