#!/usr/bin/env bash
# Coverage-guided fuzzing of cpgait's readers with libFuzzer (clang, ASan + UBSan).
#   scripts/fuzz.sh [SECONDS per target] [TARGET ...]     (default 60 s, every target)
#   FUZZ_RUNS=N scripts/fuzz.sh SECONDS ...               (stop a target at N executions or SECONDS)
# Seeds: inputs made by code from the repo's fixtures (build-fuzz/tests/fuzz_seeds) and, when present,
# ../shared's files of each kind (copied into the work folder, never into the repo). A finding leaves
# crash-*/leak-*/timeout-*/oom-* files in build-fuzz/findings/<target>/; add a fixed one to
# tests/fuzz/regressions/<target>/, which the test suite replays (FuzzRegressions).
# Prints per target: executions, executions per second, coverage (edges) and findings; the summary
# table is also in build-fuzz/fuzz-report.txt.
set -euo pipefail
cd "$(dirname "$0")/.."
seconds=${1:-60}
shift || true
targets=("$@")
runs=${FUZZ_RUNS:--1}
command -v clang++ > /dev/null || { echo "fuzz.sh: clang++ is missing (apt-get install clang)"; exit 1; }
CC=clang CXX=clang++ cmake -S . -B build-fuzz -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCPGAIT_FUZZ=ON > /dev/null
[ ${#targets[@]} -eq 0 ] && IFS=',' read -r -a targets < build-fuzz/fuzz_targets.txt
cmake --build build-fuzz -j2 --target fuzz_seeds $(printf 'fuzz_%s ' "${targets[@]}") > build-fuzz/build.log
build-fuzz/tests/fuzz_seeds build-fuzz/corpus
shared=../shared/reference
seed() {  # seed TARGET FILES...
  local dir=build-fuzz/corpus/$1; shift
  mkdir -p "$dir"
  for f in "$@"; do [ -f "$f" ] && cp "$f" "$dir/$(echo "$f" | tr '/' '_')"; done
  return 0
}
tools='InverseKinematicsTool|InverseDynamicsTool|AnalyzeTool|CMCTool|ForwardTool|ForceSet|ControlSet|CMC_TaskSet|IKTaskSet'
for t in "${targets[@]}"; do
  case $t in
    trc) seed trc $(find $shared -name '*.trc' -size -300k 2>/dev/null | head -20) ;;
    storage) seed storage $(find $shared \( -name '*.mot' -o -name '*.sto' \) -size -300k 2>/dev/null | head -30) ;;
    c3d) seed c3d $(find $shared/c3d -name '*.c3d' 2>/dev/null) ;;
    mesh) seed mesh $(find $shared \( -name '*.vtp' -o -name '*.stl' -o -name '*.obj' \) -size -100k 2>/dev/null | head -12) ;;
    osim) seed osim $(find $shared -name '*.osim' -size -200k 2>/dev/null | head -20) ;;
    external_loads) seed external_loads $(grep -rl ExternalLoads $shared --include=*.xml 2>/dev/null | head -10) ;;
    scale_setup) seed scale_setup $(grep -rl ScaleTool $shared --include=*.xml 2>/dev/null | head -10) ;;
    setup_xml) seed setup_xml $(grep -rlE "$tools" $shared --include=*.xml 2>/dev/null | head -40) ;;
  esac
  mkdir -p build-fuzz/corpus/$t build-fuzz/findings/$t
  [ -d tests/fuzz/regressions/$t ] && cp tests/fuzz/regressions/$t/* build-fuzz/corpus/$t/ 2>/dev/null || true
done
report=build-fuzz/fuzz-report.txt
printf '%-18s %10s %10s %8s %s\n' target executions exec/s edges findings | tee $report
for t in "${targets[@]}"; do
  log=build-fuzz/findings/$t.log
  (cd build-fuzz/findings/$t && ../../tests/fuzz_$t -max_total_time=$seconds -runs=$runs -max_len=1048576 -rss_limit_mb=2048 \
      -timeout=10 -print_final_stats=1 ../../corpus/$t > ../$t.log 2>&1) || true
  execs=$(grep -o 'stat::number_of_executed_units: *[0-9]*' $log | grep -o '[0-9]*$' || echo 0)
  rate=$(grep -o 'stat::average_exec_per_sec: *[0-9]*' $log | grep -o '[0-9]*$' || echo 0)
  edges=$(grep -oE 'cov: [0-9]+' $log | tail -1 | grep -oE '[0-9]+' || echo 0)
  findings=$(ls build-fuzz/findings/$t | tr '\n' ' ')
  printf '%-18s %10s %10s %8s %s\n' "$t" "$execs" "$rate" "$edges" "${findings:-none}" | tee -a $report
  grep -E "^==[0-9]+==ERROR|SUMMARY|runtime error|upload answered" $log | head -3 || true
done
