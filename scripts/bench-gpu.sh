#!/usr/bin/env bash
# The committed benchmark tables for a GPU: `dispmap bench` with every default method on
# the bundled rocks, bricks and mountains maps at 1920x1080 (a GPU idles at the default
# 640x360: `bump` is then a few microseconds of dispatch overhead), 8 frames x 3 passes,
# the exact CPU reference on frame 0 only (at 1080p the reference of every frame would
# take most of the wall time). It prints the chosen device first and refuses a CPU
# driver (lavapipe) unless --allow-cpu is given.
#
# Usage: scripts/bench-gpu.sh [--device INDEX|NAME] [--out DIR] [--size WxH]
#                             [--allow-cpu] [--dry-run] [-- MORE BENCH OPTIONS]
#
#   --device     the Vulkan device (as `dispmap --device`; `dispmap info` lists the
#                chosen one) [default: DISPMAP_DEVICE, else the best GPU]
#   --out        where report.md, results.csv and the plots go [default: bench-gpu]
#   --size       the frame [default: 1920x1080]
#   --allow-cpu  run on a CPU driver too (to try the script; its times are CPU times)
#   --dry-run    print the commands, run nothing
#   after --      more `dispmap bench` options, e.g. `-- --maps rocks --sizes none`
#
# The binary: $DISPMAP if set, else target/release/dispmap (built with cargo if missing).
# Runs from any folder.
set -euo pipefail
cd "$(dirname "$0")/.."

device=""
out="bench-gpu"
size="1920x1080"
allow_cpu=0
dry_run=0
extra=()
usage() {
    sed -n '9,18p' "$0" | sed 's/^# \{0,1\}//' >&2
    exit 2
}
need_value() {
    if [[ $# -lt 2 || -z "$2" ]]; then
        echo "bench-gpu: $1 needs a value" >&2
        exit 2
    fi
}
while [[ $# -gt 0 ]]; do
    case "$1" in
    --device)
        need_value "$@"
        device="$2"
        shift 2
        ;;
    --out)
        need_value "$@"
        out="$2"
        shift 2
        ;;
    --size)
        need_value "$@"
        size="$2"
        shift 2
        ;;
    --allow-cpu)
        allow_cpu=1
        shift
        ;;
    --dry-run)
        dry_run=1
        shift
        ;;
    --)
        shift
        extra=("$@")
        break
        ;;
    -h | --help) usage ;;
    *)
        echo "bench-gpu: unknown option '$1' (bench options go after --)" >&2
        usage
        ;;
    esac
done

bin="${DISPMAP:-target/release/dispmap}"
device_args=()
if [[ -n "$device" ]]; then
    device_args=(--device "$device")
fi
bench=("$bin" "${device_args[@]}" bench --size "$size" --error-frames 1 --out "$out"
    "${extra[@]}")

if [[ $dry_run -eq 1 ]]; then
    if [[ ! -x "$bin" ]]; then
        echo "cargo build --release -p dispmap-cli"
    fi
    echo "$bin ${device_args[*]} info"
    echo "${bench[*]}"
    exit 0
fi

if [[ ! -x "$bin" ]]; then
    if [[ -n "${DISPMAP:-}" ]]; then
        echo "bench-gpu: DISPMAP=$DISPMAP is not an executable" >&2
        exit 1
    fi
    cargo build --release -p dispmap-cli
fi

info=$("$bin" "${device_args[@]}" info)
echo "$info"
type=$(sed -n 's/^type: *//p' <<<"$info")
if [[ "$type" == "CPU" && $allow_cpu -eq 0 ]]; then
    echo "bench-gpu: the chosen device is a CPU driver; name a GPU with --device (or pass" \
        "--allow-cpu to run anyway)" >&2
    exit 1
fi

echo "${bench[*]}"
"${bench[@]}"
echo "bench-gpu: the tables are in $out/report.md; commit $out/report.md and" \
    "$out/results.csv under docs/bench/<device>/ with the commit they were measured at."
