#!/usr/bin/env bash
# tests/client/stats_cli.sh LOCUS SHARED: `locus render --workers 0 --stats`
# with the real binary (CTest `render_stats_cli`; common/base/params.h
# Stats): the JSON's seconds hold prepare, render and load (the scene
# file's), and a larger file takes longer to load than a small one. Prints one line per check and
# "N passed, M failed".
set -uo pipefail
[ $# -eq 2 ] || { echo "usage: $0 LOCUS SHARED" >&2; exit 2; }
locus=$1 shared=$2
py=/usr/bin/python3
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
passed=0 failed=0
ok() { echo "ok: $1"; passed=$((passed + 1)); }
bad() { echo "FAILED: $1"; failed=$((failed + 1)); }
# field FILE KEY: seconds.KEY of a --stats file.
field() { "$py" -c 'import json, sys; print(json.load(open(sys.argv[1]))["seconds"][sys.argv[2]])' "$1" "$2"; }
positive() { "$py" -c 'import sys; sys.exit(0 if float(sys.argv[1]) > 0 else 1)' "$1"; }
less() { "$py" -c 'import sys; sys.exit(0 if float(sys.argv[1]) < float(sys.argv[2]) else 1)' "$1" "$2"; }

small=$shared/spd/s1/tetra.nff big=$shared/spd/def/tetra.nff
if "$locus" render "$small" --size 32x32 --workers 0 -o "$tmp/s.png" --stats "$tmp/s.json" 2>"$tmp/log"; then
  for k in prepare render load; do
    v=$(field "$tmp/s.json" "$k") && positive "$v" && ok "seconds.$k is there and positive ($v)" ||
      bad "seconds.$k of $tmp/s.json"
  done
else
  bad "render --workers 0 --stats"; cat "$tmp/log"
fi
# def tetra has 1,024 times s1's polygons: its load takes longer.
if "$locus" render "$big" --size 8x8 --workers 0 -o "$tmp/b.png" --stats "$tmp/b.json" 2>"$tmp/log"; then
  a=$(field "$tmp/s.json" load) b=$(field "$tmp/b.json" load)
  less "$a" "$b" && ok "the larger file's load is longer ($a < $b s)" || bad "load $a (s1) against $b (def)"
else
  bad "render def tetra --stats"; cat "$tmp/log"
fi
echo "$passed passed, $failed failed"
[ "$failed" -eq 0 ] && [ "$passed" -gt 0 ]
