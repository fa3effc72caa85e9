#!/usr/bin/env bash
# The farm split (docs/farm.md) through a real scheduler: a private one-node
# Slurm cluster (munged, slurmctld, slurmd, all state in a temp folder) runs
#   * `fit cloth --shard i/3` as one array job, one task of which is killed
#     mid-fit and requeued by Slurm, and `merge` as a job depending on the
#     array (afterok); the merged preset must equal `fit cloth --shards 3`
#     (one process, no time budget) byte for byte;
#   * `synth --frames A:B` as an array job of three chunks; the frames must
#     equal one whole render of the range byte for byte.
# Usage: run_slurm_farm.sh FLOWVID SCRATCH_DIR CAPTURES_DIR
# Exit: 0 pass, 1 fail, 77 skipped (slurm-wlm or munge not installed, or no
# shared captures). A cluster that is installed but does not start is a failure.
set -uo pipefail

if (($# != 3)); then
  echo "usage: $0 FLOWVID SCRATCH_DIR CAPTURES_DIR" >&2
  exit 2
fi
flowvid=$(realpath -m "$1")
work=$(realpath -m "$2")
captures=$(realpath -m "$3")

SKIP=77
# The daemons live in sbin, which an ordinary user's PATH may lack.
export PATH="$PATH:/usr/sbin:/sbin"

start_us=${EPOCHREALTIME/./}
# Every wait ends by then, so that the teardown runs before ctest's TIMEOUT
# (300 s) would kill this script and leave the daemons behind.
overall_deadline=$((start_us + 240 * 1000000))
log() { printf '[%6.1fs] %s\n' "$(((${EPOCHREALTIME/./} - start_us) / 100000))e-1" "$*"; }
skip() { echo "SKIPPED: $*"; exit "$SKIP"; }

for tool in munged mungekey slurmctld slurmd sbatch squeue sinfo scontrol scancel; do
  command -v "$tool" >/dev/null ||
    skip "'$tool' is not installed: the Slurm farm test needs Debian's slurm-wlm and munge (bash scripts/bootstrap.sh installs them)"
done
capture="$captures/cloth-silk-static-1"
clip="$captures/video-waterfall-cascade"
for c in "$capture" "$clip"; do
  [[ -f $c/capture.json ]] || skip "$c is absent: the Slurm farm test fits and tracks the shared captures (../shared/captures)"
done
[[ -x $flowvid ]] || { echo "FAILED: $flowvid is not an executable" >&2; exit 1; }

# ---- the cluster, torn down whatever happens ---------------------------------
# A short path: munged's socket lives here (a Unix socket path has at most 107 bytes).
cluster=$(mktemp -d "${TMPDIR:-/tmp}/flowvid-slurm.XXXXXX")
chmod 755 "$cluster"  # munged refuses a socket folder that others cannot enter
# Where this runs inside a Slurm job or a site's defaults, the client
# commands would read those settings (SBATCH_PARTITION, ...): ours only.
for variable in $(compgen -e | grep -E '^(SLURM|SBATCH|SQUEUE|SINFO|SCONTROL|SCANCEL)_'); do unset "$variable"; done
export SLURM_CONF="$cluster/slurm.conf"
# Every process this test starts, the jobs included, carries this in its
# environment: the teardown's last sweep kills exactly those.
export FLOWVID_SLURM_TEST_CLUSTER="$cluster"
passed=0

own_processes() {  # (the subshell and its commands run without the variable)
  local pattern="FLOWVID_SLURM_TEST_CLUSTER=$cluster"
  (
    unset FLOWVID_SLURM_TEST_CLUSTER
    grep -slzxF "$pattern" /proc/[0-9]*/environ | cut -d/ -f3 | grep -vx "$$"
  )
}

stop_daemons() {  # SIGTERM to all, then SIGKILL to those still there after 5 s
  local pids=() pid i
  for pid in "$@"; do [[ -s $pid ]] && pids+=("$(<"$pid")"); done
  ((${#pids[@]})) || return 0
  kill -TERM "${pids[@]}" 2>/dev/null
  for ((i = 0; i < 50; i++)); do
    kill -0 "${pids[@]}" 2>/dev/null || return 0
    sleep 0.1
  done
  kill -KILL "${pids[@]}" 2>/dev/null
}

teardown() {
  local code=$? i left
  trap - EXIT INT TERM
  if [[ -s $cluster/slurmctld.pid ]] && kill -0 "$(<"$cluster/slurmctld.pid")" 2>/dev/null; then
    timeout 10 scancel --user="$(id -un)" 2>/dev/null
    # Let the cancelled jobs end before slurmd goes (else their slurmstepd lingers).
    for ((i = 0; i < 50; i++)); do
      [[ -z $(timeout 5 squeue -h -o %i 2>/dev/null) ]] && break
      sleep 0.2
    done
  fi
  if ((code != 0 && code != SKIP)); then
    for f in slurmctld.log slurmd.log munged.log; do
      [[ -f $cluster/$f ]] && { echo "---- $f (last 40 lines)"; tail -n 40 "$cluster/$f"; }
    done
    mkdir -p "$work" && cp "$cluster"/*.log "$cluster/slurm.conf" "$work/" 2>/dev/null
  fi
  stop_daemons "$cluster/slurmd.pid" "$cluster/slurmctld.pid" "$cluster/munged.pid"
  left=$(own_processes)
  if [[ -n $left ]]; then
    echo "teardown: killing leftover processes:"
    ps -o pid=,args= -p "$(echo $left | tr ' ' ,)"
    kill -KILL $left 2>/dev/null
  fi
  rm -rf "$cluster"
  if ((passed)); then rm -rf "$work"; elif ((code != SKIP)); then echo "the test's files are kept in $work"; fi
  log "cluster torn down"
  exit "$code"
}
trap teardown EXIT
trap 'exit 130' INT TERM

fail() {
  echo "FAILED: $*"
  local f
  for f in "$work"/logs/*.log; do [[ -f $f ]] && { echo "---- $f"; tail -n 30 "$f"; }; done
  exit 1
}

# Polls CMD every 0.2 s until it succeeds; fails after SECONDS (or at the
# overall deadline) with DESCRIPTION.
wait_for() {
  local description=$1 seconds=$2 deadline
  shift 2
  deadline=$((${EPOCHREALTIME/./} + seconds * 1000000))
  ((deadline < overall_deadline)) || deadline=$overall_deadline
  until "$@"; do
    ((${EPOCHREALTIME/./} < deadline)) || fail "timed out after ${seconds} s waiting for $description"
    sleep 0.2
  done
}

free_ports() {  # two TCP ports nobody listens on now
  /usr/bin/python3 -c '
import socket
s = [socket.socket() for _ in range(2)]
for x in s: x.bind(("127.0.0.1", 0))
print(*[x.getsockname()[1] for x in s])'
}

log "flowvid: $flowvid"
mungekey --create --keyfile="$cluster/munge.key" || fail "mungekey could not create a key"
munged --socket="$cluster/munge.sock" --key-file="$cluster/munge.key" --pid-file="$cluster/munged.pid" \
  --log-file="$cluster/munged.log" --seed-file="$cluster/munged.seed" ||
  fail "munged did not start ($(tail -n 3 "$cluster/munged.log" 2>/dev/null))"

read -r ctld_port slurmd_port < <(free_ports)
node=$(hostname -s)
mkdir -p "$cluster/state" "$cluster/spool"
# One node with the machine's real CPUs and memory (slurmd -C), CPUs as the
# consumable resource so that one-CPU tasks run side by side; no cgroups (CI
# containers have none to give). A requeued job waits cred_expire (default
# 120 s) before it may start again, so that is short, and a backfill pass
# every second starts it then (the main scheduler waits for an event).
cat >"$SLURM_CONF" <<EOF
ClusterName=flowvidtest
SlurmctldHost=$node(127.0.0.1)
SlurmctldPort=$ctld_port
SlurmdPort=$slurmd_port
SlurmUser=$(id -un)
SlurmdUser=$(id -un)
AuthType=auth/munge
CredType=cred/munge
AuthInfo=socket=$cluster/munge.sock,cred_expire=5
StateSaveLocation=$cluster/state
SlurmdSpoolDir=$cluster/spool
SlurmctldPidFile=$cluster/slurmctld.pid
SlurmdPidFile=$cluster/slurmd.pid
SlurmctldLogFile=$cluster/slurmctld.log
SlurmdLogFile=$cluster/slurmd.log
SlurmctldDebug=info
SlurmdDebug=info
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
SwitchType=switch/none
MpiDefault=none
SchedulerType=sched/backfill
SchedulerParameters=bf_interval=1
SelectType=select/cons_tres
SelectTypeParameters=CR_CPU
ReturnToService=2
JobRequeue=1
KillWait=2
MinJobAge=600
MailProg=/bin/true
$(slurmd -C | head -n 1) NodeAddr=127.0.0.1 State=UNKNOWN
PartitionName=farm Nodes=$node Default=YES MaxTime=10 State=UP
EOF
# Both fork into the background first; a bad configuration shows up after.
slurmctld -c || fail "slurmctld did not start"
exited() {  # exited DAEMON: it wrote its pid file and is gone since
  [[ -s $cluster/$1.pid ]] && ! kill -0 "$(<"$cluster/$1.pid")" 2>/dev/null
}
ctld_up() {
  exited slurmctld && fail "slurmctld exited (its log is below)"
  [[ $(scontrol ping 2>/dev/null) == *UP* ]]
}
wait_for "slurmctld to answer scontrol ping" 20 ctld_up
slurmd -c -N "$node" || fail "slurmd did not start"
node_idle() {
  exited slurmd && fail "slurmd exited (its log is below)"
  [[ $(sinfo -h -n "$node" -o %T 2>/dev/null) == idle ]]
}
wait_for "node $node to be idle in sinfo" 30 node_idle
log "cluster up: $(sinfo -h -o '%P %D node(s) %c CPUs %m MB, %T') (slurmctld port $ctld_port, slurmd port $slurmd_port; $(sinfo --version), $(munged --version 2>&1 | head -n 1))"

# ---- the jobs -----------------------------------------------------------------
[[ $work == */* && $work != / ]] || fail "scratch folder '$work' is not a folder of its own"
rm -rf "$work"
mkdir -p "$work/jobs" "$work/logs" "$work/shards" "$work/merged" "$work/reference" "$work/chunks" "$work/whole"
# What the job scripts read (sbatch passes the environment on).
export FLOWVID="$flowvid" CAPTURE="$capture" WORK="$work"
export SOURCE_DATE_EPOCH=1795000000  # the presets' created_utc (docs/farm.md)
# The fit of tests/cli/test_cli_farm.cpp: a static drape, an 8x8 mesh, 16
# evaluations (about a second a shard).
export FIT_OPTIONS="--evaluations 16 --resolution 8x8 --seed 5"
export SHARDS=3
export KILL_TASK=2  # the array task killed and requeued
export CHUNK=4      # synth frames 1..12 in three array tasks of 4 frames
frames=12

cat >"$work/jobs/fit-shards.sh" <<'EOF'
#!/bin/bash
# One shard per array task; a requeued task runs this again from the start.
set -euo pipefail
i=$SLURM_ARRAY_TASK_ID
attempt=${SLURM_RESTART_COUNT:-0}
echo "shard $i attempt $attempt: job $SLURM_JOB_ID (${SLURM_ARRAY_JOB_ID}_$i) SLURM_RESTART_COUNT=${SLURM_RESTART_COUNT:-unset} started $(date +%T.%N)" >>"$WORK/attempts.log"
# FIT_OPTIONS: plain words, split here.
shard=("$FLOWVID" --progress json fit cloth --capture "$CAPTURE" $FIT_OPTIONS
       --threads "$SLURM_CPUS_PER_TASK" --shard "$i/$SHARDS" --out "$WORK/shards/$i.json")
echo "shard $i attempt $attempt: ${shard[*]}" >>"$WORK/attempts.log"
progress="$WORK/logs/progress-$i-attempt$attempt.jsonl"
if [[ $i == "$KILL_TASK" && $attempt == 0 ]]; then
  # A shard takes about a second, so for the test's kill to land mid-fit on
  # any machine this attempt holds flowvid (SIGSTOP) once flowvid reports its
  # design phase: the capture is loaded, the simulations are under way and no
  # file is written yet. Slurm's requeue then kills it (SIGCONT, SIGTERM, SIGKILL).
  mkfifo "$WORK/logs/progress-$i.fifo"
  "${shard[@]}" 2>"$WORK/logs/progress-$i.fifo" &
  pid=$!
  while IFS= read -r event; do
    printf '%s\n' "$event" >>"$progress"
    if [[ $event == *'"detail":"design'* ]]; then
      kill -STOP "$pid"
      echo "$pid" >"$WORK/held-$i"
    fi
  done <"$WORK/logs/progress-$i.fifo"
  wait "$pid"
else
  "${shard[@]}" 2>>"$progress"
fi
echo "shard $i attempt $attempt: wrote shards/$i.json $(date +%T.%N)" >>"$WORK/attempts.log"
EOF

cat >"$work/jobs/merge.sh" <<'EOF'
#!/bin/bash
# The winner of the shards, simulated once more, as a preset.
set -euo pipefail
echo "merge: job $SLURM_JOB_ID started $(date +%T.%N) with $(cd "$WORK/shards" && ls -A | tr '\n' ' ')" >>"$WORK/attempts.log"
merge=("$FLOWVID" --progress none merge --threads "$SLURM_CPUS_PER_TASK" --out "$WORK/merged/silk.fabric.json" "$WORK"/shards/*.json)
echo "merge: ${merge[*]}" >>"$WORK/attempts.log"
"${merge[@]}"
EOF

cat >"$work/jobs/synth-chunks.sh" <<'EOF'
#!/bin/bash
# Frames a..b of the infinite sequence, the task id picking the chunk.
set -euo pipefail
a=$(( (SLURM_ARRAY_TASK_ID - 1) * CHUNK + 1 )); b=$(( SLURM_ARRAY_TASK_ID * CHUNK ))
synth=("$FLOWVID" --progress none synth --bank "$WORK/clip.bank.exr" --frames "$a:$b" --threads "$SLURM_CPUS_PER_TASK"
       --out "$WORK/chunks/%06d.png")
echo "synth chunk $SLURM_ARRAY_TASK_ID: job $SLURM_JOB_ID (${SLURM_ARRAY_JOB_ID}_$SLURM_ARRAY_TASK_ID): ${synth[*]}" >>"$WORK/attempts.log"
"${synth[@]}"
EOF

log "tracking the bank the synth chunks render (outside Slurm): $clip, 30 frames"
"$flowvid" -q track --capture "$clip" --frame-count 30 --out "$work/clip.bank.exr" >"$work/logs/track.log" 2>&1 ||
  fail "flowvid track failed: $(tail -n 5 "$work/logs/track.log")"

submit() {  # submit VAR ARGS...: sbatch ARGS, the job id in VAR
  local var=$1 id
  shift
  id=$(sbatch --parsable --chdir="$work" --cpus-per-task=1 --open-mode=append "$@") || fail "sbatch $* was refused"
  log "submitted job ${id%%;*}: sbatch $*"
  printf -v "$var" '%s' "${id%%;*}"
}
submit fit --job-name=fit --array=1-$SHARDS --requeue --output="$work/logs/fit-%A_%a.log" "$work/jobs/fit-shards.sh"
# afterok: the merge starts only when every task of the array succeeded. A
# task requeued while it runs (scontrol requeue) keeps this valid: it is
# pending again, not failed. In Slurm 22.05 a task that has ended cancelled or
# failed (scancel, or an exit code that RequeueExit requeues) leaves afterok
# "DependencyNeverSatisfied" for good, even once the task is requeued and
# succeeds, which is why the kill here is Slurm's own requeue of a running task.
submit merge --job-name=merge --dependency=afterok:"$fit" --output="$work/logs/merge-%j.log" "$work/jobs/merge.sh"
submit synth --job-name=synth --array=1-$((frames / CHUNK)) --output="$work/logs/synth-%A_%a.log" "$work/jobs/synth-chunks.sh"

# Job states as squeue reports them, logged when they change.
last_states=""
states() { squeue -h -t all -j "$fit,$merge,$synth" -o '%i %T %r' 2>/dev/null | sort | tr '\n' ';'; }
watch_states() {
  local now
  now=$(states)
  if [[ $now != "$last_states" ]]; then
    log "squeue: ${now//;/  }"
    last_states=$now
  fi
  [[ $now == *DependencyNeverSatisfied* ]] && fail "the merge's dependency can never be satisfied: $now"
  return 0
}
held() { watch_states; [[ -s $work/held-$KILL_TASK ]]; }
process_state() { awk '{print $3}' "/proc/$1/stat" 2>/dev/null; }  # R, S, T (stopped), Z, or nothing
gone() { watch_states; local s; s=$(process_state "$1"); [[ -z $s || $s == Z ]]; }
task_field() { scontrol -o show job "$1" | tr ' ' '\n' | sed -n "s/^$2=//p" | head -n 1; }

# ---- the kill and the requeue -------------------------------------------------
wait_for "task ${fit}_$KILL_TASK to hold flowvid mid-fit" 120 held
held_pid=$(<"$work/held-$KILL_TASK")
[[ $(process_state "$held_pid") == T ]] || fail "flowvid $held_pid of task ${fit}_$KILL_TASK is not held (state '$(process_state "$held_pid")')"
log "task ${fit}_$KILL_TASK, attempt 0: flowvid (pid $held_pid) held mid-fit; its progress so far: $(tr '\n' ' ' <"$work/logs/progress-$KILL_TASK-attempt0.jsonl")"
log "task ${fit}_$KILL_TASK: $(task_field "${fit}_$KILL_TASK" JobState), Restarts=$(task_field "${fit}_$KILL_TASK" Restarts)"
log "kill and requeue: scontrol requeue ${fit}_$KILL_TASK"
scontrol requeue "${fit}_$KILL_TASK" || fail "scontrol requeue ${fit}_$KILL_TASK was refused"
wait_for "Slurm to kill flowvid $held_pid of task ${fit}_$KILL_TASK" 30 gone "$held_pid"
log "flowvid $held_pid is gone (killed by Slurm)"
requeued() { watch_states; [[ $(task_field "${fit}_$KILL_TASK" JobState) == PENDING ]]; }
wait_for "task ${fit}_$KILL_TASK to be pending again" 30 requeued
restarts=$(task_field "${fit}_$KILL_TASK" Restarts)
[[ $restarts == 1 ]] || fail "task ${fit}_$KILL_TASK has Restarts=$restarts after the requeue, not 1"
log "task ${fit}_$KILL_TASK: PENDING ($(task_field "${fit}_$KILL_TASK" Reason)), Restarts=1"
[[ ! -e $work/shards/$KILL_TASK.json ]] || fail "the killed attempt left shards/$KILL_TASK.json"
grep -q '"event":"done"' "$work/logs/progress-$KILL_TASK-attempt0.jsonl" &&
  fail "the killed attempt's flowvid reported it was done: the kill came too late"
log "the killed attempt wrote nothing: shards/ holds [$(cd "$work/shards" && ls -A | tr '\n' ' ')]"

# ---- the one-machine results, while the requeued task waits -------------------
t0=${EPOCHREALTIME/./}
"$flowvid" --progress none fit cloth --capture "$capture" $FIT_OPTIONS --shards "$SHARDS" --threads 2 \
  --out "$work/reference/silk.fabric.json" >"$work/logs/reference-fit.log" 2>&1 ||
  fail "the one-machine fit failed: $(tail -n 5 "$work/logs/reference-fit.log")"
log "reference: flowvid fit cloth --capture $capture $FIT_OPTIONS --shards $SHARDS --threads 2 ($(((${EPOCHREALTIME/./} - t0) / 1000)) ms)"
t0=${EPOCHREALTIME/./}
"$flowvid" --progress none synth --bank "$work/clip.bank.exr" --frames "1:$frames" --threads 2 \
  --out "$work/whole/%06d.png" >"$work/logs/reference-synth.log" 2>&1 ||
  fail "the whole synth failed: $(tail -n 5 "$work/logs/reference-synth.log")"
log "reference: flowvid synth --bank clip.bank.exr --frames 1:$frames --threads 2 ($(((${EPOCHREALTIME/./} - t0) / 1000)) ms)"

# ---- every job ends -----------------------------------------------------------
finished() {
  watch_states
  local s all
  all=$(squeue -h -t all -j "$fit,$merge,$synth" -o %T 2>/dev/null)
  (($(wc -w <<<"$all") == SHARDS + 1 + frames / CHUNK)) || return 1  # squeue did not answer, or not yet per task
  for s in $all; do
    case $s in
      COMPLETED) ;;
      PENDING | CONFIGURING | RUNNING | COMPLETING | REQUEUED) return 1 ;;
      *) fail "a job ended $s: $(states)" ;;
    esac
  done
}
wait_for "every job to complete" 180 finished
for id in "${fit}_1" "${fit}_2" "${fit}_3" "$merge" "${synth}_1" "${synth}_2" "${synth}_3"; do
  state=$(task_field "$id" JobState) exit_code=$(task_field "$id" ExitCode) restarts=$(task_field "$id" Restarts)
  log "job $id: $state ExitCode=$exit_code Restarts=$restarts"
  [[ $state == COMPLETED && $exit_code == 0:0 ]] || fail "job $id ended $state with exit code $exit_code"
  expected=0
  [[ $id == "${fit}_$KILL_TASK" ]] && expected=1
  [[ $restarts == "$expected" ]] || fail "job $id ran $((restarts + 1)) times, expected $((expected + 1))"
done

log "the requeue as Slurm and the tasks recorded it:"
grep -F "JobId=${fit}_$KILL_TASK(" "$cluster/slurmctld.log" | sed 's/^/    slurmctld.log: /'
grep -F "DUE TO JOB REQUEUE" "$work"/logs/fit-"${fit}_$KILL_TASK".log | sed 's/^/    task log: /'
sed 's/^/    attempts.log: /' "$work/attempts.log"
grep -q "^shard $KILL_TASK attempt 1: .*SLURM_RESTART_COUNT=1 " "$work/attempts.log" ||
  fail "no second attempt of shard $KILL_TASK with SLURM_RESTART_COUNT=1 in attempts.log"
grep -q "^shard $KILL_TASK attempt 0: wrote" "$work/attempts.log" && fail "the killed attempt ran to its end"
grep -q "DUE TO JOB REQUEUE" "$work"/logs/fit-"${fit}_$KILL_TASK".log ||
  fail "the task's log does not say Slurm cancelled it for the requeue"

# ---- the results --------------------------------------------------------------
[[ $(cd "$work/shards" && ls -A | tr '\n' ' ') == "1.json 2.json 3.json " ]] ||
  fail "shards/ should hold exactly 1.json 2.json 3.json: $(ls -A "$work/shards")"
cmp "$work/merged/silk.fabric.json" "$work/reference/silk.fabric.json" ||
  fail "the merged preset differs from fit cloth --shards $SHARDS"
log "cmp merged/silk.fabric.json reference/silk.fabric.json: identical ($(wc -c <"$work/merged/silk.fabric.json") bytes, created_utc $(grep -o '"created_utc": *"[^"]*"' "$work/merged/silk.fabric.json" | cut -d'"' -f4))"

count=$(find "$work/chunks" -mindepth 1 | wc -l)
((count == frames)) || fail "chunks/ holds $count files, expected frames 1..$frames"
cmp -s "$work/whole/000001.png" "$work/whole/$(printf %06d "$frames").png" &&
  fail "frames 1 and $frames of the whole render are identical: nothing flows, the comparison would prove nothing"
for ((f = 1; f <= frames; f++)); do
  name=$(printf %06d.png "$f")
  cmp "$work/chunks/$name" "$work/whole/$name" || fail "frame $f differs between its chunk and the whole render"
done
log "cmp chunks/%06d.png whole/%06d.png: frames 1..$frames identical"
passed=1
log "PASSED: the Slurm array jobs equal the one-machine fit and render byte for byte"
