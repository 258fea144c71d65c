#!/usr/bin/env bash
# A new user's first hour, as the README writes it, on a fresh clone without ../shared:
# the README's two commands, `cargo install --locked --path .`, then every line of the
# README's tour in order, twice; every command must exit 0 and `git status` stay clean.
#
#   scripts/fresh_clone.sh [REPO] [WORK]
#
# REPO: what to clone (default: this repository's folder; its committed HEAD is what is
# cloned, not the work tree). WORK: an empty or absent folder for the clone (default: a
# new temporary folder, removed at the end on success). The binary is installed under
# WORK/bin (`--root`), not into ~/.cargo, and found there through PATH. Set
# CARGO_TARGET_DIR to reuse a build (the default builds from nothing, as a clone does).
# Prints each command's wall time; exits 1 at the first failure, naming it.
set -euo pipefail
here="$(cd "$(dirname "$0")/.." && pwd)"
repo="${1:-$here}"
work="${2:-$(mktemp -d)}"
mkdir -p "$work"
work="$(cd "$work" && pwd)"
if [ -n "$(ls -A "$work")" ]; then
    echo "fresh_clone: $work is not empty" >&2
    exit 1
fi
# No development data: neither beside the clone nor through the environment.
unset GREYBOX_SHARED_DATA
clone="$work/greybox"
git clone --quiet "$repo" "$clone"
if [ -e "$work/shared" ]; then
    echo "fresh_clone: $work/shared exists; the clone must not see development data" >&2
    exit 1
fi
cd "$clone"

step() {
    local start end
    start=$(date +%s)
    echo "\$ $*"
    if ! bash -c "$*"; then
        echo "fresh_clone: FAILED: $*" >&2
        exit 1
    fi
    end=$(date +%s)
    echo "  ok, $((end - start)) s"
}

# The README's first code block: its two commands.
mapfile -t first < <(awk '/^```sh/{n++; next} /^```/{if (n == 1) exit} n == 1 && !/^#/ && NF' README.md)
[ "${#first[@]}" -eq 2 ] || { echo "fresh_clone: the README's first block has ${#first[@]} commands, not 2" >&2; exit 1; }
for c in "${first[@]}"; do step "$c"; done

step "cargo install --locked --quiet --path . --root '$work/bin'"
export PATH="$work/bin/bin:$PATH"

# The tour: the code block under "## A tour", line by line in one shell (so that its `cd`
# carries), each line with no standard input (a line reading stdin would eat the rest), twice.
awk '/^## A tour/{t=1} t && /^```sh/{b=1; next} b && /^```/{exit} b' README.md > "$work/tour.sh"
[ -s "$work/tour.sh" ] || { echo "fresh_clone: no tour found in README.md" >&2; exit 1; }
for run in 1 2; do
    echo "# tour, run $run"
    (
        set -e
        while IFS= read -r line; do
            case "$line" in '' | '#'*) continue ;; esac
            start=$(date +%s)
            echo "\$ $line"
            # Each line in the tour's own shell, so that `mkdir -p tour && cd tour` holds.
            eval "$line" < /dev/null > "$work/last.out" 2>&1 || {
                rc=$?
                cat "$work/last.out" >&2
                echo "fresh_clone: FAILED (exit $rc) in tour run $run: $line" >&2
                exit 1
            }
            echo "  ok, $(($(date +%s) - start)) s"
        done < "$work/tour.sh"
    )
done

status="$(git status --porcelain)"
if [ -n "$status" ]; then
    echo "fresh_clone: git status is not clean after the tour:" >&2
    echo "$status" >&2
    exit 1
fi
echo "fresh_clone: every command exited 0 and git status is clean ($clone)"
if [ -z "${2:-}" ]; then
    rm -rf "$work"
fi
