#!/usr/bin/env bash
# End-to-end test of slurm/convert.sbatch and slurm/convert_array.sbatch on a real single-node Slurm
# started here, in a temporary folder: munged, slurmctld and slurmd with their own sockets, ports, state,
# pid and log files (nothing in /etc, /run or /var is used), ProctrackType=proctrack/linuxproc,
# TaskPlugin=task/none. All daemons are stopped by PID and the folder removed at the end.
#
#   tests/slurm/run_slurm_test.sh GIMFORGE_EXE [SOURCE_DIR]      (ctest: label "slurm")
#
# 1. convert.sbatch through sbatch, 2 tasks with `srun --mpi=pmix`: once the first item is committed the
#    batch shell gets SIGUSR1 (what --signal=B:USR1@300 sends before the time limit); the script passes
#    it on, the ranks stop (exit 4), the job requeues itself and the second run finishes with --resume.
# 2. slurm/split_collection.py cuts the same collection (as a job file) into 2 slices, converted by
#    convert_array.sbatch as a 2-task array job; the two part archives together hold exactly the items of
#    the archive of step 1, with the same names, labels and data.
# 3. A binary PLY scan converted by bricks through a proxy under srun --mpi=pmix with 2 tasks (and, for the
#    generated scan, as a relief map by bricks, equal to one process bit for bit): the proxy
#    and the PSNR of one process.
# Exit 0 passed, 1 failed, 77 skipped (Slurm or munge not installed: scripts/setup-deps.sh installs them).
set -euo pipefail

GIMFORGE=${1:?usage: run_slurm_test.sh GIMFORGE_EXE [SOURCE_DIR]}
SRC=$(cd "${2:-$(dirname "$0")/../..}" && pwd)
GIMFORGE=$(cd "$(dirname "$GIMFORGE")" && pwd)/$(basename "$GIMFORGE")
PY=/usr/bin/python3
PATH=$PATH:/usr/sbin:/sbin
T0=$SECONDS
log() { echo "slurm-test [$((SECONDS - T0)) s]: $*"; }
fail() { echo "slurm-test: FAILED: $*" >&2; exit 1; }

missing=()
for b in munged munge slurmctld slurmd sbatch srun sinfo squeue scontrol scancel; do
  command -v "$b" >/dev/null || missing+=("$b")
done
if [ ${#missing[@]} -gt 0 ]; then
  echo "slurm-test: SKIPPED: not installed: ${missing[*]} (Debian: slurmctld slurmd slurm-client munge;" \
       "scripts/setup-deps.sh installs them)"
  exit 77
fi
[ -x "$GIMFORGE" ] || fail "$GIMFORGE: not an executable"

# Nothing of an outer Slurm job (when this runs inside one) may leak into ours.
for v in $(compgen -e | grep '^SLURM_' || true); do unset "$v"; done

# Stop what we started, by PID: jobs first (scancel), then slurmd, slurmctld, munged; then any process
# still running in our folder (a job step left over after a failure), and the watchdog.
T="" watchdog=""
stop_pid() {  # stop_pid PIDFILE: SIGTERM, up to 10 s, then SIGKILL
  local pid
  [ -s "$1" ] || return 0
  pid=$(cat "$1")
  kill "$pid" 2>/dev/null || return 0
  for _ in $(seq 100); do kill -0 "$pid" 2>/dev/null || return 0; sleep 0.1; done
  kill -9 "$pid" 2>/dev/null || true
}
cleanup() {
  local rc=$?
  set +e
  [ -n "$watchdog" ] && kill "$watchdog" 2>/dev/null
  [ -n "$T" ] && [ -d "$T" ] || exit $rc
  if [ $rc -ne 0 ]; then
    for f in "$T"/out/*.out "$T"/log/slurmctld.log "$T"/log/slurmd.log; do
      [ -f "$f" ] && { echo "---- ${f#"$T"/} (last 40 lines)"; tail -n 40 "$f"; }
    done
  fi
  if [ -s "$T/slurmctld.pid" ] && kill -0 "$(cat "$T/slurmctld.pid")" 2>/dev/null; then
    scancel --quiet --user="$(id -un)" 2>/dev/null
    for _ in $(seq 50); do [ -z "$(squeue -h 2>/dev/null)" ] && break; sleep 0.2; done
  fi
  stop_pid "$T/slurmd.pid"
  stop_pid "$T/slurmctld.pid"
  stop_pid "$T/munge/munged.pid"
  for p in /proc/[0-9]*; do
    case "$(readlink "$p/cwd" 2>/dev/null)" in "$T" | "$T"/*) kill -9 "${p#/proc/}" 2>/dev/null ;; esac
  done
  rm -rf "$T"
  log "daemons stopped, $T removed"
  exit $rc
}
trap cleanup EXIT
trap 'fail "interrupted"' INT TERM
# The daemons outlive a killed test, so the test stops itself before ctest's timeout (300 s) could.
limit=$((240 + ${GIMFORGE_SLURM_TIMEOUT:-0}))
trap 'fail "not done after $limit s"' ALRM
( trap 'kill "$s" 2>/dev/null; exit 0' TERM; sleep "$limit" & s=$!; wait "$s" && kill -ALRM $$ ) 2>/dev/null &
watchdog=$!

# A short path: munge's socket path must fit a sockaddr_un (108 bytes).
T=$(mktemp -d /tmp/gimforge-slurm.XXXXXX)
chmod 755 "$T"  # munged wants its socket's folders searchable by all
mkdir -p "$T/munge" "$T/state" "$T/spool" "$T/log" "$T/in" "$T/out"
chmod 755 "$T/munge"
export SLURM_CONF=$T/slurm.conf

# --- munge: own key, socket, pid, log and seed files
dd if=/dev/urandom of="$T/munge/munge.key" bs=1024 count=1 status=none
chmod 400 "$T/munge/munge.key"
munged --socket="$T/munge/munge.sock" --pid-file="$T/munge/munged.pid" --log-file="$T/log/munged.log" \
  --key-file="$T/munge/munge.key" --seed-file="$T/munge/munged.seed" ||
  { cat "$T/log/munged.log" >&2; fail "munged did not start"; }
munge -S "$T/munge/munge.sock" -n </dev/null | unmunge -S "$T/munge/munge.sock" >/dev/null ||
  fail "munge credentials do not work"

# --- slurm.conf: one node with this machine's CPUs, free ports, everything under $T
read -r ctld_port slurmd_port < <("$PY" -c '
import socket
s = [socket.socket() for _ in range(2)]
for x in s: x.bind(("127.0.0.1", 0))
print(*[x.getsockname()[1] for x in s])')
cpus=$(nproc)
node=$(slurmd -C 2>/dev/null | head -n 1 | grep -o 'CPUs=.*ThreadsPerCore=[0-9]*' || echo "CPUs=$cpus")
overrides=""
if [ "$cpus" -lt 2 ]; then node="CPUs=2" overrides="SlurmdParameters=config_overrides"; fi  # 2 tasks
user=$(id -un)
cat >"$SLURM_CONF" <<EOF
ClusterName=gimforge-test
SlurmctldHost=localhost
SlurmctldPort=$ctld_port
SlurmdPort=$slurmd_port
SlurmUser=$user
SlurmdUser=$user
AuthType=auth/munge
CredType=cred/munge
AuthInfo=socket=$T/munge/munge.sock
StateSaveLocation=$T/state
SlurmdSpoolDir=$T/spool
SlurmctldPidFile=$T/slurmctld.pid
SlurmdPidFile=$T/slurmd.pid
SlurmctldLogFile=$T/log/slurmctld.log
SlurmdLogFile=$T/log/slurmd.log
PlugStackConfig=$T/plugstack.conf
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
SelectType=select/cons_tres
SelectTypeParameters=CR_CPU
MpiDefault=none
ReturnToService=2
MailProg=/bin/true
$overrides
NodeName=gfnode NodeHostname=$(hostname) NodeAddr=127.0.0.1 $node RealMemory=1000 State=UNKNOWN
PartitionName=debug Nodes=gfnode Default=YES MaxTime=INFINITE State=UP OverSubscribe=YES
EOF
: >"$T/plugstack.conf"
slurmctld -f "$SLURM_CONF" || fail "slurmctld did not start"
slurmd -f "$SLURM_CONF" -N gfnode || fail "slurmd did not start"
for _ in $(seq 150); do
  state=$(sinfo -h -n gfnode -o %T 2>/dev/null || true)
  [ "$state" = idle ] && break
  sleep 0.2
done
[ "$state" = idle ] || fail "node not idle after 30 s (state: '$state'; $(scontrol show node gfnode 2>&1 | grep -E 'State|Reason' | tr -s ' \n' ' '))"
log "slurm up: node gfnode idle, $cpus CPUs, ports $ctld_port/$slurmd_port"
# PMIx first, on its own: `srun --mpi=list` names pmix even when the plugin cannot load libpmix.so.
if ! err=$(timeout 60 srun --mpi=pmix --ntasks=1 --time=1 true 2>&1); then
  fail "srun --mpi=pmix does not work (Debian: the mpi/pmix plugin needs libpmix-dev's libpmix.so): $err"
fi

# --- the collection: 3 classes (folders) of 6 meshes, and one mesh without a folder (label "")
for c in alpha beta gamma; do
  mkdir -p "$T/in/$c"
  cp "$SRC"/tests/data/{cathead,fist,kitten,sphere_r1,sphere_r1.01}.ply "$SRC/tests/data/tetra.obj" "$T/in/$c/"
done
cp "$SRC/tests/data/tetra.obj" "$T/in/"
n_items=19

# job_field JOB KEY: the KEY=value of every record of `scontrol show job` (array tasks: one line each)
job_field() { scontrol -o show job "$1" 2>/dev/null | grep -o "$2=[^ ]*" | cut -d= -f2; }
# wait_jobs JOB SECONDS: until every record of JOB is in a final state
wait_jobs() {
  local end=$((SECONDS + $2)) states
  while [ $SECONDS -lt $end ]; do
    states=$(job_field "$1" JobState | sort -u | tr '\n' ' ')
    if [ -n "$states" ] && ! grep -qE 'PENDING|RUNNING|COMPLETING|CONFIGURING|REQUEUE|SUSPENDED|RESIZING' <<<"$states"; then
      return 0
    fi
    sleep 0.5
  done
  fail "job $1 not finished after $2 s (states: $states)"
}

# --- 1. convert.sbatch: 2 tasks under srun --mpi=pmix, SIGUSR1, requeue, resume
job=$(sbatch --parsable --ntasks=2 --cpus-per-task=1 --time=10 --chdir="$T" --output="$T/out/convert-%j.out" \
  --export=ALL,GIMFORGE="$GIMFORGE" "$SRC/slurm/convert.sbatch" \
  --input "$T/in" -o "$T/out/all.h5" --method gim --size 65 --metric-samples 20000)
log "submitted convert.sbatch as job $job"
journal=$T/out/all.h5.work/journal.jsonl
for _ in $(seq 600); do
  [ -f "$journal" ] && grep -q '"event":"done"' "$journal" && break
  state=$(job_field "$job" JobState)
  grep -qE '^(PENDING|CONFIGURING|RUNNING)$' <<<"$state" || fail "job $job is $state before its first item was committed"
  sleep 0.1
done
grep -q '"event":"done"' "$journal" || fail "no item committed after 60 s"
scancel --batch --signal=USR1 "$job"
log "first item committed; sent SIGUSR1 to the batch shell (as --signal=B:USR1@300 does)"
for _ in $(seq 600); do
  [ "$(job_field "$job" Restarts)" = 1 ] && [ "$(job_field "$job" JobState)" = PENDING ] && break
  [ -f "$T/out/all.h5" ] && fail "job $job finished before SIGUSR1 took effect"
  sleep 0.1
done
[ "$(job_field "$job" Restarts)" = 1 ] || fail "job $job did not requeue itself"
# Slurm holds a requeued job back for 2 minutes (BeginTime); the test releases it once the node is idle
# again and 2 s have passed (slurmd refuses to launch it with "Job credential revoked" when the new
# credential is from the same second as the requeue's revocation of the old one).
for _ in $(seq 300); do [ "$(sinfo -h -n gfnode -o %T)" = idle ] && break; sleep 0.1; done
sleep 2
scontrol update JobId="$job" StartTime=now
log "job $job requeued itself; released"
wait_jobs "$job" 120
out=$T/out/convert-$job.out
if [ "$(job_field "$job" JobState)" != COMPLETED ] || [ "$(job_field "$job" ExitCode)" != 0:0 ]; then
  fail "job $job ended $(job_field "$job" JobState), exit $(job_field "$job" ExitCode)"
fi
[ "$(grep -c 'on 2 rank(s)' "$out")" = 2 ] || fail "expected two runs with 2 MPI ranks each in $out"
grep -q 'stopped by signal 10' "$out" || fail "the ranks did not stop on SIGUSR1 ($out)"
grep -q 'requeued, the next run resumes' "$out" || fail "no requeue in $out"
grep -Eq '\(([1-9][0-9]*) already done\)' "$out" || fail "the second run did not resume committed items ($out)"
[ -d "$T/out/all.h5.work" ] && fail "the work directory was not removed after the merge"
log "job $job: stopped, requeued, resumed, completed"

# --- 2. convert_array.sbatch: 2 slices, one array task each
cat >"$T/job.toml" <<EOF
metric_samples = 20000
[[collection]]
input = "in"
[[output]]
method = "gim"
size = 65
EOF
"$PY" "$SRC/slurm/split_collection.py" "$T/job.toml" 2 "$T/slices"
submit_array() {
  sbatch --parsable --array=0-1 --ntasks=1 --cpus-per-task=1 --time=10 --chdir="$T" \
    --output="$T/out/array-%A_%a.out" --export=ALL,GIMFORGE="$GIMFORGE" "$SRC/slurm/convert_array.sbatch" \
    "$T/slices" "$T/out/parts"
}
array=$(submit_array)
log "submitted convert_array.sbatch as array job $array"
wait_jobs "$array" 120
states=$(job_field "$array" JobState | sort | tr '\n' ' ')
[ "$states" = "COMPLETED COMPLETED " ] || fail "array job $array: task states $states"
log "array job $array: both tasks completed"
# Submitting it again converts nothing: both slices are complete.
again=$(submit_array)
wait_jobs "$again" 60
states=$(job_field "$again" JobState | sort | tr '\n' ' ')
[ "$states" = "COMPLETED COMPLETED " ] || fail "array job $again: task states $states"
[ "$(cat "$T"/out/array-"$again"_*.out | grep -c 'is complete: nothing to do')" = 2 ] ||
  fail "array job $again did not skip the complete slices"
log "array job $again (the same again): both slices skipped as complete"

# --- 3. a scan converted by bricks under srun --mpi=pmix, 2 tasks (jobs/brick_convert.h): one archive, and
#        the proxy one process makes. GIMFORGE_SLURM_SCAN=FILE.ply (with GIMFORGE_SLURM_SCAN_ARGS, e.g.
#        "--method gim --size 513", and GIMFORGE_SLURM_TIMEOUT seconds) runs a benchmark-size scan instead.
scan=${GIMFORGE_SLURM_SCAN:-}
if [ -z "$scan" ]; then
  scan=$T/scan.ply
  "$GIMFORGE" synth subdivide "$SRC/tests/data/kitten.ply" --segments 3 -o "$scan" >/dev/null || fail "synth subdivide"
  read -r -a scan_args <<<"--method gim --size 65 --proxy-faces 1500 --metric-samples 20000"
else
  read -r -a scan_args <<<"${GIMFORGE_SLURM_SCAN_ARGS:---method gim --size 513}"
fi
scan_job=$(sbatch --parsable --ntasks=2 --cpus-per-task=1 --time=60 --chdir="$T" --output="$T/out/scan-%j.out" \
  --wrap="/usr/bin/time -v srun --mpi=pmix $GIMFORGE convert $scan ${scan_args[*]} --json -o $T/out/scan.h5 > $T/out/scan.json")
log "submitted the brick conversion of $(basename "$scan") as job $scan_job"
wait_jobs "$scan_job" "${GIMFORGE_SLURM_TIMEOUT:-120}"
[ "$(job_field "$scan_job" JobState)" = COMPLETED ] ||
  fail "job $scan_job ended $(job_field "$scan_job" JobState): $(tail -n 5 "$T/out/scan-$scan_job.out")"
"$GIMFORGE" convert "$scan" "${scan_args[@]}" --json -o "$T/out/scan1.h5" >"$T/out/scan1.json" || fail "single-process convert"
check_scan() {  # JSON of the 2-task run, JSON of one process
  "$PY" - "$1" "$2" <<'EOF'
import json, sys
two, one = (json.load(open(p)) for p in sys.argv[1:3])
assert two["ranks"] == 2, two
if "proxy_faces" in one:  # an image method through a proxy (jobs/brick_convert.h)
    assert two["proxy_faces"] == one["proxy_faces"], (two, one)
    # Bit for bit, but a wrap's new vertices round through the ranks' temporary file (--wrap).
    assert abs(two["proxy_psnr"] - one["proxy_psnr"]) <= (1e-9 * one["proxy_psnr"] if "wrap_faces" in one else 0.0), (two, one)
    assert abs(two["psnr"] - one["psnr"]) <= 1e-9 * one["psnr"], (two["psnr"], one["psnr"])
    what = f"proxy {two['proxy_psnr']:.4f} dB"
else:  # a relief map (jobs/brick_relief.h): equal bit for bit
    for key in ("psnr", "hausdorff_rms", "hausdorff_max", "samples", "occluded_samples", "storage_bytes"):
        assert two[key] == one[key], (key, two[key], one[key])
    what = f"relief N = {two['n']}, {int(two['samples'])} samples"
print(f"slurm-test: scan by bricks on 2 tasks: {two['method']} PSNR {two['psnr']:.4f} dB ({what}), "
      f"{two['seconds_command']:.1f} s, {two['rank_peak_rss_mb']:.0f} MB per rank at most; "
      f"one process {one['seconds_command']:.1f} s")
EOF
}
check_scan "$T/out/scan.json" "$T/out/scan1.json" || fail "the scan by bricks differs from one process"
log "job $scan_job: the scan converted by bricks equals one process"
if [ -z "${GIMFORGE_SLURM_SCAN:-}" ]; then
  # The same scan as a relief map by bricks (jobs/brick_relief.h): the one-process archive, bit for bit.
  relief_args=(--method relief --texture 16 --metric-samples 20000)
  relief_job=$(sbatch --parsable --ntasks=2 --cpus-per-task=1 --time=60 --chdir="$T" --output="$T/out/relief-%j.out" \
    --wrap="srun --mpi=pmix $GIMFORGE convert $scan ${relief_args[*]} --json -o $T/out/relief.h5 > $T/out/relief.json")
  wait_jobs "$relief_job" 120
  [ "$(job_field "$relief_job" JobState)" = COMPLETED ] ||
    fail "job $relief_job ended $(job_field "$relief_job" JobState): $(tail -n 5 "$T/out/relief-$relief_job.out")"
  "$GIMFORGE" convert "$scan" "${relief_args[@]}" --json -o "$T/out/relief1.h5" >"$T/out/relief1.json" ||
    fail "single-process relief convert"
  check_scan "$T/out/relief.json" "$T/out/relief1.json" || fail "the relief map by bricks differs from one process"
  log "job $relief_job: the relief map by bricks equals one process"
fi

# --- the archives
"$PY" - "$T/out/all.h5" "$n_items" "$T/out/parts/part_0000.h5" "$T/out/parts/part_0001.h5" <<'EOF'
import sys
import h5py
import numpy as np

path, n = sys.argv[1], int(sys.argv[2])
def load(p):
    with h5py.File(p, "r") as f:
        g = f["batch/gim_65"]
        names = list(g["names"].asstr()[()])
        return {"names": names, "labels": dict(zip(names, g["labels"].asstr()[()])),
                "data": dict(zip(names, g["data"][()])), "shape": g["data"].shape,
                "failed": int(g.attrs["failed_count"]), "count": int(g.attrs["count"])}
a = load(path)
assert a["shape"] == (n, 3, 65, 65), f"{path}: data shape {a['shape']}"
assert a["count"] == n and a["failed"] == 0, f"{path}: count {a['count']}, failed {a['failed']}"
assert len(set(a["names"])) == n, f"{path}: duplicate names {a['names']}"
assert set(a["labels"].values()) == {"alpha", "beta", "gamma", ""}, a["labels"]
parts = [load(p) for p in sys.argv[3:]]
part_names = [x for p in parts for x in p["names"]]
assert all(p["count"] > 0 and p["failed"] == 0 for p in parts), [(p["count"], p["failed"]) for p in parts]
assert sorted(part_names) == sorted(a["names"]), f"parts {sorted(part_names)} != {sorted(a['names'])}"
for p in parts:
    for name in p["names"]:
        assert p["labels"][name] == a["labels"][name], name
        assert np.array_equal(p["data"][name], a["data"][name]), f"{name}: data differ"
print(f"slurm-test: archive {n} items, parts {[p['count'] for p in parts]}: same names, labels and data")
EOF
log "PASSED"
