#!/usr/bin/env bash
# Runs one fuzz target (docs/testing.md "Fuzzing") for SECONDS seconds.
#
#   scripts/fuzz.sh TARGET SECONDS [RUNS]   # TARGET: trace, scene, design, study, livepoints, or all
#
# Builds the libFuzzer executables with clang, ASan and UBSan in build-asan/
# (scripts/asan_build.sh, shared with the sanitizer suite), generates a seed corpus
# from the project's own files (built-in scenes as traces in both payload
# encodings, with the fragment count recorded and not; the mesh scene files;
# the designs in configs/; the studies in studies/; small libraries, their
# payloads and forgeries of them, fuzz/forge_livepoints.py), adds the kept
# inputs of fuzz/regressions/TARGET/, and fuzzes. The trace target's custom
# mutator also rewrites the header's fragment count (fuzz_targets.h).
# With RUNS, stops after that many executions instead (the time limit still
# holds). Prints the number of executions; exits 1 on any crash, leak,
# sanitizer report or timeout, naming the input to keep as a regression:
# copy it into fuzz/regressions/TARGET/ once fixed.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
[ $# -ge 2 ] || { echo "usage: $0 trace|scene|design|study|livepoints|all SECONDS [RUNS]" >&2; exit 2; }
target="$1"
seconds="$2"
runs="${3:-0}"
if [ "$target" = all ]; then
  for t in trace scene design study livepoints; do bash "$0" "$t" "$seconds" "$runs"; done
  exit 0
fi
case "$target" in trace | scene | design | study | livepoints) ;; *) echo "$0: unknown target '$target'" >&2; exit 2 ;; esac

bash "$root/scripts/asan_build.sh" "fuzz_$target" ropsim >/dev/null
b="$root/build-asan"

# Seeds, made once per build folder.
seeds="$b/seeds/$target"
if [ ! -d "$seeds" ]; then
  mkdir -p "$seeds.tmp"
  case "$target" in
    trace)
      i=0
      for s in testcard eight-layers enderton-1 enderton-2 cloth smoke opaque; do
        for c in none zstd; do
          for d in plane per-sample; do
            i=$((i + 1))
            spp=$((1 << (i % 7)))
            # Checksummed (the default) and not: mutations of a checksummed seed mostly stop at
            # the block checksum, so the unflagged seeds keep the record parser fuzzed.
            for k in checksum no-checksum; do
              ASAN_OPTIONS=detect_leaks=0 "$b/ropsim" scene "$s" --width 12 --height 10 --spp "$spp" --compression "$c" \
                --depth "$d" --color "$([ $((i % 2)) = 0 ] && echo rgb-f32 || echo rgb-unorm8)" \
                $([ $k = no-checksum ] && echo --no-checksum) -o "$seeds.tmp/$s-$c-$d-$k.rtrace" >/dev/null
            done
            # Through a FIFO: the writer cannot seek back, so the count stays 0 (not recorded).
            mkfifo "$seeds.tmp/fifo"
            cat "$seeds.tmp/fifo" >"$seeds.tmp/$s-$c-$d-unrecorded.rtrace" &
            ASAN_OPTIONS=detect_leaks=0 "$b/ropsim" scene "$s" --width 12 --height 10 --spp "$spp" --compression "$c" \
              --depth "$d" -o "$seeds.tmp/fifo" >/dev/null
            wait
            rm "$seeds.tmp/fifo"
          done
        done
      done
      ;;
    scene) cp "$root"/traces/scenes/mesh/*.toml "$seeds.tmp/" ;;
    design)
      cp "$root"/configs/*.toml "$seeds.tmp/"
      printf '[cache]\nways = 8\n%%%%\ncache.ways=4\nclock.frequency_ghz=1.25\nsorter.kind=bitonic\n' >"$seeds.tmp/overrides.toml"
      ;;
    study) cp "$root"/studies/*.toml "$seeds.tmp/" ;;
    livepoints)
      # Small libraries of three methods (lk: the tracker; slab: its layers),
      # whole files and their bare payloads (the target wraps those itself).
      for m in lk slab opaque; do
        ASAN_OPTIONS=detect_leaks=0 "$b/ropsim" livepoints --scene eight-layers --spp 4 --width 16 --height 12 \
          --method "$m" --sample-units 3 --sample-size 16 --sample-warmup 8 --sample-cooldown 8 --sample-warming 16 \
          --threads 1 --quiet -o "$seeds.tmp/$m.rlp"
        tail -c +33 "$seeds.tmp/$m.rlp" | zstd -q -d -c >"$seeds.tmp/$m.payload"
        # Forgeries: one field out of range each, as bare payloads (the target
        # wraps them with a valid checksum, so they reach the range checks).
        /usr/bin/python3 "$root/fuzz/forge_livepoints.py" "$seeds.tmp/$m.payload" "$seeds.tmp/forged-$m"
        for f in "$seeds.tmp/forged-$m"/*; do mv "$f" "$seeds.tmp/$m-$(basename "$f")"; done
        rmdir "$seeds.tmp/forged-$m"
      done
      ;;
  esac
  mv "$seeds.tmp" "$seeds"
fi
corpus="$b/corpus/$target"
crashes="$b/crashes/$target"
mkdir -p "$corpus" "$crashes"
dict=()
[ -f "$root/fuzz/$target.dict" ] && dict=(-dict="$root/fuzz/$target.dict")
log="$b/fuzz-$target.log"
export TMPDIR=/dev/shm  # the per-execution input files
cd "$b"  # studies resolve relative paths from their own folder; run from the build folder
set +e
ASAN_OPTIONS="detect_leaks=1:allocator_may_return_null=0" UBSAN_OPTIONS="print_stacktrace=1:halt_on_error=1" \
  "$b/fuzz/fuzz_$target" "$corpus" "$seeds" "$root/fuzz/regressions/$target" "${dict[@]}" \
  -max_total_time="$seconds" -runs="$([ "$runs" -gt 0 ] && echo "$runs" || echo -1)" \
  -timeout=20 -rss_limit_mb=4096 -malloc_limit_mb=2048 -print_final_stats=1 \
  -artifact_prefix="$crashes/" >"$log" 2>&1
status=$?
set -e
execs="$(grep -o 'stat::number_of_executed_units: *[0-9]*' "$log" | grep -o '[0-9]*$' || echo '?')"
if [ $status -ne 0 ]; then
  tail -60 "$log" >&2
  echo "fuzz $target: FAILED after $execs executions (exit $status); the input is in $crashes/ (full log $log)" >&2
  exit 1
fi
echo "fuzz $target: $execs executions in ${seconds} s at most, 0 crashes (corpus $(ls "$corpus" | wc -l) inputs)"
