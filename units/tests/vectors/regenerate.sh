#!/bin/sh
# Regenerate the committed SoftFloat vectors (needs the `softfloat` feature: a C compiler).
# Usage: sh units/tests/vectors/regenerate.sh   (from the workspace root)
set -eu
dir=$(dirname "$0")
gen() {
    cargo run --quiet --release -p imagine-units --features softfloat --example testfloat_gen -- "$@"
}
for op in f32_add f32_sub f32_mul f32_div f32_sqrt f32_lt f32_le f32_eq f32_min f32_max \
          f32_to_i32 f32_to_i32_r_minMag i32_to_f32; do
    gen "$op" 2500 2024 > "$dir/$op.txt"
done
for op in f32_add f32_sub f32_mul f32_div f32_sqrt; do
    gen --ftz "$op" 800 2025 > "$dir/ftz_$op.txt"
done
