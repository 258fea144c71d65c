#!/usr/bin/env bash
# The firmware core in CI: greybox-observer-capi built without std (the `libm` crate's
# functions, panic = abort), linked with the C example (examples/track.c) against the
# committed header, run over the shipped log in double and float; the double run must
# print what `greybox track` prints, digit for digit, for the MRAS and the Kalman filter.
#   observer/capi/check.sh [GREYBOX_BINARY]   (default target/release/greybox)
set -euo pipefail
cd "$(dirname "$0")/../.."
bin=${1:-target/release/greybox}
out=target/nostd
CARGO_TARGET_DIR=$out RUSTFLAGS="-C panic=abort" \
    cargo build --release --quiet -p greybox-observer-capi --no-default-features
cc -O2 -std=c11 -Wall -Wextra -Werror -pedantic -I observer/capi/include observer/capi/examples/track.c \
    "$out/release/libgreybox_observer_capi.a" -lm -o "$out/track"
# The core alone: its tests with the `libm` crate's functions (the workspace tests ran them with
# the C library's).
cargo test --release --quiet -p greybox-observer
gunzip -c data/sample.csv.gz > "$out/sample.csv"
# The module example's settings: 4 pole pairs, L_s = 4.5 mH known, started off the truth.
args=(4 4.5e-3 0.45 0.7)
for est in mras ekf; do
    want=$("$bin" track "$out/sample.csv" -p "${args[0]}" --l-s "${args[1]}" --k-e0 "${args[2]}" \
        --r-s0 "${args[3]}" --estimator "$est" 2>/dev/null)
    got=$("$out/track" "$out/sample.csv" "${args[@]}" "$est" f64)
    single=$("$out/track" "$out/sample.csv" "${args[@]}" "$est" f32)
    echo "greybox track: $want"
    echo "C, double:     $got"
    echo "C, float:      $single"
    if [ "$want" != "$got" ]; then
        echo "the C program's $est estimates differ from greybox track's" >&2
        exit 1
    fi
done
# A salient machine (the `_init_salient` functions): the drive simulator's interior-magnet
# motor (L_d = 3 mH, L_q = 7 mH, 3 pole pairs), started off the truth.
"$bin" simulate --scenario exp1 --motor ipm --duration 2 --seed 1 -o "$out/ipm.csv" 2>/dev/null
args=(3 3e-3 0.5 0.5)
for est in mras ekf; do
    want=$("$bin" track "$out/ipm.csv" -p "${args[0]}" --l-s "${args[1]}" --l-q 7e-3 --k-e0 "${args[2]}" \
        --r-s0 "${args[3]}" --estimator "$est" 2>/dev/null || true)
    got=$("$out/track" "$out/ipm.csv" "${args[@]}" "$est" f64 7e-3)
    single=$("$out/track" "$out/ipm.csv" "${args[@]}" "$est" f32 7e-3)
    echo "greybox track (salient): $want"
    echo "C, double:               $got"
    echo "C, float:                $single"
    if [ -z "$want" ] || [ "$want" != "$got" ]; then
        echo "the C program's salient $est estimates differ from greybox track's" >&2
        exit 1
    fi
done
