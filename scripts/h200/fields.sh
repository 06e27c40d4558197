#!/usr/bin/env bash
# One location for k fields (issue 28) on the H200: jets 12M, ids and values of 0, 1, 3 and 5
# fields, in one launch a batch (after) against the ids' launch plus a launch a field (before).
#   1. `tetloc bench jets:12M --queries host,random` with no field and with `--field f`, with the
#      binary of main (before: host values in 2 launches) and of the fields branch (after: 1),
#      interleaved ROUNDS times (default 1; samples/s end to end for host; random is the
#      single-field kernel, unchanged: the control).
#   2. examples/fields.rs (one binary, both paths in one process): for k = 0, 1, 3, 5 fields,
#      host points end to end (one launch / per field) and the kernel time of random points
#      (GPU timestamps: the one launch / the ids' launch + a launch a field), on every kernel,
#      plus a bit-for-bit check of the two paths' answers on 1M points.
# JSON lines and logs under $OUT; summary.txt holds the tables.
#
# Build here, carry .gl and .devbin (64 MiB in all: strip them):
#   git -C /work/main worktree add /tmp/before main && (cd /tmp/before && cargo build --release -p tetloc-cli)
#   mkdir -p .devbin && objcopy --strip-debug /tmp/before/target/release/tetloc .devbin/tetloc-before
#   cargo build --release -p tetloc-cli -p tetloc-vulkan --example fields   # on the fields branch
#   objcopy --strip-debug target/release/tetloc .devbin/tetloc-after
#   objcopy --strip-debug target/release/examples/fields .devbin/fields
# Usage, from the repository root on the device machine (about 6 minutes, + 2 a round):
#   OUT=... bash scripts/h200/fields.sh .devbin/tetloc-before .devbin/tetloc-after .devbin/fields [TETS]
set -u
BEFORE=$1
AFTER=$2
FIELDS=$3
TETS=${4:-12M}
. "$(dirname "$0")/common.sh"
gpu_setup "$AFTER"

# 1. The CLI, before and after, interleaved.
for round in $(seq "${ROUNDS:-1}"); do
  for which in before after; do
    bin=$BEFORE; [ "$which" = after ] && bin=$AFTER
    for field in none f; do
      args=(); [ "$field" = f ] && args=(--field f)
      log="$OUT/cli-$which-$field-$round"
      timeout 120 "$bin" bench "jets:$TETS" --backend soft-bvh,rt-bvh --queries host,random --repeats 5 \
        --json "${args[@]}" > "$log.jsonl" 2> "$log.log"
      echo "cli $which field=$field round $round: exit $? ($(wc -l < "$log.jsonl") rows)" | tee -a "$OUT/summary.txt"
    done
  done
done

# 2. k fields in one launch and per field, one process.
n=${TETS%M}; n=$((n * 1000000))
timeout 360 "$FIELDS" --tets "$n" --repeats 5 > "$OUT/fields.jsonl" 2> "$OUT/fields.log"
echo "fields example: exit $? ($(wc -l < "$OUT/fields.jsonl") rows)" | tee -a "$OUT/summary.txt"

python3 - "$OUT" >> "$OUT/summary.txt" 2>&1 <<'PY'
import glob, json, os, sys
out = sys.argv[1]
def rows(path):
    return [json.loads(l) for l in open(path) if l.startswith("{")] if os.path.exists(path) else []
print("\n1. tetloc bench jets (samples/s; field f: the host row is ids + f end to end)")
print(f"{'backend':<10} {'queries':<7} {'field':<5} {'before':>22} {'after':>22}")
table = {}
for path in sorted(glob.glob(f"{out}/cli-*.jsonl")):
    _, which, field, _ = os.path.basename(path)[:-6].split("-")
    for r in rows(path):
        table.setdefault((r["backend"], r["queries"], field), {}).setdefault(which, []).append(r["samples_per_s"])
g = lambda v: "/".join(f"{x / 1e9:.3f}" for x in v) + " G/s"
for (b, q, f), w in sorted(table.items()):
    print(f"{b:<10} {q:<7} {f:<5} {g(w.get('before', [])):>22} {g(w.get('after', [])):>22}")
print("\n2. examples/fields (samples/s; host: end to end, kernel: random points, GPU time)")
print(f"{'kernel':<16} {'k':>2} {'what':<7} {'one launch':>12} {'per field':>12} {'ratio':>6}")
ex = rows(f"{out}/fields.jsonl")
keyed = {(r["kernel"], r["fields"], r["what"], r["path"]): r["samples_per_s"] for r in ex if "path" in r}
for (k_, k, what, path), v in sorted(keyed.items()):
    if path != "one":
        continue
    per = keyed.get((k_, k, what, "per-field"))
    ratio = f"{v / per:.2f}" if per else "-"
    print(f"{k_:<16} {k:>2} {what:<7} {v / 1e9:>10.3f}G {(per or 0) / 1e9:>10.3f}G {ratio:>6}")
for r in ex:
    if "answers_differ" in r:
        print(f"check {r['kernel']} k={r['fields']}: {r['answers_differ']} of {r['check_points']} points' answers differ")
PY
cat "$OUT/summary.txt"
