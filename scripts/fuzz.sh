#!/usr/bin/env bash
# Coverage-guided fuzzing of cpgait's readers with libFuzzer (clang, ASan + UBSan).
#   scripts/fuzz.sh [SECONDS per target] [TARGET ...]     (default 60 s, every target)
# Seeds: the repo's fixtures and, when present, ../shared's files of each kind (copied into the
# work folder, never into the repo). A finding leaves crash-*/leak-*/timeout-* files in
# build-fuzz/findings/<target>/; add a fixed one to tests/fuzz/regressions/<target>/, which the test
# suite replays (FuzzRegressions.EveryKeptInputIsReadOrRefused).
set -euo pipefail
cd "$(dirname "$0")/.."
seconds=${1:-60}
shift || true
targets=("$@")
[ ${#targets[@]} -eq 0 ] && targets=(trc storage c3d osim external_loads ik_tasks_json scale_setup)
command -v clang++ > /dev/null || { echo "fuzz.sh: clang++ is missing (apt-get install clang)"; exit 1; }
CC=clang CXX=clang++ cmake -S . -B build-fuzz -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCPGAIT_FUZZ=ON > /dev/null
cmake --build build-fuzz -j2 --target $(printf 'fuzz_%s ' "${targets[@]}") > build-fuzz/build.log
shared=../shared/reference
seed() {  # seed TARGET FILES...
  local dir=build-fuzz/corpus/$1; shift
  mkdir -p "$dir"
  for f in "$@"; do [ -f "$f" ] && cp "$f" "$dir/$(echo "$f" | tr '/' '_')"; done
  return 0
}
for t in "${targets[@]}"; do
  case $t in
    trc) seed trc $(find $shared -name '*.trc' 2>/dev/null | head -20) ;;
    storage) seed storage $(find $shared -name '*.mot' -o -name '*.sto' 2>/dev/null | head -30) ;;
    c3d) seed c3d $(find $shared/c3d -name '*.c3d' 2>/dev/null) ;;
    osim) seed osim fixtures/models/walker.osim $(find $shared -name '*.osim' -size -200k 2>/dev/null | head -20) ;;
    external_loads) seed external_loads $(grep -rl ExternalLoads $shared --include=*.xml 2>/dev/null | head -10) ;;
    ik_tasks_json) seed ik_tasks_json $(find tests -name '*.json' 2>/dev/null | head -5) ;;
    scale_setup) seed scale_setup $(grep -rl ScaleTool $shared --include=*.xml 2>/dev/null | head -10) ;;
  esac
  mkdir -p build-fuzz/corpus/$t build-fuzz/findings/$t
  [ -d tests/fuzz/regressions/$t ] && cp tests/fuzz/regressions/$t/* build-fuzz/corpus/$t/ 2>/dev/null || true
  echo "== $t: ${seconds} s"
  (cd build-fuzz/findings/$t && ../../tests/fuzz_$t -max_total_time=$seconds -max_len=1048576 -rss_limit_mb=2048 \
      -timeout=10 -print_final_stats=1 ../../corpus/$t 2>&1 | grep -E "stat::number_of_executed_units|stat::average_exec_per_sec|cov:|ERROR|SUMMARY" | tail -5) || true
  ls build-fuzz/findings/$t | head -5
done
