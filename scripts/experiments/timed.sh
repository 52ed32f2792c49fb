# Sourced by the labelling-path scripts: `timed NAME COMMAND...` runs the command with its output
# in $WORK/NAME.log and appends NAME=<wall-clock seconds> to the caller's STEPS array; LOAD is the
# machine's load average when the script started (other work beside it).
# shellcheck shell=bash
LOAD=$(cut -d' ' -f1 /proc/loadavg)
STEPS=()
timed() {  # NAME COMMAND...: run it, keep its wall-clock seconds
  local name=$1 start end
  shift
  start=$(date +%s.%N)
  "$@" >"$WORK/$name.log" 2>&1
  end=$(date +%s.%N)
  STEPS+=("$name=$(echo "$end - $start" | bc)")
}
