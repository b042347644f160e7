#!/usr/bin/env bash
# The long reliability runs of issue 9 (the short versions run in scripts/test.sh):
#  1. crash safety: SIGKILL the offline runner at random points while it maps, merges and saves
#     into an existing map, many times; after each kill the map must load (map_check verifies
#     every file) and equal either the old map (byte-identical) or the new one (the content of
#     an uninterrupted run). Prints the number of kills survived.
#  2. long run: sessions of the `small` profile merged one after the other, each in its own
#     offline_mapper process under /usr/bin/time -v; prints the peak memory and the map's size
#     after each (the memory curve).
#  3. nodelets twice: ONE nodelet manager with the four nodelets (launch/mapping.launch with
#     play:=false) maps a `campus` bag, finishes (idle_finish_s without a scan), merges and
#     saves, then maps the same bag again as a second session in the same process. Both runs
#     merge into a map made beforehand by offline_mapper from the same scans, so that they do
#     the same work (a first session's merge only stores it). The manager's RSS
#     (/proc/PID/status VmRSS) is sampled every 2 s; prints per run the scans played and mapped,
#     the peak RSS, the RSS after the finish (merge and save done) and the map's size on disk.
#     MapMerging logs the live heap after each merge (glibc mallinfo2 over all arenas: what
#     a leak makes grow; the RSS also holds freed pages the allocator keeps).
#     Pass: both sessions merged and saved, each maps at least 90 % of the scans played (fewer:
#     the pipeline dropped or refused scans), the live heap after the second finish exceeds the
#     one after the first by at most the map's growth on disk plus 5 % of the first, and the
#     RSS after the second finish exceeds the RSS after the first by at most the map's growth
#     on disk plus 5 % of the first run's peak RSS. The map is all the state a session leaves
#     behind (map_merging holds it,
#     place_recognition its descriptor database); the 5 % are for heap fragmentation: freed
#     pages that still hold a live block stay resident (heaptrack, first 15 s of `small` s00,
#     3 sessions in one manager: live heap after each finish 11.5 / 11.6 / 11.7 MB while the
#     RSS after the finish grew by several MB per session). A leak of a session's points (the
#     fused submaps' buffers, kept until the fix: +5.6 MB live heap per such `small` session)
#     grows with the session's size. --nodelet-runs N: N runs, the criterion between runs 1
#     and 2.
#   scripts/stress.sh [--kills N] [--max-minutes M] [--sessions N] [--only kills|long|nodelets]
#                     [--nodelet-bag PATH] [--nodelet-duration S] [--nodelet-rate R]
#                     [--nodelet-runs N]
#   --nodelet-bag: default: one simulated `campus` session in build/stress_data/campus1;
#   --nodelet-duration: play only the first S seconds of it (rosbag play --duration), default
#   the whole bag; --nodelet-rate: playback rate, default 1.0.
# Data goes to build/stress_data (reused when present), maps to build/stress_maps.
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/lib/common.sh"

kills=50
max_minutes=30
sessions=10
only=""
nodelet_bag=""
nodelet_duration=""
nodelet_rate="1.0"
nodelet_runs=2
while [ $# -gt 0 ]; do
  case "$1" in
    --kills) kills="$2"; shift ;;
    --max-minutes) max_minutes="$2"; shift ;;
    --sessions) sessions="$2"; shift ;;
    --only) only="$2"; shift ;;
    --nodelet-bag) nodelet_bag="$2"; shift ;;
    --nodelet-duration) nodelet_duration="$2"; shift ;;
    --nodelet-rate) nodelet_rate="$2"; shift ;;
    --nodelet-runs) nodelet_runs="$2"; shift ;;
    -h|--help) sed -n '2,38p' "$0"; exit 0 ;;
    *) msm_die "unknown argument '$1' (see --help)" ;;
  esac
  shift
done
case "${only}" in ""|kills|long|nodelets) ;; *) msm_die "--only: kills, long or nodelets" ;; esac

msm_install_deps
if [ -f "${MSM_WS}/build/Makefile" ]; then
  # An existing workspace: build only the three tools used here.
  make -C "${MSM_WS}/build" -j"${MSM_JOBS:-$(nproc)}" offline_mapper map_check simulate_campus \
    multisession_mapper_nodelets >/dev/null || msm_die "building the tools failed"
else
  msm_build
fi
msm_source_workspace
bin="${MSM_WS}/devel/lib/multisession_mapper"
for tool in offline_mapper map_check simulate_campus; do
  [ -x "${bin}/${tool}" ] || msm_die "${bin}/${tool} is missing (build failed?)"
done
data="${MSM_REPO}/build/stress_data"
maps="${MSM_REPO}/build/stress_maps"
mkdir -p "${data}" "${maps}"

simulate() {  # profile sessions out
  if [ ! -f "$3/sessions.yaml" ]; then
    msm_log "simulating $2 session(s) of the $1 profile into $3"
    "${bin}/simulate_campus" --profile "$1" --sessions "$2" --seed 3 --out "$3" --quiet
  fi
}

# map_check output field ($2) of the map at $1; empty when there is no map.
field() { "${bin}/map_check" "$1" 2>/dev/null | sed -n "s/^$2: //p"; }

now() { date +%s.%N; }
elapsed() { awk -v a="$1" -v b="$(now)" 'BEGIN { printf "%.2f", b - a }'; }

# ---------------------------------------------------------------------------------------------
crash_safety() {
  # The `small` profile: s00 whole is the old map, the first 300 scans of s02 (about 25 s of
  # mapping and merging; the `tiny` sessions do not overlap enough to be merged) are the run
  # that is killed.
  local sim="${data}/small3"
  simulate small 3 "${sim}"
  local base="${maps}/kill_base" work="${maps}/kill_work" ref="${maps}/kill_ref"
  local bag_first="${sim}/s00.bag" bag_next="${sim}/s02.bag"
  local -a next_args=(--max-scans 300)
  # The old map: the first session, mapped without interruption.
  rm -rf "${base}" "${base}.new" "${base}.old"
  "${bin}/offline_mapper" --bag "${bag_first}" --map "${base}" --quiet
  # Reference run of the killed command: does merging work yet?
  local mode old_state old_files new_content
  rm -rf "${ref}" "${ref}.new" "${ref}.old"
  cp -a "${base}" "${ref}"
  local start; start=$(now)
  set +e
  "${bin}/offline_mapper" --bag "${bag_next}" "${next_args[@]}" --map "${ref}" --quiet \
    2>"${maps}/kill_ref.log"
  local rc=$?
  set -e
  local run_s; run_s=$(elapsed "${start}")
  if [ ${rc} -eq 0 ]; then
    mode="merge"
    msm_log "crash safety: killing merges of ${bag_next##*/} into a map of ${bag_first##*/} (uninterrupted: ${run_s} s)"
  elif [ ${rc} -eq 3 ]; then
    mode="first"
    echo "NOTE: the map refused the second session (offline_mapper exit 3, merging not possible:"
    echo "      $(tr -d '\n' < "${maps}/kill_ref.log" | cut -c1-200))."
    echo "      Killing the mapping and saving of a first session into an empty map instead."
    rm -rf "${ref}" && start=$(now)
    next_args=()
    "${bin}/offline_mapper" --bag "${bag_first}" --map "${ref}" --quiet
    run_s=$(elapsed "${start}")
  else
    cat "${maps}/kill_ref.log"
    msm_die "the uninterrupted reference run failed (exit ${rc})"
  fi
  new_content=$(field "${ref}" content_digest)
  # A second uninterrupted run: is the content deterministic?
  local ref2="${maps}/kill_ref2"
  rm -rf "${ref2}" "${ref2}.new" "${ref2}.old"
  if [ "${mode}" = "merge" ]; then cp -a "${base}" "${ref2}"; fi
  # It also times the save: from <map>.new appearing to the end of the process.
  "${bin}/offline_mapper" --bag "$([ "${mode}" = merge ] && echo "${bag_next}" || echo "${bag_first}")" \
    "${next_args[@]}" --map "${ref2}" --quiet 2>/dev/null &
  local ref2_pid=$! save_start=""
  while kill -0 "${ref2_pid}" 2>/dev/null; do
    [ -z "${save_start}" ] && [ -e "${ref2}.new" ] && save_start=$(now)
    sleep 0.005
  done
  wait "${ref2_pid}" || true
  local save_s=0.1
  [ -n "${save_start}" ] && save_s=$(elapsed "${save_start}")
  echo "uninterrupted save: ${save_s} s (kills aimed at the save fall in 0 .. ${save_s} s after it starts)"
  local strict=1
  if [ "$(field "${ref2}" content_digest)" != "${new_content}" ]; then
    strict=0
    echo "NOTE: two uninterrupted runs give different map content; a killed run's map is accepted"
    echo "      as 'new' when it loads and lists the new session (not compared with the reference)."
  fi
  local new_sessions; new_sessions=$(field "${ref}" sessions)
  if [ "${mode}" = "merge" ]; then
    old_files=$(field "${base}" files_digest)
  else
    old_files="none"
  fi

  local survived=0 failed=0 as_old=0 as_new=0 in_save=0 i deadline
  deadline=$(awk -v a="$(date +%s)" -v m="${max_minutes}" 'BEGIN { print a + 60 * m }')
  for ((i = 1; i <= kills; i++)); do
    if [ "$(date +%s)" -ge "${deadline}" ]; then
      echo "time limit of ${max_minutes} min reached after $((i - 1)) kills"
      break
    fi
    rm -rf "${work}" "${work}.new" "${work}.old"
    if [ "${mode}" = "merge" ]; then cp -a "${base}" "${work}"; fi
    local bag; bag=$([ "${mode}" = merge ] && echo "${bag_next}" || echo "${bag_first}")
    "${bin}/offline_mapper" --bag "${bag}" "${next_args[@]}" --map "${work}" --quiet 2>/dev/null &
    local pid=$!
    local how
    if (( i % 2 == 1 )); then
      # Anywhere in the run.
      local delay; delay=$(awk -v s="${run_s}" -v r="${RANDOM}" 'BEGIN { printf "%.3f", s * r / 32768 }')
      sleep "${delay}"
      how="at ${delay} s"
    else
      # During the save: once <map>.new appears, after a random part of the save's duration.
      while kill -0 "${pid}" 2>/dev/null && [ ! -e "${work}.new" ]; do sleep 0.005; done
      local delay; delay=$(awk -v s="${save_s}" -v r="${RANDOM}" 'BEGIN { printf "%.3f", s * r / 32768 }')
      sleep "${delay}"
      how="in the save, +${delay} s"
      in_save=$((in_save + 1))
    fi
    kill -KILL "${pid}" 2>/dev/null || how="${how} (had already finished)"
    wait "${pid}" 2>/dev/null || true
    set +e
    local out; out=$("${bin}/map_check" "${work}" 2>&1)
    local check=$?
    set -e
    local files content sess
    files=$(sed -n 's/^files_digest: //p' <<<"${out}")
    content=$(sed -n 's/^content_digest: //p' <<<"${out}")
    sess=$(sed -n 's/^sessions: //p' <<<"${out}")
    local verdict=""
    if [ ${check} -eq 3 ] && [ "${old_files}" = "none" ]; then
      verdict="old (no map)"
    elif [ ${check} -eq 0 ] && [ "${files}" = "${old_files}" ]; then
      verdict="old"
    elif [ ${check} -eq 0 ] && { { [ ${strict} -eq 1 ] && [ "${content}" = "${new_content}" ]; } ||
                                 { [ ${strict} -eq 0 ] && [ "${sess}" = "${new_sessions}" ]; }; }; then
      verdict="new"
    fi
    if [ -n "${verdict}" ]; then
      survived=$((survived + 1))
      case "${verdict}" in old*) as_old=$((as_old + 1)) ;; *) as_new=$((as_new + 1)) ;; esac
      printf 'kill %3d %-34s -> %s map\n' "${i}" "${how}" "${verdict}"
    else
      failed=$((failed + 1))
      printf 'kill %3d %-34s -> FAILED: %s\n' "${i}" "${how}" "$(tr '\n' ' ' <<<"${out}")"
      cp -a "${work}" "${maps}/kill_failed_${i}" 2>/dev/null || true
    fi
  done
  echo "crash safety (${mode}): $((survived + failed)) kills (${in_save} aimed at the save), ${survived} survived (${as_old} old map, ${as_new} new map), ${failed} failed"
  [ ${failed} -eq 0 ]
}

# ---------------------------------------------------------------------------------------------
long_run() {
  local sim="${data}/small${sessions}"
  simulate small "${sessions}" "${sim}"
  local map="${maps}/long_small"
  rm -rf "${map}" "${map}.new" "${map}.old"
  msm_log "long run: ${sessions} sessions of the small profile merged one after the other"
  printf '%-8s %-6s %10s %12s %10s %9s %s\n' session exit wall_s peak_rss_mb map_mb submaps note
  local n=0 ok=1
  while read -r bag; do
    n=$((n + 1))
    local log="${maps}/long_${n}.log"
    set +e
    /usr/bin/time -v "${bin}/offline_mapper" --bag "${sim}/${bag}" --map "${map}" --quiet \
      >"${log}" 2>&1
    local rc=$?
    set -e
    local rss wall size submaps note=""
    rss=$(awk -F': ' '/Maximum resident set size/ { printf "%.0f", $2 / 1024 }' "${log}")
    wall=$(awk -F': ' '/Elapsed \(wall clock\)/ { print $2 }' "${log}")
    size=$(du -sm "${map}" 2>/dev/null | cut -f1)
    submaps=$(field "${map}" submaps)
    if [ ${rc} -eq 3 ]; then
      note="not merged (exit 3): $(grep -m1 'offline_mapper:' "${log}" | cut -c1-120)"
      ok=0
    elif [ ${rc} -ne 0 ]; then
      note="FAILED: $(grep -m1 'offline_mapper:' "${log}")"
      ok=0
    fi
    printf '%-8s %-6s %10s %12s %10s %9s %s\n' "${bag%.bag}" "${rc}" "${wall}" "${rss}" "${size:-0}" "${submaps:-0}" "${note}"
    [ ${ok} -eq 1 ] || break
  done < <(msm_session_bags "${sim}")
  if [ ${ok} -eq 1 ]; then
    echo "long run: ${n} sessions merged"
  else
    echo "long run: stopped after ${n} session(s)"
  fi
  [ ${ok} -eq 1 ]
}

# ---------------------------------------------------------------------------------------------
# Scans of /velodyne_points in the bag, in its first $2 seconds when $2 is given (from the bag's
# index, without reading the clouds; rosbag's _get_entries is the index walk read_messages uses).
bag_scans() {
  /usr/bin/python3 - "$1" "${2:-}" <<'PY'
import sys
import rosbag
import rospy
bag = rosbag.Bag(sys.argv[1])
topic = "/velodyne_points"
if not sys.argv[2]:
    print(bag.get_message_count(topic))
else:
    start = bag.get_start_time()
    connections = list(bag._get_connections([topic]))
    print(sum(1 for _ in bag._get_entries(connections, rospy.Time.from_sec(start),
                                          rospy.Time.from_sec(start + float(sys.argv[2])))))
PY
}

# The nodelet manager started (directly or through a launch prefix) by roslaunch $1: the
# descendant running the nodelet binary with __name:=msm_manager.
manager_pid() {
  local pid p
  for pid in $(pgrep -f '__name:=msm_manager'); do
    [ "$(basename "$(readlink "/proc/${pid}/exe" 2>/dev/null)")" = nodelet ] || continue
    p=${pid}
    while [ -n "${p}" ] && [ "${p}" -gt 1 ]; do
      if [ "${p}" = "$1" ]; then echo "${pid}"; return 0; fi
      p=$(ps -o ppid= -p "${p}" 2>/dev/null | tr -d ' ')
    done
  done
}

rss_mb() { awk '/^VmRSS:/ { printf "%.0f", $2 / 1024 }' "/proc/$1/status" 2>/dev/null; }

# growth_within WHAT BEFORE AFTER MAP_GREW BASE BASE_NAME: passes when AFTER - BEFORE (MB) is at
# most the map's growth on disk MAP_GREW plus 5 % of BASE; prints the verdict.
growth_within() {
  local what=$1 before=$2 after=$3 map_grew=$4 base=$5 base_name=$6 grew allowed
  grew=$(awk -v a="${before}" -v b="${after}" 'BEGIN { printf "%.1f", b - a }')
  allowed=$(awk -v m="${map_grew}" -v p="${base}" 'BEGIN { printf "%.1f", (m > 0 ? m : 0) + 0.05 * p }')
  if awk -v g="${grew}" -v a="${allowed}" 'BEGIN { exit !(g <= a) }'; then
    echo "nodelets twice: pass: ${what} after the finish grew ${grew} MB from run 1 to run 2 (allowed: map growth ${map_grew} MB + 5 % of ${base_name} = ${allowed} MB)"
  else
    echo "nodelets twice: FAIL: ${what} after the finish grew ${grew} MB from run 1 to run 2, more than the map growth ${map_grew} MB + 5 % of ${base_name} (${allowed} MB)"
    return 1
  fi
}

nodelets_twice() {
  local bag="${nodelet_bag}"
  if [ -z "${bag}" ]; then
    simulate campus 1 "${data}/campus1"
    bag="${data}/campus1/$(msm_session_bags "${data}/campus1" | head -n 1)"
  fi
  [ -f "${bag}" ] || msm_die "no bag at ${bag}"
  local map="${maps}/nodelets" log="${maps}/nodelets_launch.log" samples="${maps}/nodelets_rss.txt"
  rm -rf "${map}" "${map}.new" "${map}.old"
  : > "${samples}"
  local played; played=$(bag_scans "${bag}" "${nodelet_duration}")
  local -a peak after heap map_kb scans note
  # The map both runs are merged into: the same scans mapped beforehand by offline_mapper, so
  # that run 1 does what run 2 does (query the history database, register and merge a revisit)
  # and the two are comparable (a first session's merge only stores it).
  local name; name=$(basename "${bag}" .bag)
  msm_log "nodelets twice: prior map of the same ${played} scans (offline_mapper, session ${name}_offline)"
  "${bin}/offline_mapper" --bag "${bag}" --map "${map}" --session "${name}_offline" \
    --max-scans "${played}" --quiet || msm_die "offline_mapper failed on ${bag}"
  map_kb[0]=$(du -sk "${map}" | cut -f1)
  # A master of its own: other ROS processes on this machine keep theirs.
  local port=$((20000 + RANDOM % 20000))
  export ROS_MASTER_URI="http://localhost:${port}"
  msm_log "nodelets twice: ${bag##*/}${nodelet_duration:+ (first ${nodelet_duration} s)}, ${played} scans per run, rate ${nodelet_rate}, one manager (master port ${port})"
  # Line-buffered output (to a file): the log lines are waited for below.
  ROSCONSOLE_STDOUT_LINE_BUFFERED=1 PYTHONUNBUFFERED=1 \
    roslaunch -p "${port}" "${MSM_REPO}/launch/mapping.launch" play:=false bag:="${bag}" session:="${name}" \
      map_dir:="${map}" idle_finish_s:=5.0 > "${log}" 2>&1 &
  launch_pid=$!  # global: the EXIT trap stops it
  local manager="" i
  for ((i = 0; i < 120; i++)); do
    kill -0 "${launch_pid}" 2>/dev/null || break
    manager=$(manager_pid "${launch_pid}")
    [ -n "${manager}" ] && grep -q 'MapMerging: map directory' "${log}" \
      && grep -q 'SubmapManager: session' "${log}" && grep -q 'ScanMatching: config' "${log}" && break
    sleep 0.5
  done
  stop_launch() {
    [ -n "${sampler:-}" ] && kill "${sampler}" 2>/dev/null
    kill -INT "${launch_pid}" 2>/dev/null || true
    for ((i = 0; i < 60; i++)); do kill -0 "${launch_pid}" 2>/dev/null || break; sleep 0.5; done
    kill -KILL "${launch_pid}" 2>/dev/null || true
    wait "${launch_pid}" 2>/dev/null || true
  }
  sampler=""
  trap 'stop_launch' EXIT
  trap 'exit 130' INT TERM
  if [ -z "${manager}" ] || ! grep -q 'MapMerging: map directory' "${log}"; then
    tail -n 30 "${log}"
    stop_launch
    msm_die "the nodelet manager did not start (see ${log})"
  fi
  ( while kill -0 "${manager}" 2>/dev/null; do
      echo "$(date +%s) $(rss_mb "${manager}")" >> "${samples}"
      sleep 2
    done ) &
  sampler=$!
  after[0]=$(rss_mb "${manager}")  # started, prior map loaded
  peak[0]=${after[0]}
  local ok=1 run start_s merges
  for ((run = 1; run <= nodelet_runs; run++)); do
    start_s=$(date +%s)
    local args=(--clock --rate "${nodelet_rate}" --queue 1000)
    [ -n "${nodelet_duration}" ] && args+=(--duration "${nodelet_duration}")
    rosbag play "${args[@]}" "${bag}" > "${maps}/nodelets_play_${run}.log" 2>&1 \
      || { note[run]="rosbag play failed"; ok=0; }
    # The session finishes idle_finish_s after the last scan was processed, then merges and
    # saves: wait for the merge's log line (success or failure) of this run; 15 min at most
    # after the end of the playback (the backlog of a pipeline slower than the playback and a
    # campus merge take a few minutes).
    local deadline=$(( $(date +%s) + 900 ))
    while merges=$(grep -c "MapMerging: session '" "${log}" || true); [ "${merges}" -lt "${run}" ]; do
      if ! kill -0 "${manager}" 2>/dev/null; then note[run]="manager died"; ok=0; break; fi
      if [ "$(date +%s)" -ge "${deadline}" ]; then
        note[run]="no merge within 15 min after the playback ($(grep -c 'ScanMatching: scan skipped' "${log}") skip warnings)"
        ok=0; break
      fi
      sleep 1
    done
    sleep 4  # the latched map and summary are published after the save
    after[run]=$(rss_mb "${manager}")
    peak[run]=$(awk -v s="${start_s}" '$1 >= s && $2 > m { m = $2 } END { print m + 0 }' "${samples}")
    [ -n "${after[run]}" ] && [ "${after[run]}" -gt "${peak[run]}" ] && peak[run]=${after[run]}
    map_kb[run]=$(du -sk "${map}" 2>/dev/null | cut -f1)
    heap[run]=$(grep -E "MapMerging: heap in use after merge ${run}: " "${log}" | tail -n 1 \
                | sed -E 's/.*: ([0-9.]+) MB.*/\1/')
    scans[run]=$(grep "SubmapManager: session '.*': [0-9]* scans" "${log}" | sed -n "${run}p" \
                 | sed -E 's/.*: ([0-9]+) scans.*/\1/')
    local merged_line; merged_line=$(grep "MapMerging: session '" "${log}" | sed -n "${run}p")
    if [ -z "${note[run]:-}" ] && ! grep -q 'saved to' <<<"${merged_line}"; then
      note[run]="not merged/saved: $(sed -E 's/.*MapMerging: //' <<<"${merged_line}" | cut -c1-120)"
      ok=0
    fi
    if [ -z "${note[run]:-}" ] && [ $(( ${scans[run]:-0} * 10 )) -lt $(( played * 9 )) ]; then
      note[run]="only ${scans[run]:-0} of ${played} scans mapped"
      ok=0
    fi
    [ ${ok} -eq 1 ] || break
  done
  local hwm; hwm=$(awk '/^VmHWM:/ { printf "%.0f", $2 / 1024 }' "/proc/${manager}/status" 2>/dev/null || true)
  stop_launch
  trap - EXIT INT TERM
  printf '%-4s %8s %8s %12s %17s %18s %7s %s\n' run played mapped peak_rss_mb rss_after_fin_mb \
    heap_after_fin_mb map_mb note
  # Run 0: the map made by offline_mapper; the manager started with it loaded, before any scan.
  for ((run = 0; run <= nodelet_runs; run++)); do
    [ -n "${after[run]:-}${note[run]:-}" ] || continue
    printf '%-4s %8s %8s %12s %17s %18s %7s %s\n' "${run}" "${played}" "${scans[run]:-(offline)}" \
      "${peak[run]:-?}" "${after[run]:-?}" "${heap[run]:--}" "$(awk -v k="${map_kb[run]:-0}" 'BEGIN { printf "%.1f", k / 1024 }')" "${note[run]:-}"
  done
  echo "manager peak RSS over all runs (VmHWM): ${hwm:-?} MB; RSS samples: ${samples}"
  if [ ${ok} -eq 1 ] && [ "${nodelet_runs}" -ge 2 ]; then
    local map_grew
    map_grew=$(awk -v a="${map_kb[1]}" -v b="${map_kb[2]}" 'BEGIN { printf "%.1f", (b - a) / 1024 }')
    # The leak check proper: the live heap (mallinfo2, logged by MapMerging after each merge).
    if [ -z "${heap[1]:-}" ] || [ -z "${heap[2]:-}" ]; then
      echo "nodelets twice: FAIL: no 'heap in use' line of MapMerging for runs 1 and 2 in ${log}"
      ok=0
    else
      growth_within "live heap" "${heap[1]}" "${heap[2]}" "${map_grew}" "${heap[1]}" \
        "run 1's live heap" || ok=0
    fi
    growth_within "RSS" "${after[1]}" "${after[2]}" "${map_grew}" "${peak[1]}" "the peak" || ok=0
  else
    echo "nodelets twice: FAIL (see the note; log ${log})"
  fi
  [ ${ok} -eq 1 ]
}

status=0
if [ -z "${only}" ] || [ "${only}" = kills ]; then crash_safety || status=1; fi
if [ -z "${only}" ] || [ "${only}" = long ]; then long_run || status=1; fi
if [ -z "${only}" ] || [ "${only}" = nodelets ]; then nodelets_twice || status=1; fi
exit ${status}
