#!/bin/sh
# runtime-packages.sh BINARY...: the Debian packages that own the shared
# libraries the binaries load (ldd), one a line, sorted. The image's build
# stage (deploy/docker/Dockerfile) runs it for each runtime stage, which
# then installs exactly those packages: no list to keep in step by hand.
# Fails when a library is not found or belongs to no package.
set -eu
out=$(ldd "$@")
if printf '%s\n' "$out" | grep -F 'not found'; then
  echo "runtime-packages: a library is missing" >&2
  exit 1
fi
libs=$(printf '%s\n' "$out" | awk '$2 == "=>" && $3 ~ /^\// {print $3}' | sort -u)
names=
for lib in $libs; do
  real=$(readlink -f "$lib")
  # dpkg knows a file by the path its package ships, /lib or /usr/lib
  # (merged /usr), so the pattern leaves the /usr prefix open.
  owners=$(dpkg -S "*${real#/usr}" 2>/dev/null | grep -v '^diversion ') ||
    { echo "runtime-packages: no package owns $real" >&2; exit 1; }
  # "pkg-a:amd64, pkg-b: /path": the names before the path
  names="$names
$(printf '%s\n' "$owners" | sed 's/: \/.*//' | tr ',' '\n' | sed 's/^ *//; s/:.*//')"
done
printf '%s\n' "$names" | sed '/^$/d' | sort -u
