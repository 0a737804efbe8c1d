#!/bin/sh
# runtime-packages.sh BINARY...: the Debian packages that own the shared
# libraries the binaries load (ldd), one a line, sorted. The image's build
# stage (deploy/docker/Dockerfile) runs it for each runtime stage, which
# then installs exactly those packages: no list to keep in step by hand
# (tests/container/run.sh runs it on the host for the `prebuilt` stage).
# Fails when a library is not found or belongs to no package.
set -eu
out=$(ldd "$@")
if printf '%s\n' "$out" | grep -F 'not found'; then
  echo "runtime-packages: a library is missing" >&2
  exit 1
fi
libs=$(printf '%s\n' "$out" | awk '$2 == "=>" && $3 ~ /^\// {print $3}' | sort -u)
# dpkg knows a file by the path its package ships, /lib or /usr/lib
# (merged /usr): both forms are looked up, in one pass over dpkg's file
# lists (dpkg -S per library reads its whole database each time: minutes
# on a host with many packages).
paths=$(for lib in $libs; do
  real=$(readlink -f "$lib")
  printf '%s\n%s\n' "/usr${real#/usr}" "${real#/usr}"
done)
owners=$(printf '%s\n' "$paths" | grep -H -F -x -f - /var/lib/dpkg/info/*.list || true)
for lib in $libs; do
  real=$(readlink -f "$lib")
  printf '%s\n' "$owners" | grep -q -F -e ":${real#/usr}" -e ":/usr${real#/usr}" ||
    { echo "runtime-packages: no package owns $real" >&2; exit 1; }
done
# "/var/lib/dpkg/info/libfoo1:amd64.list:/path": the package's name
printf '%s\n' "$owners" | sed 's|^/var/lib/dpkg/info/||; s|\.list:.*||; s|:.*||' | sort -u
