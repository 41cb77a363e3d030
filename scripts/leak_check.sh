#!/usr/bin/env bash
# Leak check of the packaged FMUs: 10 000 fmi2Instantiate/fmi2FreeInstance cycles per interface
# (Co-Simulation and Model Exchange; with initialization, steps, FMU states and a refused call in
# each) through the C ABI.
#
#   scripts/leak_check.sh [cycles] [--native]
#       cycles: default 10000; every FMU in target/fmu, built if missing
#       --native: check 1 only (no valgrind); `cargo xtask test` runs it with a few cycles so that
#                 the driver keeps up with the models' interface
#
# Two checks per model, and the script exits non-zero if either fails:
#  1. natively, the heap in use (mallinfo2) must not grow between the end of a warm-up (a
#     tenth of the cycles) and the end;
#  2. under valgrind --leak-check=full, no byte may be definitely or indirectly lost, and no
#     invalid read/write may occur (--error-exitcode).
# Needs cc, python3, valgrind (not with --native), and the FMI 2.0 headers (shipped with fmpy in .venv, or set
# FMI2_HEADERS=<dir>).
set -euo pipefail
cd "$(dirname "$0")/.."
cycles="${1:-10000}"
native_only="${2:-}"
[[ -z "$native_only" || "$native_only" == --native ]] || { echo "usage: $0 [cycles] [--native]" >&2; exit 2; }
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT

headers="${FMI2_HEADERS:-$(dirname "$(find .venv -name fmi2Functions.h -path '*fmpy*' 2>/dev/null | head -n1)")}"
if [[ ! -f "$headers/fmi2Functions.h" ]]; then
    echo "FMI 2.0 headers not found: run 'cargo xtask test' once (creates .venv with fmpy) or set FMI2_HEADERS" >&2
    exit 2
fi
cc -O1 -g -Wall -Wextra -Werror -I "$headers" scripts/leak_driver.c -o "$work/leak_driver" -ldl

# Every model whose FMI 2.0 archive `cargo xtask fmu` writes, as its manifests list them (the
# plants, then the controllers): no list of models to keep up here.
[[ -f target/fmu/models.txt && -f target/fmu/controllers.txt ]] || cargo xtask fmu
for model in $(cat target/fmu/models.txt target/fmu/controllers.txt); do
    fmu="target/fmu/$model.fmu"
    python3 -m zipfile -e "$fmu" "$work/$model"
    md="$work/$model/modelDescription.xml"
    guid="$(grep -o 'guid="[^"]*"' "$md" | head -n1 | cut -d'"' -f2)"
    vr_of() { grep -o "name=\"$1\" valueReference=\"[0-9]*\"" "$md" | grep -o '[0-9]*"$' | tr -d '"'; }
    tau_m="$(vr_of tau_m)"
    omega_m="$(vr_of omega_m)"
    # The continuous states: one derivative attribute each.
    nx="$({ grep -o 'derivative="[0-9]*"' "$md" || true; } | wc -l)"
    nz="$(grep -o 'numberOfEventIndicators="[0-9]*"' "$md" | head -n1 | cut -d'"' -f2)"
    # A controller has no continuous state (the driver then runs its Co-Simulation cycle).
    [[ -n "$guid" && -n "$tau_m" && -n "$omega_m" && -n "$nz" ]] || { echo "$model: cannot read $md" >&2; exit 2; }
    so="$work/$model/binaries/linux64/$model.so"

    echo "== $model: heap growth over $cycles cycles (native)"
    "$work/leak_driver" "$so" "$guid" "$cycles" "$tau_m" "$omega_m" "$nx" "$nz"

    [[ -n "$native_only" ]] && continue
    echo "== $model: valgrind --leak-check=full over $cycles cycles"
    valgrind --quiet --leak-check=full --show-leak-kinds=definite,indirect \
        --errors-for-leak-kinds=definite,indirect --error-exitcode=3 \
        "$work/leak_driver" "$so" "$guid" "$cycles" "$tau_m" "$omega_m" "$nx" "$nz"
done
if [[ -n "$native_only" ]]; then
    echo "leak check passed (native only): $cycles cycles per model and interface, no heap growth"
else
    echo "leak check passed: $cycles cycles per model and interface, no heap growth, nothing lost"
fi
