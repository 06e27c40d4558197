#!/usr/bin/env bash
# soft-bvh on the device (docs/design/soft-bvh.md, the H100 runs), every benchmark warmed up for 0.5 s:
#   part 1: soft-bvh variants at jets 12M (root traversal, entry grid, walk start at 1 and 2
#           tets a cell, f32-first and pure-f32 tests), japan 62M root vs walk;
#   part 2: a regular unjittered 13.2M grid (the probe's mesh kind) with rt-bvh and
#           rt-shared-faces, jets 12M with every array forced into <= 100 MB buffers
#           (checked), jets 250M soft-bvh and rt-bvh.
# Usage, from the repository root on the device machine, after building vkbench here and
# copying it to .devbin/ (carry .gl and .devbin); PARTS picks parts (default "1 2", ~3 + ~7 min):
#   bash scripts/gpu-softbvh.sh .devbin/vkbench "$OUT"
set -u
B=$1
L=$2
for f in .gl/*.deb; do dpkg -x "$f" /; done
ldconfig
{ date -u; nvidia-smi --query-gpu=name,driver_version,clocks.sm,clocks.max.sm,power.draw,temperature.gpu --format=csv; } > "$L/gpu.txt" 2>&1
run() { # name, time limit, vkbench arguments...
    local name=$1 limit=$2
    shift 2
    timeout "$limit" "$B" "$@" > "$L/$name.log" 2>&1
    echo "$name exit $? $(date -u +%T)" >> "$L/gpu.txt"
}
for part in ${PARTS:-1 2}; do
    if [ "$part" = 1 ]; then
        run v12 220 --tets 12000000 --kernels soft-bvh --variants --modes uniform,random --check 200000 --repeats 7
        run j62 80 --tets 62000000 --shape japan --kernels soft-bvh --no-walk --modes uniform,random --check 0 --repeats 5
        run j62w 110 --tets 62000000 --shape japan --kernels soft-bvh --modes uniform,random --check 200000 --repeats 5
    else
        run reg 130 --tets 13200000 --regular --kernels soft-bvh,rt-bvh,rt-shared-faces --modes uniform,random --check 200000 --repeats 7
        run split 90 --tets 12000000 --kernels soft-bvh --max-buffer 100000000 --modes uniform,random --check 200000 --repeats 7
        run j250 600 --tets 250000000 --kernels soft-bvh,rt-bvh --modes uniform,random --check 0 --repeats 5
    fi
done
cat "$L/gpu.txt"
grep -h -E "^mesh|check of|build failed|rror|built in" "$L"/*.log
for f in "$L"/*.log; do sed -n '/^config/,$p' "$f" | cut -c1-150; done
