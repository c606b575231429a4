#!/bin/bash
# CPU an idle firmware costs: 16 lockstep firmware processes on vcan0, nobody sending SYNC, their
# user+system time over 20 s (after 15 s to start) as a share of one CPU. An idle node should
# wake only for its timers (heartbeat), not every millisecond. Run where vcan0 exists:
#   tools/with-vcan -- tools/firmware_idle_cpu.sh [FIRMWARE...]   (default: build/bin/joint-firmware)
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
tick=$(getconf CLK_TCK)
cpu_ticks() {
  local total=0 pid fields
  for pid in "$@"; do
    read -ra fields < "/proc/$pid/stat"
    total=$((total + fields[13] + fields[14]))  # utime + stime
  done
  echo "$total"
}
for firmware in "${@:-build/bin/joint-firmware}"; do
  pids=()
  for id in $(seq 1 16); do "$firmware" --can vcan0 --node-id "$id" >/dev/null 2>&1 & pids+=($!); done
  sleep 15
  start=$(cpu_ticks "${pids[@]}")
  sleep 20
  end=$(cpu_ticks "${pids[@]}")
  kill "${pids[@]}"; wait 2>/dev/null || true
  echo "$firmware: 16 idle processes, $(( (end - start) * 100 / tick )) cs of CPU in 20 s:" \
       "$(( (end - start) * 100 / tick / 20 )) % of one CPU"
done
