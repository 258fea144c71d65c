#!/usr/bin/env bash
# scripts/compare_reports.sh BEFORE AFTER: the reports of scripts/reports.sh compared, the
# JSON without its timings to the bit, the text with times and folder names masked.
before=$1; after=$2; rc=0
mask() { sed -E "s/in [0-9.]+ s/in T s/; s/[0-9.]+ (ms|s)\b/T/g; s#$before/#D/#g; s#$after/#D/#g" "$1"; }
for f in "$before"/*.stripped; do cmp -s "$f" "$after/$(basename "$f")" || { echo "DIFF $(basename "$f")"; rc=1; }; done
for f in "$before"/*.txt; do
  diff <(mask "$f") <(mask "$after/$(basename "$f")") >/dev/null || { echo "DIFF $(basename "$f")"; rc=1; }
done
for f in sample.res.csv sim.csv; do cmp -s "$before/$f" "$after/$f" || { echo "DIFF $f"; rc=1; }; done
[ $rc = 0 ] && echo "ALL IDENTICAL"
exit $rc
