#!/usr/bin/env bash
# Benchmarks on a GPU machine: the paper's Table 1 and 2 for every backend on generated
# meshes, plus frames/s of the ray marcher. Usage: scripts/gpu-bench.sh BIN OUTDIR SPEC...
# where SPEC is SHAPE:N (e.g. jets:12M). Each step has a time limit so one slow kernel
# cannot take the whole run; JSON lines and logs go to OUTDIR.
set -uo pipefail
bin=$1; out=$2; shift 2
mkdir -p "$out"
nvidia-smi --query-gpu=name,driver_version,memory.total --format=csv,noheader > "$out/gpu.txt" 2>&1 || true
"$bin" devices | tee "$out/devices.txt"
for spec in "$@"; do
  name=${spec/:/_}
  limit=${BENCH_LIMIT:-150}
  echo "== bench $spec (limit ${limit}s)"
  timeout "$limit" "$bin" bench "$spec" --backend "${BACKENDS:-all}" --queries "${QUERIES:-centers,random,bbox,host}" \
    --power --json > "$out/bench-$name.jsonl" 2> "$out/bench-$name.log"
  echo "exit $?"; tail -n 3 "$out/bench-$name.log"
  python3 - "$out/bench-$name.jsonl" <<'PY'
import json, sys
rows = [json.loads(l) for l in open(sys.argv[1]) if l.startswith("{")]
for r in rows:
    mib = lambda b: "-" if b is None else f"{b/2**20:.0f}"
    print(f"{r['backend']:<16} {r['queries']:<8} {r['samples_per_s']/1e6:>10.1f} M/s  build {r['build_s']:.2f}s  final {mib(r['final_bytes'])} MiB  peak {mib(r['peak_bytes'])} MiB  outside {r['outside']}  W {r['power_watts']}")
PY
done
