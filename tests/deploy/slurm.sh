#!/usr/bin/env bash
# The farm under Slurm on a one-node cluster made on this machine: a private munged (generated key, run as the munge
# user) and slurmctld + slurmd on free ports with state in a temporary folder. deploy/slurm/coordinator.sbatch runs
# the coordinator as a Slurm job, deploy/slurm/workers.sbatch fans 3 workers out as a job array, `tessera submit`
# renders scenes/cbox_area_light.json through them over HTTPS with client certificates (a throwaway CA made here), and
# the EXR must be bitwise identical to a single-process render. `scancel --batch --signal=HUP` must reach the
# coordinator (it re-reads its certificate); scancel must then stop every worker cleanly (SIGTERM: exit 0) and the
# coordinator too.
# Needs root and Debian's slurm-wlm + munge (deploy/install-deps.sh); anything missing is a failure, never a skip.
# Arguments: TESSERA EXR_COMPARE SOURCE_DIR. Every daemon is stopped on exit, by pid.
set -euo pipefail
# shellcheck source-path=SCRIPTDIR source=../lib/proc.sh
source "$(dirname "$0")/../lib/proc.sh"
# shellcheck source-path=SCRIPTDIR source=../lib/tls.sh
source "$(dirname "$0")/../lib/tls.sh"
TESSERA=$(realpath "$1")
EXR_COMPARE=$(realpath "$2")
SRC=$(realpath "$3")
DEADLINE=$((SECONDS + 100))   # the whole test, daemons included; ctest's TIMEOUT is the hard stop behind it

fail() {
  echo "FAIL: $*" >&2
  FAILED=1
  local f
  for f in "${WORK:-/nonexistent}"/*.log "${WORK:-/nonexistent}"/slurm/*.log; do
    [ -f "$f" ] && { echo "--- $f" >&2; tail -n 30 "$f" >&2; }
  done
  exit 1
}

# Prerequisites: a clear failure for each missing piece.
[ "$(id -u)" = 0 ] || fail "must run as root (slurmd runs jobs as their user, munged as the munge user); run deploy/test.sh as root"
for tool in munged setpriv slurmctld slurmd sbatch squeue sinfo scancel scontrol python3; do
  command -v "$tool" >/dev/null || fail "'$tool' not found: install Debian's slurm-wlm and munge (bash deploy/install-deps.sh)"
done
id munge >/dev/null 2>&1 || fail "no 'munge' user: the munge package is not installed properly"

WORK=$(mktemp -d "${TMPDIR:-/tmp}/tessera-slurm-test.XXXXXX")
chmod 755 "$WORK"   # munged (as munge) must reach its folder below
FAILED=0
DAEMONS=()          # pids of munged, slurmctld, slurmd, in start order
JOBS=()             # Slurm job ids submitted
export SLURM_CONF="$WORK/slurm/slurm.conf"

# alive_in_work: pids of processes whose command line names this test's folder (job scripts' tessera processes).
alive_in_work() {
  local d
  for d in /proc/[0-9]*; do
    { tr '\0' ' ' <"$d/cmdline"; } 2>/dev/null | grep -qF -- "$WORK" && echo "${d#/proc/}"
  done
  return 0
}

cleanup() {
  set +e
  local p j i rev=()
  for j in "${JOBS[@]}"; do scancel "$j" 2>/dev/null; done
  # Let Slurm stop the jobs itself (workers finish on SIGTERM), for at most 15 s.
  for _ in $(seq 150); do
    [ ${#JOBS[@]} = 0 ] && break
    [ -z "$(squeue -h -j "$(IFS=,; echo "${JOBS[*]}")" 2>/dev/null)" ] && break
    sleep 0.1
  done
  # The daemons in reverse start order (slurmd, slurmctld, munged): 5 s for SIGTERM, then SIGKILL.
  for ((i = ${#DAEMONS[@]} - 1; i >= 0; i--)); do rev+=("${DAEMONS[i]}"); done
  stop_pids 50 "${rev[@]}"
  # Anything a job left behind (it names $WORK on its command line), by pid.
  for p in $(alive_in_work); do [ "$p" != $$ ] && kill -KILL "$p" 2>/dev/null; done
  if [ "$FAILED" = 0 ]; then rm -rf "$WORK"; else echo "logs kept in $WORK" >&2; fi
}
trap cleanup EXIT
trap 'fail "interrupted"' INT TERM

# wait_until SECONDS DESCRIPTION COMMAND...: polls every 0.2 s; fails the test with DESCRIPTION on timeout.
wait_until() {
  local limit=$((SECONDS + $1)) what=$2
  shift 2
  while ! "$@"; do
    [ $SECONDS -lt $limit ] && [ $SECONDS -lt $DEADLINE ] || fail "timed out waiting for $what"
    sleep 0.2
  done
}

free_port() { python3 -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])'; }

# --- munge: a generated key owned by munge, mode 400; munged started as the munge user on a private socket.
mkdir -p "$WORK/munge" "$WORK/munge-run" "$WORK/slurm/state" "$WORK/slurm/spool"
dd if=/dev/urandom of="$WORK/munge/munge.key" bs=1024 count=1 status=none
chown -R munge:munge "$WORK/munge" "$WORK/munge-run"
chmod 700 "$WORK/munge"
chmod 755 "$WORK/munge-run"   # the socket's folder: every client must reach it
chmod 400 "$WORK/munge/munge.key"
MUNGE_SOCKET="$WORK/munge-run/munge.socket"
setpriv --reuid=munge --regid=munge --init-groups munged --foreground --key-file="$WORK/munge/munge.key" \
  --socket="$MUNGE_SOCKET" --pid-file="$WORK/munge/munged.pid" --seed-file="$WORK/munge/munged.seed" \
  --log-file="$WORK/munge/munged.log" >"$WORK/munged.log" 2>&1 &
DAEMONS+=($!)
wait_until 10 "munged's socket" test -S "$MUNGE_SOCKET"

# --- slurm.conf: a one-node cluster on free ports, everything under $WORK.
HOST=$(hostname -s)
CTLD_PORT=$(free_port)
SLURMD_PORT=$(free_port)
[ "$CTLD_PORT" != "$SLURMD_PORT" ] || SLURMD_PORT=$(free_port)
cat >"$SLURM_CONF" <<CONF
ClusterName=tessera-test
SlurmctldHost=$HOST(127.0.0.1)
SlurmUser=root
SlurmctldPort=$CTLD_PORT
SlurmdPort=$SLURMD_PORT
AuthType=auth/munge
CredType=cred/munge
AuthInfo=socket=$MUNGE_SOCKET
StateSaveLocation=$WORK/slurm/state
SlurmdSpoolDir=$WORK/slurm/spool
SlurmctldPidFile=$WORK/slurm/slurmctld.pid
SlurmdPidFile=$WORK/slurm/slurmd.pid
SlurmctldLogFile=$WORK/slurm/slurmctld.log
SlurmdLogFile=$WORK/slurm/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
SelectType=select/cons_tres
SelectTypeParameters=CR_Core
MpiDefault=none
MailProg=/bin/true
ReturnToService=2
KillWait=20
SchedulerParameters=sched_interval=1
NodeName=$HOST NodeAddr=127.0.0.1 CPUs=$(nproc) State=UNKNOWN
# Oversubscribed so the coordinator and three 1-CPU workers run together on a 2-core machine.
PartitionName=test Nodes=$HOST Default=YES MaxTime=10 State=UP OverSubscribe=FORCE:4
CONF

slurmctld -D -c -f "$SLURM_CONF" >"$WORK/slurmctld.log" 2>&1 &
DAEMONS+=($!)
slurmd -D -f "$SLURM_CONF" -N "$HOST" >"$WORK/slurmd.log" 2>&1 &
DAEMONS+=($!)
node_idle() { sinfo -h -n "$HOST" -o %T 2>/dev/null | grep -qx idle; }
wait_until 30 "the node to register idle with slurmctld" node_idle

# --- TLS: a throwaway CA, the coordinator's certificate for 127.0.0.1, and one client certificate for all.
mkdir -p "$WORK/tls"
make_ca "$WORK/tls" ca
make_cert "$WORK/tls" ca coordinator "IP:127.0.0.1" serverAuth
make_cert "$WORK/tls" ca member "DNS:member" clientAuth
TLS_CLIENT=(--ca-file "$WORK/tls/ca.pem" --tls-cert "$WORK/tls/member.pem" --tls-key "$WORK/tls/member.key")

# --- the coordinator as a Slurm job, then the workers as a job array pointing at it.
sbatch_job() { sbatch --parsable --chdir="$WORK" "$@" | cut -d';' -f1; }
COORD=$(TESSERA_BIN="$TESSERA" TESSERA_DATA="$WORK/data" TESSERA_LISTEN=127.0.0.1:0 TESSERA_URL_FILE="$WORK/url" \
  TESSERA_TLS_CERT="$WORK/tls/coordinator.pem" TESSERA_TLS_KEY="$WORK/tls/coordinator.key" \
  TESSERA_TLS_CLIENT_CA="$WORK/tls/ca.pem" \
  sbatch_job --cpus-per-task=1 --output="$WORK/coordinator.log" "$SRC/deploy/slurm/coordinator.sbatch") || fail "sbatch coordinator"
JOBS+=("$COORD")
WORKERS=$(TESSERA_BIN="$TESSERA" TESSERA_COORDINATOR_FILE="$WORK/url" TESSERA_CACHE="$WORK/cache" \
  TESSERA_CA_FILE="$WORK/tls/ca.pem" TESSERA_TLS_CERT="$WORK/tls/member.pem" TESSERA_TLS_KEY="$WORK/tls/member.key" \
  sbatch_job --array=0-2 --output="$WORK/worker-%a.log" "$SRC/deploy/slurm/workers.sbatch") || fail "sbatch workers"
JOBS+=("$WORKERS")
wait_until 30 "the coordinator job's URL file" test -s "$WORK/url"
URL=$(cat "$WORK/url")
[[ "$URL" == https://127.0.0.1:* ]] || fail "the URL file says $URL, not https://127.0.0.1:PORT"
workers_running() { [ "$(squeue -h -j "$WORKERS" -t RUNNING -o %i | wc -l)" = 3 ]; }
wait_until 30 "3 running worker tasks" workers_running

# --- render through the farm and compare with a single-process render.
SCENE="$SRC/scenes/cbox_area_light.json"
"$TESSERA" render "$SCENE" -o "$WORK/ref.exr" --spp 2 -q >"$WORK/render.log" 2>&1 || fail "single-process render"
timeout $((DEADLINE - SECONDS)) "$TESSERA" submit "$SCENE" --coordinator "$URL" "${TLS_CLIENT[@]}" --spp 2 --tile 32 -o "$WORK/farm.exr" -q \
  >"$WORK/submit.log" 2>&1 || fail "submit through the Slurm farm failed"
"$EXR_COMPARE" "$WORK/ref.exr" "$WORK/farm.exr" || fail "the Slurm farm's EXR differs from the single-process render"

# --- SIGHUP through Slurm reaches the coordinator, which re-reads its certificate and keeps serving.
scancel --batch --signal=HUP "$COORD"
reloaded() { grep -q 'TLS certificate and key re-read' "$WORK/coordinator.log"; }
wait_until 20 "the coordinator to re-read its certificate after scancel --signal=HUP" reloaded

# --- scancel: every worker finishes (SIGTERM -> exit 0) and reports its tiles; all 64 tiles came from them.
scancel "$WORKERS"
workers_gone() { [ -z "$(squeue -h -j "$WORKERS" -o %i)" ]; }
wait_until 30 "the worker array to end after scancel" workers_gone
uploaded=0
for t in 0 1 2; do
  line=$(grep -E 'stopping: [0-9]+ tiles uploaded' "$WORK/worker-$t.log") || fail "worker task $t did not stop cleanly"
  n=$(sed -E 's/.*stopping: ([0-9]+) tiles uploaded.*/\1/' <<<"$line")
  uploaded=$((uploaded + n))
done
[ "$uploaded" -ge 64 ] || fail "the Slurm workers uploaded $uploaded tiles, fewer than the job's 64"
scancel "$COORD"
coord_gone() { [ -z "$(squeue -h -j "$COORD" -o %i)" ]; }
wait_until 30 "the coordinator job to end after scancel" coord_gone
grep -q 'tessera serve exited with status 0' "$WORK/coordinator.log" || fail "the coordinator did not exit cleanly"
[ ! -e "$WORK/url" ] || fail "the coordinator job left its URL file behind"
echo "PASS: 3 Slurm array workers rendered $uploaded tiles, bitwise identical to the single-process render ($SECONDS s)"
