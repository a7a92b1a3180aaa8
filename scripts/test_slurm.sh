#!/bin/bash
# `make test-slurm` (docs/batch.md): `kinesplat batch --scheduler slurm` on a real one-node Slurm
# cluster on loopback. Installs slurm-wlm and munge (Debian) where missing, starts munged, slurmctld
# and slurmd with their configuration, state and logs in a temporary folder, runs a batch of three
# small synthetic photos with few iterations (one of them broken on purpose), checks the two
# avatars and the reported failure, runs batch again to show that only the failed item is handed
# over again, and stops the daemons by their pid files.
#
#   scripts/test_slurm.sh [KINESPLAT]      (default build/kinesplat)
# Environment: KS_SLURM_NO_INSTALL=1 (do not apt-get), KS_SLURM_KEEP=1 (keep the temporary folder),
#   KS_SLURM_ITERS / KS_SLURM_FRAMES (the items' --iters / --frames; default 30 / 4),
#   KS_SLURM_TIMEOUT (seconds to wait for each batch; default 1800).
# Exit status: 0 passed, 1 failed, 77 skipped (not root, or Slurm missing with KS_SLURM_NO_INSTALL).
set -uo pipefail

KS=$(readlink -f "${1:-build/kinesplat}")
ITERS=${KS_SLURM_ITERS:-30}
FRAMES=${KS_SLURM_FRAMES:-4}
TIMEOUT=${KS_SLURM_TIMEOUT:-1800}

say() { echo "test-slurm: $*"; }
fail() {
  echo "test-slurm: FAILED: $*" >&2
  exit 1
}

[ -x "$KS" ] || fail "no kinesplat program at $KS (make build first)"
if [ "$(id -u)" -ne 0 ]; then
  say "SKIPPED: slurmctld and slurmd run as root here (run as root, or with sudo)"
  exit 77
fi
have_slurm() { command -v slurmctld && command -v slurmd && command -v sbatch && command -v munged; } >/dev/null 2>&1
if ! have_slurm; then
  if [ -n "${KS_SLURM_NO_INSTALL:-}" ]; then
    say "SKIPPED: Slurm is not installed (slurm-wlm, munge); make test-slurm installs it"
    exit 77
  fi
  say "installing slurm-wlm and munge (apt-get)"
  apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq \
    --no-install-recommends slurm-wlm munge >/dev/null || fail "apt-get install slurm-wlm munge"
  have_slurm || fail "slurm-wlm / munge installed but slurmctld, slurmd, sbatch or munged missing"
fi

T=$(mktemp -d /tmp/ks-slurm.XXXXXX) || fail "mktemp"
chmod 755 "$T"
mkdir -p "$T/state" "$T/spool" "$T/work"

stop_daemons() {
  # By their pid files, slurmd first; each waited for.
  for name in slurmd slurmctld munged; do
    local pf="$T/$name.pid"
    [ -s "$pf" ] || continue
    local pid
    pid=$(cat "$pf")
    if kill "$pid" 2>/dev/null; then
      for _ in $(seq 50); do kill -0 "$pid" 2>/dev/null || break; sleep 0.2; done
      kill -0 "$pid" 2>/dev/null && { say "$name ($pid) still running, sending KILL"; kill -9 "$pid"; }
      say "stopped $name (pid $pid)"
    fi
  done
}
cleanup() {
  stop_daemons
  if [ -n "${KS_SLURM_KEEP:-}" ]; then say "kept $T"; else rm -rf "$T"; fi
}
trap cleanup EXIT

# Two free loopback ports.
port_free() { ! (exec 3<>"/dev/tcp/127.0.0.1/$1") 2>/dev/null; }
pick_port() {
  local p
  for _ in $(seq 100); do
    p=$((20000 + RANDOM % 20000))
    port_free "$p" && port_free "$((p + 1))" && { echo "$p"; return; }
  done
  fail "no free port"
}
PORT=$(pick_port)
HOST=$(hostname -s)
CPUS=$(nproc)
MEM_MB=$(awk '/MemTotal/ {print int($2 / 1024 * 0.9)}' /proc/meminfo)

# munge: a generated key, its socket in the temporary folder.
dd if=/dev/urandom of="$T/munge.key" bs=1024 count=1 status=none && chmod 600 "$T/munge.key"
munged --key-file="$T/munge.key" --socket="$T/munge.sock" --pid-file="$T/munged.pid" \
  --log-file="$T/munged.log" --seed-file="$T/munged.seed" --force 2>"$T/munged.err" ||
  fail "munged did not start: $(cat "$T/munged.err" "$T/munged.log" 2>/dev/null | tail -3)"

cat >"$T/slurm.conf" <<EOF
ClusterName=kstest
SlurmctldHost=$HOST(127.0.0.1)
SlurmctldPort=$PORT
SlurmdPort=$((PORT + 1))
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
CredType=cred/munge
AuthInfo=socket=$T/munge.sock
StateSaveLocation=$T/state
SlurmdSpoolDir=$T/spool
SlurmctldPidFile=$T/slurmctld.pid
SlurmdPidFile=$T/slurmd.pid
SlurmctldLogFile=$T/slurmctld.log
SlurmdLogFile=$T/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
SelectType=select/cons_tres
SelectTypeParameters=CR_Core_Memory
SchedulerType=sched/backfill
ReturnToService=2
MpiDefault=none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
SlurmctldTimeout=30
SlurmdTimeout=30
NodeName=$HOST NodeAddr=127.0.0.1 CPUs=$CPUS RealMemory=$MEM_MB State=UNKNOWN
PartitionName=debug Nodes=$HOST Default=YES MaxTime=INFINITE State=UP
EOF
export SLURM_CONF="$T/slurm.conf"

slurmctld -i -f "$SLURM_CONF" || fail "slurmctld did not start: $(tail -5 "$T/slurmctld.log")"
slurmd -f "$SLURM_CONF" || fail "slurmd did not start: $(tail -5 "$T/slurmd.log")"
for i in $(seq 60); do
  state=$(sinfo -h -n "$HOST" -o %T 2>/dev/null | head -1)
  [ "$state" = idle ] && break
  sleep 1
done
[ "$state" = idle ] || fail "node $HOST not idle after 60 s (state '$state'): $(tail -5 "$T/slurmctld.log")"
say "cluster up: $HOST on 127.0.0.1:$PORT, $CPUS CPUs, ${MEM_MB} MB; $(sinfo --version)"

# The cluster runs a 2-task array before kinesplat's turn.
job=$(sbatch --parsable --array=0-1 --output="$T/check_%a.out" --wrap 'echo task $SLURM_ARRAY_TASK_ID on $(hostname)') ||
  fail "sbatch of a trivial array"
for i in $(seq 60); do [ -z "$(squeue -h -j "$job" 2>/dev/null)" ] && break; sleep 1; done
cat "$T"/check_0.out "$T"/check_1.out 2>/dev/null | grep -q "task 1 on" || fail "the trivial array did not run"
say "a trivial 2-task array ran (job $job)"

if [ -n "${KS_SLURM_CLUSTER_ONLY:-}" ]; then say "PASSED (cluster only)"; exit 0; fi

# Three small synthetic photos; the second is not an image at all.
W="$T/work"
for seed in 301 302; do
  "$KS" synth --seed "$seed" --out "$W/synth$seed" --size 256x384 --frames 1 >/dev/null 2>&1 ||
    fail "kinesplat synth --seed $seed"
done
echo "this is not a PNG" >"$W/broken.png"
# Per-item options are `create`'s: few iterations and poses, small videos, and synth's own
# keypoints and mask for the two people (no detector needed on the node).
opts="$ITERS,$FRAMES,none,128x192"
cat >"$W/manifest.csv" <<EOF
id,photo,iters,frames,motions,size,keypoints-file,keypoints,keypoints-pixel-centre,mask
alice,synth301/photo.png,$opts,$W/synth301/photo_keypoints.json,joints,0.5,$W/synth301/photo_mask.png
broken,broken.png,$opts,,,,
bob,synth302/photo.png,$opts,$W/synth302/photo_keypoints.json,joints,0.5,$W/synth302/photo_mask.png
EOF
say "manifest $W/manifest.csv:"
sed 's/^/  /' "$W/manifest.csv"

wait_batch() {  # the batch's items until none is queued or running
  local t0=$SECONDS
  while true; do
    local left
    left=$("$KS" batch status "$W/out" --json | grep -cE '"state": "(queued|running)"')
    [ "$left" -eq 0 ] && return 0
    [ $((SECONDS - t0)) -gt "$TIMEOUT" ] && fail "batch not finished after $TIMEOUT s"
    sleep 2
  done
}

say "\$ kinesplat batch manifest.csv --out out --scheduler slurm"
( cd "$W" && "$KS" batch manifest.csv --out out --scheduler slurm ) || fail "batch (first run)"
wait_batch
say "\$ kinesplat batch status out"
( cd "$W" && "$KS" batch status out )
status=$("$KS" batch status "$W/out" --json)
for id in alice bob; do
  [ -s "$W/out/items/$id/avatar.ksavatar" ] || fail "no avatar for $id ($(tail -3 "$W/out/items/$id/create.log"))"
done
[ "$(echo "$status" | grep -c '"state": "done"')" -eq 2 ] || fail "expected 2 items done"
[ "$(echo "$status" | grep -c '"state": "failed"')" -eq 1 ] || fail "expected 1 item failed"
echo "$status" | grep -q '"error": ".*broken.png' || fail "the failure does not name broken.png"
say "the failed item's task output (slurm/%A_%a.out):"
sed 's/^/  /' "$W"/out/slurm/*_1.out

say "\$ kinesplat batch manifest.csv --out out --scheduler slurm   (again)"
again=$(cd "$W" && "$KS" batch manifest.csv --out out --scheduler slurm) || fail "batch (second run)"
echo "$again"
echo "$again" | grep -q "3 items, 2 done; 1 to submit" || fail "the second run hands over more than the failed item"
grep -q '^#SBATCH --array=1$' "$W/out/batch.sbatch" || fail "the second array is not row 1 alone"
say "the second batch.sbatch: $(grep '^#SBATCH --array' "$W/out/batch.sbatch")"
wait_batch
say "\$ kinesplat batch status out"
( cd "$W" && "$KS" batch status out )

# The same three items as a Kubernetes Indexed Job (written only: no cluster here). The pods would
# mount a volume at the work folder, so that they see the photos and the output at these paths.
say "\$ kinesplat batch manifest.csv --out out-k8s --scheduler k8s --image kinesplat:0.1 --volume avatars:$W"
( cd "$W" && "$KS" batch manifest.csv --out out-k8s --scheduler k8s --image kinesplat:0.1 \
    --volume "avatars:$W" ) || fail "batch --scheduler k8s"
grep -q '"completionMode": "Indexed"' "$W/out-k8s/batch.k8s.json" || fail "no Indexed Job"
cat "$W/out-k8s/batch.k8s.json"
say "PASSED"
